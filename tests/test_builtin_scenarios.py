"""The built-in scenarios do what their one-line descriptions say, and together reach every
transition of the seed's table and every crash rule."""
import math
from functools import lru_cache

import numpy as np
import pytest

from touchdown import scenarios
from scenes import events, final_state, series, tilt_deg, topics
from touchdown.sim.enums import TRANSITION_EVENTS, SurfaceState
from touchdown.sim.run import run
from touchdown.sim.scenario import parse_text

S = SurfaceState


@lru_cache(maxsize=None)
def recorded(name):
    scn = parse_text(scenarios.text(name), name)
    return scn, list(run(scn))


def test_at_least_twelve_builtins():
    assert len(scenarios.names()) >= 12


EXPECTED = {
    "bounce": (["ship.contact", "ship.liftoff", "ship.contact", "ship.landed"], S.LANDED),
    "soft-touchdown": (["ship.contact", "ship.landed"], S.LANDED),
    "double-bounce": (["ship.contact", "ship.liftoff"] * 2 + ["ship.contact", "ship.landed"],
                      S.LANDED),
    "crash": (["ship.crashed"], S.CRASHED),
    "tilt-recover": (["ship.contact", "ship.landed"], S.LANDED),
    "topple": (["ship.contact", "ship.tipped"], S.TIPPED),
    "righting": (["ship.righted", "ship.landed"], S.LANDED),
    "slide": (["ship.landed"], S.LANDED),
    "trip": (["ship.contact", "ship.tipped"], S.TIPPED),
    "liftoff": (["ship.liftoff", "ship.contact", "ship.landed"], S.LANDED),
    "thrust-off": (["ship.contact", "ship.liftoff"], S.FLYING),
    "spinning-moon": (["ship.contact", "ship.landed"], S.LANDED),
    "earth": (["ship.contact", "ship.landed"], S.LANDED),
    "hills": (["ship.landed"], S.LANDED),
    "tumble-crash": (["ship.crashed"], S.CRASHED),
    "recontact-crash": (["ship.contact", "ship.liftoff", "ship.crashed"], S.CRASHED),
}


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_single_ship_builtins(name):
    _, recs = recorded(name)
    names, final = EXPECTED[name]
    assert topics(recs) == names
    assert final_state(recs) is final


def test_bounce_is_the_readme_story():
    """20 m/s on the Moon, one bounce of about 25 m, settled."""
    _, recs = recorded("bounce")
    (_, _, v_imp), (t_l, _, v_sep), (t_c, _, _), _ = events(recs)
    assert -v_imp == pytest.approx(math.sqrt(20.0 ** 2 + 2 * 1.6248 * 5.0), rel=1e-3)
    apex = series(recs, "altitude_m")[t_l:t_c].max()
    assert 20.0 < apex < 30.0


def test_slide_distance_matches_coulomb():
    """Four feet sliding at 4 m/s on level ground stop where Coulomb friction says, v0^2 / (2 mu_k g)
    (the centre of mass's furthest point: braking pitches the ship forward a degree)."""
    scn, recs = recorded("slide")
    g = scn.params.body.gm_m3ps2 / float(np.linalg.norm(recs[0].state.pos_m[0])) ** 2
    p0 = recs[0].state.pos_m[0]
    d = max(float(np.linalg.norm(r.state.pos_m[0] - p0)) for r in recs)
    assert d == pytest.approx(4.0 ** 2 / (2 * 0.5 * g), rel=0.01)


def test_trip_a_fast_sideways_touchdown_trips_over_its_leading_feet():
    """6 m/s sideways at a 2 m/s touchdown: friction at the leading feet pitches the lander over
    them (tests/test_friction.py checks the time against an independent planar solution)."""
    _, recs = recorded("trip")
    assert tilt_deg(recs)[-1] > 85.0


def test_spinning_moon_carries_the_landed_ship_round():
    scn, recs = recorded("spinning-moon")
    t_land = next(t for t, n, _ in events(recs) if n == "ship.landed")
    p0, p1 = recs[t_land].state.pos_m[0], recs[-1].state.pos_m[0]
    angle = math.atan2(p1[1], p1[0]) - math.atan2(p0[1], p0[0])
    elapsed = (len(recs) - 1 - t_land) * scn.params.sim.dt_s
    assert angle == pytest.approx(2 * math.pi / 3600.0 * elapsed, rel=1e-9)
    assert np.linalg.norm(p1) == pytest.approx(np.linalg.norm(p0), abs=1e-6)


def test_hills_the_ship_rides_up_the_terrain():
    """The feet follow the height field: the centre of mass rises by about the hill's height where
    the ship crosses it, and the feet stay at the ground (altitude ~ -sag) while in contact."""
    scn, recs = recorded("hills")
    r = np.array([np.linalg.norm(rec.state.pos_m[0]) for rec in recs])
    rise = r.max() - r[10]
    assert 0.3 < rise < 0.7
    contact = series(recs, "altitude_m")[10:100]
    assert np.all(np.abs(contact) < 0.2)


def test_fleet_outcomes():
    scn, recs = recorded("fleet")
    final = {sid: final_state(recs, i) for i, sid in enumerate(scn.params.ships.ship_id)}
    assert final == {"soft": S.LANDED, "bouncer": S.LANDED, "crasher": S.CRASHED,
                     "toppler": S.TIPPED, "slider": S.LANDED, "hover": S.FLYING}
    assert "ship.liftoff" in topics(recs, 1)


def test_topple_goes_past_the_critical_angle():
    _, recs = recorded("topple")
    assert tilt_deg(recs)[-1] > 85.0


def test_builtins_reach_every_transition_and_crash_rule():
    seen = set()
    for name in scenarios.names():
        for r in recorded(name)[1]:
            seen |= {(S(e.from_state), S(e.to_state)) for e in r.events}
    seed_table = {(S.FLYING, S.CONTACT), (S.CONTACT, S.LANDED), (S.CONTACT, S.TIPPED),
                  (S.CONTACT, S.FLYING), (S.CONTACT, S.CRASHED), (S.TIPPED, S.CONTACT),
                  (S.LANDED, S.FLYING), (S.FLYING, S.CRASHED)}
    assert seed_table <= seen, seed_table - seen
    assert seen <= set(TRANSITION_EVENTS)
