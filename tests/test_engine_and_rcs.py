"""Engine, fuel and the attitude controller against closed forms."""
import math

import numpy as np
import pytest

from scenes import records, scene, series, tilt_deg
from touchdown.sim.constants import G0_MPS2, MOON_GM_M3PS2, MOON_RADIUS_M


def test_fuel_burns_at_thrust_over_isp_g0_and_the_mass_drops_with_it():
    thrust, isp, t_burn = 60000.0, 311.0, 2.0
    recs = records(scene({"altitude": 1000.0}, ship={"max_thrust": thrust, "isp": isp},
                         inputs=[{"t": 0.0, "throttle": 0.5}, {"t": t_burn, "throttle": 0.0}],
                         duration=3.0))
    fuel = np.array([r.state.fuel_kg[0] for r in recs])
    mass = np.array([r.state.mass_kg[0] for r in recs])
    expected = 0.5 * thrust / (isp * G0_MPS2) * t_burn
    assert 2000.0 - fuel[-1] == pytest.approx(expected, rel=1e-9)
    assert mass[0] - mass[-1] == pytest.approx(expected, rel=1e-9)
    assert fuel[-1] == fuel[-5]  # the engine is off: nothing more burns


def test_rcs_burns_fuel_by_torque_over_arm():
    tau, arm, isp = 20000.0, 2.0, 290.0
    recs = records(scene({"altitude": 1000.0}, ship={"max_rcs_torque": tau, "rcs_arm": arm,
                                                     "rcs_isp": isp},
                         inputs=[{"t": 0.0, "rcs": [1.0, 0.0, -0.5]}], duration=1.0))
    used = 2000.0 - recs[-1].state.fuel_kg[0]
    assert used == pytest.approx(1.5 * tau / arm / (isp * G0_MPS2) * 1.0, rel=1e-9)


def test_an_empty_tank_fires_nothing():
    recs = records(scene({"altitude": 100.0}, ship={"fuel_mass": 0.0},
                         inputs=[{"t": 0.0, "throttle": 1.0}], duration=1.0))
    assert series(recs, "throttle").max() == 0.0
    g = MOON_GM_M3PS2 / MOON_RADIUS_M ** 2
    assert series(recs, "v_radial_mps")[-1] == pytest.approx(-g * 1.0, rel=1e-3)


def test_engine_accelerates_along_the_long_axis():
    thrust, m = 60000.0, 10000.0
    recs = records(scene({"altitude": 1000.0}, ship={"max_thrust": thrust, "fuel_mass": 5000.0},
                         inputs=[{"t": 0.0, "throttle": 1.0}], duration=0.5))
    g = MOON_GM_M3PS2 / MOON_RADIUS_M ** 2
    # the mass drops a little over the half second; integrate the rocket equation exactly
    mdot = thrust / (311.0 * G0_MPS2)
    dv = 311.0 * G0_MPS2 * math.log(m / (m - mdot * 0.5)) - g * 0.5
    assert series(recs, "v_radial_mps")[-1] == pytest.approx(dv, rel=2e-3)


def test_radial_hold_brings_the_long_axis_to_local_up():
    recs = records(scene({"altitude": 2000.0, "tilt_deg": 30.0},
                         inputs=[{"t": 0.0, "hold": "radial"}], duration=12.0))
    tilt = tilt_deg(recs)
    assert tilt[0] == pytest.approx(30.0, abs=1e-9)
    assert tilt[-1] < 0.5


def test_kill_rotation_stops_a_spin():
    recs = records(scene({"altitude": 2000.0, "angular_velocity": [0.0, 0.3, 0.2]},
                         inputs=[{"t": 0.0, "hold": "kill_rotation"}], duration=15.0))
    w = recs[-1].state.omega_body_radps[0]
    assert np.linalg.norm(w) < 1e-3
    assert np.linalg.norm(recs[1].state.omega_body_radps[0]) > 0.3


def test_manual_rcs_spins_at_torque_over_inertia():
    tau, izz = 20000.0, 20000.0
    recs = records(scene({"altitude": 2000.0}, ship={"inertia": [40000.0, 40000.0, izz],
                                                     "fuel_mass": 10.0, "mass": 10000.0},
                         inputs=[{"t": 0.0, "rcs": [0.0, 0.0, 1.0]}], duration=1.0))
    # about the symmetry axis Euler's equations decouple: w_z = tau t / I (mass drops slightly)
    assert recs[-1].state.omega_body_radps[0][2] == pytest.approx(tau / izz * 1.0, rel=2e-3)
