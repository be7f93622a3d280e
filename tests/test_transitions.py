"""Every transition of the seed's table, and both sides of every threshold."""
import math
from dataclasses import replace

import numpy as np
import pytest

from scenes import events, final_state, one_ship, records, scene, tilt_deg, topics
from touchdown.sim.constants import MOON_GM_M3PS2, MOON_RADIUS_M
from touchdown.sim.enums import SurfaceState
from touchdown.sim.state import TRANSITION_DTYPE
from touchdown.sim.phases import settle
from touchdown.sim.rest import NO_RUN
from touchdown.sim.ship import Commands, EventLog

#: no engine, no RCS (sim.ship.Commands)
IDLE = Commands(0.0, 0.0, (0.0, 0.0, 0.0), False)

G = MOON_GM_M3PS2 / MOON_RADIUS_M ** 2
M = 10000.0


def drop(speed, **kw):
    """A ship whose feet are 1 mm up, descending at ``speed``: the impact speed is ``speed``."""
    return records(scene({"altitude": 0.001, "vertical_speed": -speed}, **kw))


# -- crash speed: first contact, re-contact, contact, tipped ---------------------------------------
@pytest.mark.parametrize("speed,crashed", [(49.9, False), (50.1, True)])
def test_crash_speed_at_first_contact(speed, crashed):
    recs = drop(speed, duration=1.0)
    assert topics(recs)[0] == ("ship.crashed" if crashed else "ship.contact")
    assert (final_state(recs) is SurfaceState.CRASHED) == crashed


@pytest.mark.parametrize("speed,crashed", [(49.9, False), (50.1, True)])
def test_crash_speed_while_in_contact(speed, crashed):
    recs = records(scene({"state": "contact", "altitude": 0.0, "vertical_speed": -speed},
                         duration=1.0))
    assert ("ship.crashed" in topics(recs)) == crashed


@pytest.mark.parametrize("speed,crashed", [(49.9, False), (50.1, True)])
def test_crash_speed_when_tipping_over(speed, crashed):
    """A ship tipping past tipped_angle faster than crash_speed (SEED-NOTES: 'tipped ship contacts
    ground at high speed') crashes; slower, it is tipped. Its low foot just touches the ground:
    the contact's force over the millisecond it takes to tip changes the speed by ~0.02 m/s."""
    v_down, v_side = 1.0, math.sqrt(speed * speed - 1.0)
    recs = records(scene({"state": "contact", "altitude": 0.0, "tilt_deg": 79.99,
                          "vertical_speed": -v_down, "horizontal_speed": v_side,
                          "angular_velocity": [0.0, 1.0, 0.0]},
                         contact={"align_on_touchdown": False}, duration=0.2))
    assert topics(recs)[0] == ("ship.crashed" if crashed else "ship.tipped")



@pytest.mark.parametrize("side,crashed", [(49.0, False), (51.0, True)])
def test_a_touchdown_lying_down_enters_contact_then_tips_or_crashes(side, crashed):
    """A ship already past tipped_angle when its first foot touches (not stood up: alignment
    off) enters contact, then at the same instant lies down: tipped, or crashed if it moves
    faster than crash_speed relative to the ground (sim.flight.touchdown_rules, one rule for the
    located touchdown and the last-resort one). Both events carry the impact's speed."""
    recs = records(scene({"altitude": 0.001, "vertical_speed": -8.0, "horizontal_speed": side,
                          "tilt_deg": 85.0}, contact={"align_on_touchdown": False},
                         duration=0.2))
    evs = events(recs)
    assert [t for _, t, _ in evs[:2]] == ["ship.contact",
                                          "ship.crashed" if crashed else "ship.tipped"]
    assert evs[0][0] == evs[1][0] and evs[0][2] == evs[1][2] == pytest.approx(-8.0, abs=0.01)

