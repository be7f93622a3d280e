"""The vertical bounce against the exact piecewise damped-oscillator solution (bench/reference.py).

Claim (README): with the default method (rk4) and tick (0.05 s, 25 ms contact sub-steps), the
first bounce of a 20-49 m/s impact matches the exact solution to 1% (the issue's bar; held here
to 0.5%, measured <= 0.15%) in maximum penetration,
separation speed and apex.
"""
import math

import pytest

from bench.reference import bounce_closed_form, bounce_ode
from scenes import events, records, scene, series
from sim.constants import MOON_GM_M3PS2, MOON_RADIUS_M

G_MOON = MOON_GM_M3PS2 / MOON_RADIUS_M ** 2


@pytest.mark.parametrize("v", [20.0, 35.0, 49.0])
def test_the_two_references_agree(v):
    """The closed form (uniform g) and the ODE solve (GM/r^2) agree to 0.05%: the reference is
    itself checked before anything is checked against it."""
    a = bounce_closed_form(G_MOON, v)
    b = bounce_ode(MOON_GM_M3PS2, MOON_RADIUS_M, v)
    assert a.max_penetration_m == pytest.approx(b.max_penetration_m, rel=5e-4)
    assert a.separation_speed_mps == pytest.approx(b.separation_speed_mps, rel=5e-4)
    assert a.apex_m == pytest.approx(b.apex_m, rel=5e-4)
    # SEED-NOTES 9: peak penetration ~0.068 v0; SEED-NOTES 2: restitution ~0.45 for zeta 0.3
    assert a.max_penetration_m / v == pytest.approx(0.068, abs=0.002)
    assert 0.40 < a.separation_speed_mps / v < 0.47


def first_bounce(recs):
    evs = events(recs)
    (t_c, name_c, v_imp), (t_l, name_l, v_sep) = evs[0], evs[1]
    assert (name_c, name_l) == ("ship.contact", "ship.liftoff"), evs
    t_next = evs[2][0] if len(evs) > 2 else len(recs)
    peak = series(recs, "peak_penetration_m")[t_c:t_l + 1].max()
    apex = series(recs, "altitude_m")[t_l:t_next].max()
    return -v_imp, peak, v_sep, apex


@pytest.mark.parametrize("v0", [20.0, 27.0, 35.0, 42.0, 49.0])
def test_default_method_matches_exact_bounce_to_1_percent(v0):
    alt0 = 0.3
    recs = records(scene({"altitude": alt0, "vertical_speed": -v0}, duration=2 * v0 / G_MOON + 2))
    v_imp, peak, v_sep, apex = first_bounce(recs)
    expected_impact = math.sqrt(v0 * v0 + 2 * G_MOON * alt0)
    assert v_imp == pytest.approx(expected_impact, rel=1e-4)
    ref = bounce_ode(MOON_GM_M3PS2, MOON_RADIUS_M, expected_impact)
    assert peak == pytest.approx(ref.max_penetration_m, rel=0.005)
    assert v_sep == pytest.approx(ref.separation_speed_mps, rel=0.005)
    assert apex == pytest.approx(ref.apex_m, rel=0.005)


@pytest.mark.parametrize("v0", [20.0, 45.0])
def test_default_method_matches_exact_bounce_under_earth_gravity(v0):
    """A heavy body: g = 9.8 m/s^2 (SEED-NOTES 1: restitution depends on v / (g / w))."""
    from sim.constants import EARTH_GM_M3PS2, EARTH_RADIUS_M
    g = EARTH_GM_M3PS2 / EARTH_RADIUS_M ** 2
    alt0 = 0.3
    recs = records(scene({"altitude": alt0, "vertical_speed": -v0},
                         body={"name": "Earth", "radius": EARTH_RADIUS_M, "gm": EARTH_GM_M3PS2},
                         duration=2 * v0 / g + 1))
    v_imp, peak, v_sep, apex = first_bounce(recs)
    ref = bounce_ode(EARTH_GM_M3PS2, EARTH_RADIUS_M, math.sqrt(v0 * v0 + 2 * g * alt0))
    assert peak == pytest.approx(ref.max_penetration_m, rel=0.005)
    assert v_sep == pytest.approx(ref.separation_speed_mps, rel=0.005)
    assert apex == pytest.approx(ref.apex_m, rel=0.005)
