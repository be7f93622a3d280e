"""Friction against the Coulomb law (SEED-NOTES 4): stopping distance v0^2 / (2 mu_k g), stopping
time v0 / (mu_k g), a hold on a slope up to atan(mu_s) and a slide above it, each foot its own cone
(a spin is stopped as four feet stop it), and the seed's velocity-reset law kept reachable."""

import dataclasses
import math

import numpy as np
import pytest

from touchdown.bench.reference import planar_touchdown
from touchdown.sim.state import State
from scenes import (events, final_state, footprint_centre, long_axis, records, scene, series,
                    tilt_deg, topics)
from touchdown.sim.constants import MOON_GM_M3PS2, MOON_RADIUS_M
from touchdown.sim.enums import SurfaceState

G = MOON_GM_M3PS2 / MOON_RADIUS_M ** 2
MU_K, MU_S = 0.5, 0.8


def slide(v0, com_height=3.0, **sim):
    """A ship in contact, at rest vertically (at the static sag g/100 of the k = 100 m spring),
    sliding at v0. The landing threshold is lowered so that landing (which pins the ship once
    it is slower than settle_linear_vel) does not cut the last centimetres of the slide."""
    sag = G / 100.0
    scn = scene({"state": "contact", "altitude": -sag, "horizontal_speed": v0, "heading_deg": 90.0},
                ship={"com_height": com_height}, contact={"settle_linear_vel": 1e-3}, sim=sim,
                duration=v0 / (MU_K * G) + 3.0)
    return scn, records(scn)


def _feet_travel(recs, com_height):
    def centre(r):
        return r.state.pos_m[0] - com_height * long_axis(r.state.quat)[0]
    return float(np.linalg.norm(centre(recs[-1]) - centre(recs[0])))


@pytest.mark.parametrize("v0", [2.0, 6.0])
def test_slide_stops_where_coulomb_friction_says(v0):
    """A squat ship (centre of mass 0.5 m above its feet: friction's moment hardly rocks it) slides
    v0^2 / (2 mu_k g) and stops after v0 / (mu_k g)."""
    scn, recs = slide(v0, com_height=0.5)
    slipping = np.array([r.state.sliding[0].any() for r in recs])
    assert slipping[1:5].all()
    stopped = int(np.argmax(~slipping & (np.arange(len(recs)) > 2)))
    assert stopped > 0, "never stopped"
    dt = scn.params.sim.dt_s
    g = MOON_GM_M3PS2 / float(np.linalg.norm(recs[0].state.pos_m[0])) ** 2
    t_stop = v0 / (MU_K * g)
    assert abs(stopped * dt - t_stop) <= dt + 0.01 * t_stop
    assert _feet_travel(recs, 0.5) == pytest.approx(v0 * v0 / (2 * MU_K * g), rel=2e-3)


@pytest.mark.parametrize("v_side,tips", [(3.0, False), (6.0, True)])
def test_a_sideways_touchdown_stands_or_trips_as_the_planar_reference_says(v_side, tips):
    """A 2 m/s touchdown with v_side sideways along a foot (the built-in 'trip'): friction at the
    feet, 3 m below the centre of mass, pitches the lander forward; at 3 m/s it rocks to ~22
    degrees and stands, at 6 m/s friction at the leading foot drives it on over that foot (past
    10 deg, mu (a sin t + h cos t) > a cos t - h sin t). Against bench.reference.planar_touchdown
    (an independent solve_ivp of the rigid lander on its four feet), at 2.5 ms sub-steps and
    with mu_s = mu_k as the reference has: the largest tilt within 2%, the fall within 1%."""
    v_down = math.sqrt(2.0 ** 2 + 2.0 * 1.6248 * 0.2)  # at the touchdown, from 0.2 m at 2 m/s
    t_fall = (v_down - 2.0) / 1.6248
    g = MOON_GM_M3PS2 / (MOON_RADIUS_M + 3.0) ** 2
    t_tip, max_tilt, _ = planar_touchdown(v_side, v_down, g, t_end_s=8.0)
    assert (t_tip is not None) == tips
    scn = scene({"altitude": 0.2, "vertical_speed": -2.0, "horizontal_speed": v_side,
                 "heading_deg": 90.0}, contact={"friction_static": MU_K},
                sim={"dt": 0.05, "max_substep": 0.0025}, duration=8.0)
    recs = records(scn)
    tilt = tilt_deg(recs)
    if tips:
        (tick,) = [t for t, name, _ in events(recs) if name == "ship.tipped"]
        assert abs(tick * 0.05 - (t_tip + t_fall)) <= 0.05 + 0.01 * t_tip
    else:
        assert "ship.tipped" not in topics(recs)
        assert tilt.max() == pytest.approx(max_tilt, rel=0.02)