def test_recontact_after_a_bounce_above_crash_speed_crashes():
    """SEED-NOTES 7: only thrust can make a re-contact faster than the impact (the built-in
    'recontact-crash' flips the ship in flight and fires downward)."""
    from touchdown import scenarios
    from touchdown.sim.scenario import parse_text
    recs = records(parse_text(scenarios.text("recontact-crash"), "recontact-crash"))
    names = topics(recs)
    assert names[:2] == ["ship.contact", "ship.liftoff"] and names[-1] == "ship.crashed"
    assert events(recs)[-1][2] < -50.0  # the re-contact speed


# -- bounce speed ---------------------------------------------------------------------------------
@pytest.mark.parametrize("speed,bounces", [(9.9, False), (10.1, True)])
def test_bounce_speed_separates_impacts_that_bounce(speed, bounces):
    recs = drop(speed, duration=8.0)
    assert ("ship.liftoff" in topics(recs)) == bounces
    if not bounces:
        assert topics(recs) == ["ship.contact", "ship.landed"]


def test_bounce_speed_zero_restores_the_bare_force_law():
    """SEED-NOTES 1: with the clamp alone a 5 m/s lunar impact leaves the ground again."""
    assert "ship.liftoff" in topics(drop(5.0, duration=4.0, contact={"bounce_speed": 0.0}))
    assert "ship.liftoff" not in topics(drop(5.0, duration=4.0))


# -- tipped angle (a wide footprint keeps 79 deg stable: critical = atan(10/1) = 84.3 deg) --------
@pytest.mark.parametrize("tilt,tips", [(79.0, False), (81.0, True)])
def test_tipped_angle(tilt, tips):
    recs = records(scene({"altitude": 0.01, "vertical_speed": -0.5, "tilt_deg": tilt},
                         contact={"align_on_touchdown": False},
                         ship={"com_height": 1.0, "leg_radius": 10.0}, duration=20.0))
    assert ("ship.tipped" in topics(recs)) == tips
    if tips:  # past tipped_angle but short of its 84.3 deg critical angle: it rights itself
        assert topics(recs)[:3] == ["ship.contact", "ship.tipped", "ship.righted"]
    else:
        assert final_state(recs) is SurfaceState.LANDED


# -- landed: thresholds held for settle_time (SEED-NOTES 3) ---------------------------------------
def _contact_state(landed: str = "rest"):
    scn = scene({"state": "contact", "altitude": -G / 100.0}, contact={"landed": landed},
                duration=1.0)
    return scn.params, scn.initial


def _settles(params, st, ticks=1):
    here, ship, _ = one_ship(params, st)
    events, count = np.zeros(4, TRANSITION_DTYPE), np.zeros(1, np.int64)
    for _ in range(ticks):
        ship = settle(here, ship, IDLE, NO_RUN, EventLog(events, count, 0))
        if ship.surface_state == SurfaceState.LANDED:
            return True
    return False


def _spanning_samples(params):
    """Ticks after which thresholds that held from the start of the first have held settle_time."""
    return math.ceil(params.contact.settle_time_s / params.sim.dt_s - 1e-9)


def _with_velocity(st, radial=0.0, tangential=0.0):
    r_hat = st.pos_m[0] / np.linalg.norm(st.pos_m[0])
    t_hat = np.cross([0.0, 0.0, 1.0], r_hat)
    t_hat /= np.linalg.norm(t_hat)
    return st.with_fields(vel_mps=(radial * r_hat + tangential * t_hat)[None, :])


@pytest.mark.parametrize("value,lands", [(0.49, True), (0.51, False)])
@pytest.mark.parametrize("axis", ["radial", "tangential"])
def test_settle_linear_speed(axis, value, lands):
    """The seed's thresholds alone (``landed = "attached"``: the feet's slip is not asked)."""
    params, st = _contact_state("attached")
    assert _settles(params, _with_velocity(st, **{axis: value}), _spanning_samples(params)) == lands


@pytest.mark.parametrize("value,lands", [(0.0099, True), (0.0101, False)])
def test_settle_angular_speed(value, lands):
    params, st = _contact_state("attached")
    st = st.with_fields(omega_body_radps=np.array([[value, 0.0, 0.0]]))
    assert _settles(params, st, _spanning_samples(params)) == lands


