"""Friction against the Coulomb law (SEED-NOTES 4): stopping distance v0^2 / (2 mu_k g), stopping
time v0 / (mu_k g), exact hold at rest, and the seed's velocity-reset law kept reachable."""

import numpy as np
import pytest

from scenes import final_state, records, scene, series
from sim import friction
from sim.constants import MOON_GM_M3PS2, MOON_RADIUS_M
from sim.enums import SurfaceState

G = MOON_GM_M3PS2 / MOON_RADIUS_M ** 2
MU_K, MU_S = 0.5, 0.8


def slide(v0, **sim):
    """A ship in contact, at rest vertically (at the static sag g/100 of the k = 100 m spring),
    sliding at v0. The landing threshold is lowered so that landing (which pins the ship once
    it is slower than settle_linear_vel) does not cut the last centimetres of the slide."""
    sag = G / 100.0
    scn = scene({"state": "contact", "altitude": -sag, "horizontal_speed": v0, "heading_deg": 90.0},
                contact={"settle_linear_vel": 1e-3}, sim=sim, duration=v0 / (MU_K * G) + 3.0)
    return scn, records(scn)


@pytest.mark.parametrize("v0", [2.0, 6.0])
def test_slide_stops_where_coulomb_friction_says(v0):
    scn, recs = slide(v0)
    # the feet stop slipping when friction drops below kinetic (the rigid ship then rocks back on
    # its springs, so its centre of mass does not stop dead at the same instant)
    fr = series(recs, "friction_force_n")
    kinetic = MU_K * 10000.0 * G
    stopped = int(np.argmax((fr < 0.9 * kinetic) & (np.arange(len(fr)) > 2)))
    assert stopped > 0, "never stopped"
    dt = scn.params.sim.dt_s
    t_stop = v0 / (MU_K * G)
    assert abs(stopped * dt - t_stop) <= dt + 0.01 * t_stop
    # the centre of mass's furthest point: braking pitches the ship forward by ~1 deg (friction
    # acts at the feet, 3 m below), and it rocks back upright on its springs once the feet stop
    p0 = recs[0].state.pos_m[0]
    distance = max(float(np.linalg.norm(r.state.pos_m[0] - p0)) for r in recs)
    assert distance == pytest.approx(v0 * v0 / (2 * MU_K * G), rel=0.01)


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


def _one_ship_at_rest(side_force_n, normal_n=10000.0 * G, h=0.0025, steps=400, model="coulomb"):
    """Apply a steady sideways force for ``steps`` sub-steps through the friction law alone, to a
    ship whose centre of pressure is under its centre of mass along the force-free axis (r = 0:
    the slip of the contact point is the ship's own velocity)."""
    m = np.array([10000.0])
    inertia = np.array([[40000.0, 40000.0, 20000.0]])
    pos = np.array([[MOON_RADIUS_M + 3.0, 0.0, 0.0]])
    quat = np.array([[0.7071067811865476, 0.0, 0.7071067811865476, 0.0]])  # body z along +x (up)
    cop = pos.copy()
    vel = np.zeros((1, 3))
    omega = np.zeros((1, 3))
    sliding = np.array([False])
    x = 0.0
    for _ in range(steps):
        vel = vel + np.array([[0.0, side_force_n * h / m[0], 0.0]])
        vel, omega, sliding, _f = friction.apply(model, MU_S, MU_K, h, 0.0, m, inertia, pos, vel,
                                                 quat, omega, np.array([normal_n]), cop, sliding)
        x += vel[0, 1] * h
    return x, vel[0, 1]


def test_static_friction_holds_exactly_below_mu_s_n():
    weight = 10000.0 * G
    x, v = _one_ship_at_rest(0.99 * MU_S * weight)
    assert x == 0.0 and v == 0.0


def test_static_friction_breaks_away_above_mu_s_n_and_slides_at_mu_k():
    weight = 10000.0 * G
    steps, h = 400, 0.0025
    x, v = _one_ship_at_rest(1.01 * MU_S * weight, steps=steps, h=h)
    # once sliding, net force = 1.01 mu_s W - mu_k W
    a = (1.01 * MU_S - MU_K) * weight / 10000.0
    assert v == pytest.approx(a * steps * h, rel=0.02)
    assert x > 0.0
