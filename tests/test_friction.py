"""Friction against the Coulomb law (SEED-NOTES 4): stopping distance v0^2 / (2 mu_k g), stopping
time v0 / (mu_k g), exact hold at rest, each foot its own cone (a spin is stopped as four feet stop
it), and the seed's velocity-reset law kept reachable."""

import math

import numpy as np
import pytest

from bench.reference import planar_touchdown
from scenes import events, final_state, long_axis, records, scene, series, tilt_deg, topics
from sim import friction
from sim.constants import MOON_GM_M3PS2, MOON_RADIUS_M
from sim.contact import Ground, feet
from sim.enums import SurfaceState
from sim.params import Terrain

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
    _, recs = slide(v0, **coarse)
    vt = series(recs, "v_tangential_mps")
    assert vt[-20:].max() < 1e-6

    scn = scene({"state": "contact", "altitude": -G / 100.0, "horizontal_speed": v0},
                contact={"friction_model": "seed", "settle_linear_vel": 1e-3}, sim=coarse,
                duration=6.0)
    recs = records(scn)
    vt = series(recs, "v_tangential_mps")
    assert vt[-20:].min() > 0.01, "the seed's law was expected to keep a residual 2-cycle"
    assert final_state(recs) is SurfaceState.CONTACT  # never settles


def _one_ship_at_rest(side_force_n, normal_n=10000.0 * G, h=0.0025, steps=400):
    """Apply a steady sideways force for ``steps`` sub-steps through the friction law alone, to an
    upright ship on level ground whose four feet share the normal force (their friction has no
    moment about the centre of mass here: the feet are put at it, so only translation is free)."""
    m = 10000.0
    inertia = (40000.0, 40000.0, 20000.0)
    pos = (MOON_RADIUS_M + 3.0, 0.0, 0.0)
    quat = (0.7071067811865476, 0.0, 0.7071067811865476, 0.0)  # body z along +x (up)
    ground = Ground(MOON_RADIUS_M, Terrain().record()[0], 1.0, 0.0, 0.0, False)
    ft = feet(ground, pos, quat, 0.0, 0.0)
    vel = (0.0, 0.0, 0.0)
    omega = (0.0, 0.0, 0.0)
    sliding = (False, False, False, False)
    x = 0.0
    for _ in range(steps):
        vel = (vel[0], vel[1] + side_force_n * h / m, vel[2])
        impulses = tuple(0.25 * normal_n * h for _ in range(4))
        vel, omega, sliding, _j = friction.coulomb(MU_S, MU_K, m, inertia, pos, vel, quat, omega,
                                                   ft, impulses, sliding, ground)
        x += vel[1] * h
    return x, vel[1]


def test_static_friction_holds_exactly_below_mu_s_n():
    weight = 10000.0 * G
    x, v = _one_ship_at_rest(0.99 * MU_S * weight)
    assert abs(x) < 1e-15 and abs(v) < 1e-15


def test_static_friction_breaks_away_above_mu_s_n_and_slides_at_mu_k():
    weight = 10000.0 * G
    steps, h = 400, 0.0025
    x, v = _one_ship_at_rest(1.01 * MU_S * weight, steps=steps, h=h)
    # once sliding, net force = 1.01 mu_s W - mu_k W
    a = (1.01 * MU_S - MU_K) * weight / 10000.0
    assert v == pytest.approx(a * steps * h, rel=0.02)
    assert x > 0.0