@pytest.mark.parametrize("value,lands", [(0.0099, True), (0.0101, False)])
def test_a_ship_whose_feet_slip_is_not_at_rest(value, lands):
    """At rest (MODEL-NOTES 45) the pressing feet must be still: slipping slower than 0.01 m/s (the
    seed's line between moving and still). A ship moving sideways at 0.0099 m/s lands, at
    0.0101 m/s it does not, though both are far under the seed's 0.5 m/s; so does a yaw spin
    whose feet slip at those speeds, though it is far under the seed's 0.01 rad/s."""
    params, st = _contact_state()
    assert _settles(params, _with_velocity(st, tangential=value), _spanning_samples(params)) == lands
    spin = value / params.ships.leg_radius_m[0]
    st = st.with_fields(omega_body_radps=np.array([[0.0, 0.0, spin]]))
    assert _settles(params, st, _spanning_samples(params)) == lands


@pytest.mark.parametrize("tilt,lands", [(4.9, True), (5.1, False)])
def test_settle_tilt(tilt, lands):
    scn = scene({"state": "contact", "altitude": 0.0, "tilt_deg": tilt}, duration=1.0)
    assert _settles(scn.params, scn.initial, _spanning_samples(scn.params)) == lands


def test_settle_time_must_pass_in_full():
    """Landed once the thresholds have held for settle_time in continuous time: a ship at rest in
    contact from t = 0 has held them 0.5 s at the end of its tenth 0.05 s tick, not one tick
    sooner."""
    params, st = _contact_state()
    assert _spanning_samples(params) == 10
    assert not _settles(params, st, 9)
    assert _settles(params, st, 10)


def test_the_landing_instant_is_where_the_thresholds_had_held_settle_time():
    """The thresholds begin to hold inside a tick (interpolated on their smallest margin between
    its two ends); the landing is decided at the tick end by which they have held settle_time,
    and happens, as its event says, settle_time after they began. Here the radial speed falls
    from 0.55 to 0.45 m/s across the third tick: its margin, (0.5 - |v|) / 0.5, goes from -0.1
    to +0.1, so they began half way through it. (A step samples them at every sub-step's end
    too: MODEL-NOTES 47; here only the tick's ends.)"""
    params, st = _contact_state()
    here, ship, _ = one_ship(params, st)
    r_hat = st.pos_m[0] / np.linalg.norm(st.pos_m[0])
    events, count = np.zeros(4, TRANSITION_DTYPE), np.zeros(1, np.int64)
    dt = params.sim.dt_s
    speeds = [0.6, 0.55, 0.45]  # at the ends of the first three ticks; then 0.45 on
    for k in range(40):
        v = -speeds[min(k, 2)] * r_hat
        moved = ship._replace(motion=ship.motion._replace(v=(v[0], v[1], v[2])))
        ship = settle(here, moved, IDLE, NO_RUN, EventLog(events, count, 0))
        if ship.surface_state == SurfaceState.LANDED:
            break
    began = 2 * dt + 0.5 * dt
    landed_tick = k + 1
    t_event = landed_tick * dt - (dt - float(events[0]["t_offset_s"]))
    assert (landed_tick - 1) * dt < began + 0.5 <= landed_tick * dt
    assert t_event == pytest.approx(began + 0.5, abs=1e-12)


def test_settle_time_zero_is_the_seeds_instantaneous_rule():
    params, st = _contact_state()
    params = replace(params, contact=replace(params.contact, settle_time_s=0.0))
    assert _settles(params, st, 1)


def test_never_lands_at_the_bottom_of_a_bounce():
    """Every tick of a 20 m/s bounce sampled at the moment of maximum compression would pass the
    seed's instantaneous test; with settle_time it never lands before the rebound."""
    names = topics(drop(20.0, duration=15.0))
    assert names[:2] == ["ship.contact", "ship.liftoff"]


