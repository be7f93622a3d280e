"""Stability of each method on the contact oscillator (SEED-NOTES 8): the theoretical bound, the
simulation failing just past it and holding just inside it, and the guard that sub-steps or
refuses an unstable scene."""
import math

import numpy as np
import pytest

from scenes import records, scene, series
from sim.scenario import ScenarioError
from sim.stability import largest_stable_wh

ZETA, OMEGA = 0.3, 10.0


def eigen(zeta):
    """The oscillator's eigenvalues for w = 1: -zeta +- i sqrt(1 - zeta^2)."""
    return complex(-zeta, math.sqrt(1 - zeta * zeta))


def test_bounds_agree_with_closed_forms():
    # explicit Euler: |1 + z| <= 1 on z = h lambda  <=>  w h <= 2 zeta
    assert largest_stable_wh("explicit_euler", ZETA) == pytest.approx(2 * ZETA, rel=1e-9)
    # semi-implicit Euler: Jury's test on tr = 2 - h^2 - 2 zeta h, det = 1 - 2 zeta h
    assert largest_stable_wh("semi_implicit_euler", ZETA) == pytest.approx(
        2 * (math.sqrt(ZETA ** 2 + 1) - ZETA), rel=1e-9)
    # undamped: the familiar w h < 2 for the symplectic methods, 2 sqrt 2 for RK4
    assert largest_stable_wh("semi_implicit_euler", 0.0) == pytest.approx(2.0, rel=1e-9)
    assert largest_stable_wh("velocity_verlet", 0.0) == pytest.approx(2.0, rel=1e-9)
    assert largest_stable_wh("rk4", 0.0) == pytest.approx(2 * math.sqrt(2), rel=1e-9)
    assert largest_stable_wh("explicit_euler", 0.0) < 1e-5  # unstable at any practical step


def test_rk4_bound_against_its_stability_polynomial():
    b = largest_stable_wh("rk4", ZETA)
    r = lambda z: 1 + z + z ** 2 / 2 + z ** 3 / 6 + z ** 4 / 24  # noqa: E731
    lam = eigen(ZETA)
    assert abs(r(b * 0.99 * lam)) < 1.0 < abs(r(b * 1.01 * lam))


def ringing(method, wh, duration=20.0):
    """A ship resting in an absorbed (bilateral) contact with zeta = 0.3, nudged at 5 cm/s so that
    it rings within its static sag (g / w^2 = 16 mm): the linear oscillator exactly, stepped once
    per tick of w h. Landing is switched off so that the ringing can be watched."""
    return records(scene({"state": "contact", "altitude": -0.0162, "vertical_speed": -0.05},
                         contact={"damping_ratio": ZETA, "absorb_damping_ratio": ZETA,
                                  "settle_linear_vel": 1e-12},
                         sim={"integrator": method, "dt": wh / OMEGA, "max_substep": 0.0,
                              "on_unstable": "allow"},
                         duration=duration))


@pytest.mark.parametrize("method", ["explicit_euler", "semi_implicit_euler", "velocity_verlet",
                                    "rk4"])
def test_each_method_holds_inside_its_bound_and_fails_past_it(method):
    bound = largest_stable_wh(method, ZETA)
    nudge = 0.05
    inside = np.abs(series(ringing(method, 0.95 * bound), "v_radial_mps"))
    assert np.isfinite(inside).all()
    assert inside.max() <= 1.2 * nudge, "never grows inside the bound"
    assert inside[-20:].max() < 0.5 * nudge, "and decays"
    # past it the ringing grows until the ship is thrown off the ground (then it bounces: the
    # clamp bounds it, but the energy came from nowhere)
    outside = np.abs(series(ringing(method, 1.05 * bound), "v_radial_mps"))
    assert outside.max() > 3.0 * nudge, "grows past the bound"


def test_an_unstable_scene_is_refused_when_asked():
    with pytest.raises(ScenarioError) as err:
        scene({"altitude": 1.0}, sim={"integrator": "rk4", "dt": 0.5, "max_substep": 0.0,
                                      "on_unstable": "error"})
    assert "sim.dt" in str(err.value) and "unstable" in str(err.value)


def test_an_unstable_scene_is_sub_stepped_by_default():
    scn = scene({"altitude": 0.5, "vertical_speed": -20.0},
                sim={"integrator": "explicit_euler", "dt": 0.1, "max_substep": 0.0}, duration=30.0)
    h = scn.params.sim.dt_s / scn.params.sim.n_fine_substeps
    assert OMEGA * h < largest_stable_wh("explicit_euler", ZETA)
    assert scn.resolved["sim"]["max_substep"] == pytest.approx(h)
    recs = records(scn)
    assert np.isfinite(series(recs, "altitude_m")).all()
    # bounded: no energy from nowhere (stable is not accurate: near its bound explicit Euler
    # cancels most of the physical damping, so this bounce comes back nearly as high as it fell)
    g = scn.params.body.surface_gravity_mps2
    assert series(recs, "altitude_m").max() <= (20.0 ** 2 + 2 * g * 0.5) / (2 * g)