def test_no_two_cycle_even_with_a_coarse_step():
    """The seed's law at dt = 0.05 without sub-steps (mu_k g dt = 0.041 > 0.02 m/s): a slide whose
    last kinetic step lands between 0.01 and 0.03 m/s overshoots to the other side of zero and
    flips sign every tick for ever. Touchdown's law stops at the same dt and speed."""
    coarse = {"dt": 0.05, "max_substep": 0.0, "integrator": "semi_implicit_euler",
              "on_unstable": "allow"}  # the seed's plain step, as it is
    v0 = 49 * MU_K * G * 0.05 + 0.025  # the last kinetic step starts at 0.025 m/s
    scn, recs = slide(v0, **coarse)
    # the feet stop and stay (the tall lander then rocks on them, released from friction's
    # moment, and lands): no velocity flipping sign under them
    slipping = np.array([r.state.sliding[0].any() for r in recs])
    stop = int(np.argmax(~slipping & (np.arange(len(recs)) > 2)))
    assert 0 < stop < len(recs) - 30
    feet = [footprint_centre(scn, r) for r in recs]
    assert max(float(np.linalg.norm(f - feet[stop])) for f in feet[stop:]) < 0.02
    assert final_state(recs) is SurfaceState.LANDED

    scn = scene({"state": "contact", "altitude": -G / 100.0, "horizontal_speed": v0},
                contact={"friction_model": "seed", "settle_linear_vel": 1e-3}, sim=coarse,
                duration=6.0)
    recs = records(scn)
    vt = series(recs, "v_tangential_mps")
    assert vt[-20:].min() > 0.01, "the seed's law was expected to keep a residual 2-cycle"
    assert final_state(recs) is SurfaceState.CONTACT  # never settles


def _settled_on_slope(slope_deg, ship, dt):
    """A lander at rest on a uniform slope falling along its heading, standing square to the
    ground: settled first on a grippier copy of the ground (mu_s = 5), so that it starts in its
    own static equilibrium (the friction's moment balanced by its feet's loads), not in the
    transient of being set down (which alone breaks a tall ship's grip a degree early). Both runs
    keep the ship in contact (a settle time longer than the run): a landed ship is pinned, and the
    hold under test is friction's, not the landed state's."""
    alt = -G * math.cos(math.radians(slope_deg)) ** 2 / 100.0
    terrain = {"slope_deg": slope_deg, "slope_azimuth_deg": 0.0}
    start = {"state": "contact", "altitude": alt, "tilt_deg": slope_deg}
    stay = {"settle_time": 1e4}
    grip = scene(start, ship=ship, sim={"dt": dt}, contact={"friction_static": 5.0, **stay},
                 body={"terrain": terrain}, duration=20.0)
    rest = records(grip)[-1].state
    scn = scene(start, ship=ship, sim={"dt": dt}, contact=stay, body={"terrain": terrain},
                duration=10.0)
    return dataclasses.replace(scn, initial=State(rows=rest.rows.copy(), tick=0))


SHIPS = {"squat": {"com_height": 0.5, "leg_radius": 3.0},
         "medium": {"com_height": 1.5, "leg_radius": 3.0},
         "tall": {"com_height": 2.5, "leg_radius": 3.0}}


@pytest.mark.parametrize("dt", [0.05, 0.1])
@pytest.mark.parametrize("ship", sorted(SHIPS))
def test_static_friction_holds_a_ship_on_a_slope_up_to_atan_mu_s(ship, dt):
    """Per-foot Coulomb friction holds a ship on a slope up to atan(mu_s) = 38.66 degrees,
    whatever its legs (its feet's loads differ: friction's moment about the centre of mass loads
    the downhill feet), and lets it slide above: 0.3 degrees below, its footprint moves less than
    2 mm in 10 s (its feet hold, creeping by a hair where one carries all it can: a foot slower
    than the stick speed keeps mu_s); 0.5 degrees above, it breaks away and slides metres; a
    degree above, down at g (sin a - mu_k cos a), to 1%. (Measured thresholds, for these three
    ships at both ticks: +0.23, +0.01 and +0.28 degrees; 0.5.0: a squat ship slid from 36.05
    degrees, 33.2 at smaller steps.)"""
    crit = math.degrees(math.atan(MU_S))
    scn = _settled_on_slope(crit - 0.3, SHIPS[ship], dt)
    recs = records(scn)
    moved = float(np.linalg.norm(footprint_centre(scn, recs[-1]) - footprint_centre(scn, recs[0])))
    assert moved < 2e-3
    scn = _settled_on_slope(crit + 0.5, SHIPS[ship], dt)
    recs = records(scn)
    assert float(np.linalg.norm(footprint_centre(scn, recs[-1])
                                - footprint_centre(scn, recs[0]))) > 1.0
    recs = records(_settled_on_slope(crit + 1.0, SHIPS[ship], dt))
    a = math.radians(crit + 1.0)
    g = MOON_GM_M3PS2 / float(np.linalg.norm(recs[0].state.pos_m[0])) ** 2
    k4, k8 = round(4.0 / dt), round(8.0 / dt)  # well past the breakaway
    v4, v8 = (float(np.linalg.norm(recs[k].state.vel_mps[0])) for k in (k4, k8))
    assert (v8 - v4) / 4.0 == pytest.approx(g * (math.sin(a) - MU_K * math.cos(a)), rel=0.01)