# -- liftoff: thrust against weight ---------------------------------------------------------------
@pytest.mark.parametrize("ratio,lifts", [(0.99, False), (1.01, True)])
def test_liftoff_when_thrust_beats_weight(ratio, lifts):
    max_thrust = 60000.0
    throttle = ratio * M * G / max_thrust
    recs = records(scene({"state": "landed"}, ship={"max_thrust": max_thrust},
                         inputs=[{"t": 0.0, "throttle": throttle}], duration=0.5))
    assert ("ship.liftoff" in topics(recs)) == lifts


def test_thrusting_off_during_contact():
    recs = records(scene({"altitude": 0.5, "vertical_speed": -15.0},
                         inputs=[{"t": 0.1, "throttle": 1.0}], duration=4.0))
    assert topics(recs) == ["ship.contact", "ship.liftoff"]
    assert final_state(recs) is SurfaceState.FLYING


# -- righting: RCS torque against gravity's about the pivot ---------------------------------------
@pytest.mark.parametrize("ratio,rights", [(0.95, False), (1.05, True)])
def test_righting_needs_rcs_torque_above_gravitys(ratio, rights):
    h = 3.0
    torque = ratio * M * G * h  # gravity's moment about the pivot at 90 deg: m g h
    recs = records(scene({"state": "tipped", "tilt_deg": 90.0},
                         ship={"max_rcs_torque": torque, "fuel_mass": 5000.0},
                         inputs=[{"t": 0.0, "rcs": [0.0, -1.0, 0.0]}], duration=8.0))
    assert ("ship.righted" in topics(recs)) == rights


@pytest.mark.parametrize("ratio,lifts", [(0.99, False), (1.01, True)])
def test_tipped_ship_lifts_off_when_its_engine_points_up_enough(ratio, lifts):
    tilt = 81.0
    max_thrust = ratio * M * G / math.cos(math.radians(tilt))
    recs = records(scene({"state": "tipped", "tilt_deg": tilt},
                         ship={"max_thrust": max_thrust, "fuel_mass": 5000.0},
                         inputs=[{"t": 0.0, "throttle": 1.0}], duration=0.2))
    assert ("ship.liftoff" in topics(recs)) == lifts


# -- touchdown alignment (SEED-NOTES 6) -----------------------------------------------------------
@pytest.mark.parametrize("align", [True, False])
def test_align_on_touchdown(align):
    recs = records(scene({"altitude": 0.2, "vertical_speed": -1.0, "tilt_deg": 10.0,
                          "angular_velocity": [0.1, 0.0, 0.0]},
                         contact={"align_on_touchdown": align}, duration=0.6))
    tick = events(recs)[0][0]
    assert events(recs)[0][1] == "ship.contact"
    tilt = tilt_deg(recs)[tick]
    if align:
        assert tilt < 0.05
    else:
        assert tilt > 9.0


# -- landing on a slope (MODEL-NOTES 44) ----------------------------------------------------------
def _on_slope(slope_deg, ship=None, **contact):
    alt = -G * math.cos(math.radians(slope_deg)) ** 2 / 100.0
    return records(scene({"state": "contact", "altitude": alt, "tilt_deg": slope_deg}, ship=ship,
                         contact=contact or None,
                         body={"terrain": {"slope_deg": slope_deg, "slope_azimuth_deg": 0.0}},
                         duration=8.0))


def test_a_ship_standing_square_on_a_slope_lands_and_one_sliding_does_not():
    """The settle tilt is measured from the ground's normal: a ship at rest on its four feet on a
    30 degree slope lands; with the seed's radial normal its 30 degrees from local vertical never
    settle. On 40 degrees (above atan(mu_s) = 38.66) it slides off from rest, slower than
    settle_linear_vel for its first second, and does not land while its feet slide (a squat ship:
    the default one would tip, 40 degrees being past its atan(a / h) = 37)."""
    assert final_state(_on_slope(30.0)) is SurfaceState.LANDED
    assert final_state(_on_slope(30.0, surface_normal="radial")) is SurfaceState.CONTACT
    recs = _on_slope(40.0, ship={"com_height": 0.5, "leg_radius": 3.0})
    assert topics(recs) == []
    assert np.linalg.norm(recs[-1].state.vel_mps[0]) > 2.0  # g (sin a - mu_k cos a) t: 3.4 m/s
