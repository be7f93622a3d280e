"""Topple about the landing-leg footprint (SEED-NOTES 5) against geometry and a pivot ODE.

The critical tilt is where the centre of mass passes over the rim foot, atan(leg_radius /
com_height); below it the footprint rights the ship, above it the ship falls onto its side. A fall
from rest is timed against I_p theta'' = m g L sin(theta - theta_c) with I_p the inertia about the
pivot (bench/reference.py), and is shown to be far from the seed's inertia-about-the-centre-of-mass
version, which topples about twice too fast.
"""
import math

import pytest

from touchdown.bench.reference import critical_angle_rad, topple_time
from scenes import events, final_state, records, scene, topics
from touchdown.sim.constants import MOON_GM_M3PS2, MOON_RADIUS_M
from touchdown.sim.enums import SurfaceState

G = MOON_GM_M3PS2 / MOON_RADIUS_M ** 2


def standing(tilt_deg, h=3.0, a=2.26, duration=20.0, **kw):
    """A ship in contact, at rest, tilted toward one of its feet, that foot on the ground."""
    return records(scene({"state": "contact", "altitude": -G / 100.0, "tilt_deg": tilt_deg},
                         ship={"com_height": h, "leg_radius": a}, duration=duration, **kw))


@pytest.mark.parametrize("h,a", [(3.0, 2.26), (4.0, 1.5)])
@pytest.mark.parametrize("side", [-1, +1])
def test_critical_angle_comes_from_the_footprint_geometry(h, a, side):
    crit = math.degrees(critical_angle_rad(h, a))
    recs = standing(crit + side * 0.3, h, a, duration=40.0)
    if side < 0:
        assert final_state(recs) is SurfaceState.LANDED, topics(recs)
        assert "ship.tipped" not in topics(recs)
    else:
        assert final_state(recs) is SurfaceState.TIPPED, topics(recs)


def test_topple_time_matches_the_pivot_ode_not_the_seeds_inertia():
    h, a, m, i_t = 3.0, 2.26, 10000.0, None
    scn_recs = standing(math.degrees(critical_angle_rad(h, a)) + 3.0, h, a, duration=30.0)
    tipped = [t for t, name, _ in events(scn_recs) if name == "ship.tipped"]
    assert tipped, topics(scn_recs)
    dt = 0.05
    t_sim = tipped[0] * dt
    # default inertia: a uniform cylinder of radius a and length 2h (sim/scenario.py documents it)
    i_t = m * (3 * a * a + (2 * h) ** 2) / 12.0
    theta0 = critical_angle_rad(h, a) + math.radians(3.0)
    t_ref = topple_time(G, m, i_t, h, a, theta0, math.radians(80.0))
    t_seed = topple_time(G, m, i_t, h, a, theta0, math.radians(80.0), about_pivot=False)
    assert abs(t_sim - t_ref) <= dt + 0.03 * t_ref, (t_sim, t_ref)
    assert t_ref > 1.8 * t_seed  # the seed's inertia would topple about twice too fast


def test_righting_time_matches_the_pivot_ode_with_rcs_torque():
    """A tipped ship (90 deg) righted by RCS torque tau about its pivot foot:
    I_p theta'' = m g L sin(theta - theta_c) - tau, from rest, until theta = tipped_angle."""
    from scipy.integrate import solve_ivp

    h, a, m, tau = 3.0, 2.26, 10000.0, 80000.0
    recs = records(scene({"state": "tipped", "tilt_deg": 90.0},
                         ship={"max_rcs_torque": tau, "fuel_mass": 100.0, "mass": m,
                               "inertia": [40000.0, 40000.0, 20000.0]},
                         inputs=[{"t": 0.0, "rcs": [0.0, -1.0, 0.0]}], duration=6.0))
    righted = [t for t, name, _ in events(recs) if name == "ship.righted"]
    assert righted, topics(recs)
    big_l = math.hypot(h, a)
    tc = critical_angle_rad(h, a)
    i_p = 40000.0 + m * big_l ** 2  # transverse inertia plus the parallel-axis term

    def rhs(t, y):
        return [y[1], (m * G * big_l * math.sin(y[0] - tc) - tau) / i_p]

    reach = lambda t, y: y[0] - math.radians(80.0)  # noqa: E731
    reach.terminal, reach.direction = True, -1
    sol = solve_ivp(rhs, (0.0, 100.0), [math.radians(90.0), 0.0], events=[reach],
                    method="DOP853", rtol=1e-11, atol=1e-12)
    t_ref = float(sol.t_events[0][0])
    dt = 0.05
    # the RCS burns fuel, so mass and inertia fall a little (0.1% here); a tick of resolution
    assert abs(righted[0] * dt - t_ref) <= dt + 0.02 * t_ref, (righted[0] * dt, t_ref)
