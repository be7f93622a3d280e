"""No more model than a scene needs: each cheaper model a ship may be given, checked against the
full model or an independent reference.

* vertical: an upright ship moving only along local up takes one exact step a tick instead of
  sub-steps (sim.phases.purely_vertical); it must match the sub-stepped full model.
* coarse flight: a ship far above the ground takes one step a tick with no contact work; its fall
  must match point-mass gravity, and it must never be caught below the ground.
* pivot: a tipped ship turns about its low foot (sim.phases.pinned); it must match the full model
  of the same fall, feet, friction and all.
"""
import math

import numba
import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from scenes import events, one_ship, records, scene, series, tilt_deg, topics
from touchdown.sim.constants import MOON_GM_M3PS2, MOON_RADIUS_M
from touchdown.sim.enums import EventKind
from touchdown.sim.dynamics import Motion, contact_at, ground_at, with_feet
from touchdown.sim.flight import (DRAG_REACH, MICRO_SLIP_MPS, NEAR_CONE, NO_RATES,
                                  TRANSITION_PIECE, TURN_REACH, EnergyRef, FootEvents, PieceStart,
                                  SlipRates, _stop_time, at_transition, no_memo, stiff_feet, turns)
from touchdown.sim.settings import Integrator
from touchdown.sim.ship import ENGAGE_AT_GROUND, NO_HOLD, NO_SLIP, Footing, Ship
from touchdown.sim.phases import clear_tick, commands, free_body, near_ground, purely_vertical
from touchdown.sim.step import step

G = MOON_GM_M3PS2 / MOON_RADIUS_M ** 2


# -- vertical ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("initial,inputs", [
    ({"altitude": 0.3, "vertical_speed": -20.0}, []),
    ({"altitude": 0.3, "vertical_speed": -45.0}, []),
    ({"altitude": 2.0, "vertical_speed": -3.0}, []),  # absorbed
    ({"altitude": 1.0, "vertical_speed": -15.0}, [{"t": 0.5, "throttle": 1.0}]),  # thrusts off
])
def test_one_vertical_step_a_tick_matches_the_sub_stepped_full_model(initial, inputs):
    """At the live service's 10 Hz tick: one exact step a tick against four 25 ms sub-steps of
    the full model, both the exponential method (the vertical step the default ``hybrid`` takes);
    the same transitions on the same ticks, positions and speeds to 1e-7 of the motion's own
    scale (each holds gravity at its step's start value where it locates the touchdown, and g
    changes by 2 dr / R ~ 1e-6 over a metre's fall, at second order)."""
    runs = {}
    for one_step in (True, False):
        runs[one_step] = records(scene(initial, inputs=inputs, duration=6.0,
                                       sim={"dt": 0.1, "vertical_one_step": one_step,
                                            "integrator": "exponential"}))
    fast, full = runs[True], runs[False]
    ev_fast, ev_full = events(fast), events(full)
    assert [(t, name) for t, name, _ in ev_fast] == [(t, name) for t, name, _ in ev_full]
    assert [v for _, _, v in ev_fast] == pytest.approx([v for _, _, v in ev_full], rel=1e-7)
    assert len(ev_fast) >= 2
    alt_fast, alt_full = series(fast, "altitude_m"), series(full, "altitude_m")
    scale = np.abs(alt_full).max()
    assert np.max(np.abs(alt_fast - alt_full)) <= 1e-7 * scale
    v_fast, v_full = series(fast, "v_radial_mps"), series(full, "v_radial_mps")
    assert np.max(np.abs(v_fast - v_full)) <= 1e-7 * np.abs(v_full).max()


def _vertical_runs(initial, inputs, dt, mass, duration):
    """The same scene with the vertical path (sim.vertical_path, MODEL-NOTES 65) and without it
    (free_flight's pieces and friction for the same one exact step a tick)."""
    return [records(scene(initial, ship={"mass": mass, "fuel_mass": 0.2 * mass}, inputs=inputs,
                          duration=duration,
                          sim={"dt": dt, "vertical_path": path})) for path in (True, False)]


def _all_events(recs):
    return [(r.tick, EventKind(e.kind).topic, e.v_radial_mps, e.t_event_s) for r in recs
            for e in r.events]


@settings(max_examples=50, deadline=None, derandomize=True, database=None,
          phases=[Phase.explicit, Phase.generate], suppress_health_check=[HealthCheck.too_slow])
@given(altitude=st.floats(0.0, 6.0), vertical=st.floats(-49.0, 2.0),
       contact=st.sampled_from([False, False, False, True]), sag=st.floats(0.3, 2.5),
       mass=st.floats(2000.0, 30000.0), of_hover=st.floats(0.0, 0.95),
       change_at=st.floats(0.0, 2.0), of_hover_after=st.floats(0.0, 0.95),
       dt=st.sampled_from([0.02, 0.05, 0.1, 0.2]))
def test_the_vertical_path_agrees_with_the_general_one(altitude, vertical, contact, sag, mass,
                                                       of_hover, change_at, of_hover_after, dt):
    """sim.vertical_path (MODEL-NOTES 65) against free_flight's general pieces for the same one
    exact step a tick, over vertical drops at any speed to 49 m/s (bounces, absorbed landings)
    and contact starts, masses 2-30 t, throttle below the hover's changed once, ticks of 20-200
    ms: the same events on the same ticks, their instants to 1e-8 s and speeds to 1e-8; every
    tick's state and telemetry to 1e-7 of the motion's scale (the feet's onset located by the
    ballistic flow's root instead of trial steps, no friction solve: four sticking feet's
    impulses of rounding's size)."""
    hover = mass * G / 60000.0
    initial = ({"state": "contact", "altitude": -sag * G / 100.0} if contact
               else {"altitude": altitude, "vertical_speed": vertical})
    inputs = [{"t": 0.0, "throttle": of_hover * hover},
              {"t": change_at, "throttle": of_hover_after * hover}]
    new, old = _vertical_runs(initial, inputs, dt, mass, 4.0)
    ev_new, ev_old = _all_events(new), _all_events(old)
    assert [e[:2] for e in ev_new] == [e[:2] for e in ev_old]
    for a, b in zip(ev_new, ev_old):
        assert abs(a[3] - b[3]) <= 1e-8
        assert abs(a[2] - b[2]) <= 1e-8 * max(1.0, abs(b[2]))
    assert [int(r.state.surface_state[0]) for r in new] == [int(r.state.surface_state[0])
                                                             for r in old]
    v_scale = max(1.0, float(np.abs(series(old, "v_radial_mps")).max()))
    for name, scale in (("altitude_m", v_scale), ("penetration_m", v_scale),
                        ("peak_penetration_m", v_scale), ("v_radial_mps", v_scale),
                        ("v_tangential_mps", v_scale), ("normal_force_n", mass * 100.0 * v_scale),
                        ("friction_force_n", mass * 100.0 * v_scale)):
        assert np.max(np.abs(series(new, name) - series(old, name))) <= 1e-7 * scale, name
    for field in ("pos_m", "vel_mps"):
        a = np.array([getattr(r.state, field)[0] for r in new])
        b = np.array([getattr(r.state, field)[0] for r in old])
        assert np.max(np.abs(a - b)) <= 1e-7 * v_scale, field


@pytest.mark.parametrize("path", [
    {},  # the vertical path (MODEL-NOTES 65)
    {"vertical_path": False},  # free_flight's pieces, one exponential step a tick
    {"vertical_path": False, "vertical_one_step": False, "integrator": "exponential"},
    {"vertical_path": False, "vertical_one_step": False},  # hybrid's sub-steps
])
def test_an_absorbed_thrust_off_follows_the_closed_model(path):
    """A ship held by its absorbers (bilateral while a foot is in the ground) thrusting off at
    three times its weight: its liftoff tick against solve_ivp of the same one-dimensional
    model (the four feet's springs and absorbers along their legs' lines to the ground,
    point-mass gravity), from the tick's start state, to 1e-8 m/s by the exact flow (1e-4 by
    rk4's sub-steps). free_flight's exponential steps were 0.047 m/s slow here, 30% of the
    tick's gain, before sim.flow_release (MODEL-NOTES 66)."""
    init, thrust = {"state": "contact", "altitude": -0.023864446829639355}, 48000.0
    recs = records(scene(init, inputs=[{"t": 0.0, "throttle": thrust / 60000.0}],
                         sim={"dt": 0.05, **path}, duration=0.2))
    (lift,) = [r for r in recs if r.events]
    start = recs[recs.index(lift) - 1]
    p, v = np.array(start.state.pos_m[0]), np.array(start.state.vel_mps[0])
    mass = float(start.state.mass_kg[0])
    k, c = 100.0 * mass, 2.0 * 1.0 * math.sqrt(100.0 * mass * mass)  # absorb_damping_ratio 1
    a, h = 2.26, 3.0  # leg radius, centre of mass height
    r0 = float(np.linalg.norm(p))

    def motion(t, y):
        r, vr = r0 + y[0], y[1]
        foot = math.sqrt((r - h) ** 2 + a * a)
        pen, gamma = MOON_RADIUS_M - foot, (r - h) / foot
        push = (k * pen - c * gamma * vr) * gamma if pen > 0.0 else 0.0
        return [vr, -MOON_GM_M3PS2 / r ** 2 + (thrust + push) / mass]

    sol = solve_ivp(motion, (0.0, 0.05), [0.0, float(v @ p) / r0], method="DOP853", rtol=1e-12,
                    atol=1e-14, max_step=2.5e-4)
    assert EventKind(lift.events[0].kind).topic == "ship.liftoff"
    exact = path.get("integrator") == "exponential" or path.get("vertical_one_step", True)
    assert float(lift.outputs.v_radial_mps[0]) == pytest.approx(sol.y[1, -1],
                                                                abs=1e-8 if exact else 1e-4)
    assert float(lift.outputs.altitude_m[0]) > 0.0


def test_the_flow_release_setting_keeps_the_old_pull():
    """sim.flow_release = false keeps the pull on through the release's trials with the
    exponential method too: the old liftoff, 25% slow (MODEL-NOTES 66)."""
    init, thrust = {"state": "contact", "altitude": -0.023864446829639355}, 48000.0
    lifts = []
    for flow in (True, False):
        recs = records(scene(init, inputs=[{"t": 0.0, "throttle": thrust / 60000.0}],
                             sim={"dt": 0.05, "vertical_path": False, "flow_release": flow},
                             duration=0.2))
        (lift,) = [r for r in recs if r.events]
        lifts.append(float(lift.outputs.v_radial_mps[0]))
    assert lifts[0] == pytest.approx(0.2008823328, abs=1e-8)  # solve_ivp's, the test above
    assert lifts[1] < lifts[0] - 0.04


def test_the_vertical_model_is_used_only_where_nothing_else_moves():
    """Bouncing upright ships qualify; a ship that is tilted, turning, slipping or torqued by a
    millionth, that stands by a bump, or sits on a spinning body does not."""
    def qualifies(initial=None, body=None, inputs=None):
        scn = scene(initial or {"altitude": 0.5, "vertical_speed": -20.0}, body=body,
                    inputs=inputs or [])
        inp = scn.inputs_at(0)
        here, ship, rec = one_ship(scn.params, scn.initial, inp)
        return bool(purely_vertical(here, ship, commands(here, ship, rec)))

    assert qualifies()
    assert qualifies({"state": "contact", "altitude": -0.016})
    assert not qualifies({"altitude": 0.5, "vertical_speed": -20.0, "tilt_deg": 1e-4})
    assert not qualifies({"altitude": 0.5, "angular_velocity": [0.0, 1e-6, 0.0]})
    assert not qualifies({"altitude": 0.5, "horizontal_speed": 1e-6})
    assert not qualifies(inputs=[{"t": 0.0, "rcs": [0.0, 1e-6, 0.0]}])
    bump = {"terrain": {"bumps": [{"east": 5.0, "north": 0.0, "radius": 4.0, "height": 0.5}]}}
    assert not qualifies(body=bump)
    far_bump = {"terrain": {"bumps": [{"east": 50.0, "north": 0.0, "radius": 4.0, "height": 0.5}]}}
    assert qualifies(body=far_bump)
    assert not qualifies(body={"rotation_period": 27.3 * 86400.0})


# -- coarse flight ------------------------------------------------------------------------------------
def test_a_long_fall_in_coarse_flight_matches_point_mass_gravity():
    """From 500 m at rest (coarse flight nearly all the way, ~25 s), the feet reach the ground
    when and as fast as the radial two-body solution says (solve_ivp, rtol 1e-12)."""
    h0, com = 500.0, 3.0
    recs = records(scene({"altitude": h0, "vertical_speed": 0.0}, duration=30.0))
    (tick, name, v_imp), = [e for e in events(recs) if e[1] == "ship.contact"]
    r_touch = math.sqrt(MOON_RADIUS_M ** 2 - 2.26 ** 2) + com  # centre of mass as the feet touch
    r0 = float(np.linalg.norm(recs[0].state.pos_m[0]))
    ground = lambda t, y: y[0] - r_touch  # noqa: E731
    ground.terminal, ground.direction = True, -1
    sol = solve_ivp(lambda t, y: [y[1], -MOON_GM_M3PS2 / y[0] ** 2], (0.0, 200.0), [r0, 0.0],
                    events=[ground], method="DOP853", rtol=1e-12, atol=1e-9)
    t_ref, v_ref = float(sol.t_events[0][0]), float(sol.y_events[0][0][1])
    dt = 0.05
    assert (tick - 1) * dt < t_ref <= tick * dt  # the contact is reported in the right tick
    assert -v_imp == pytest.approx(-v_ref, rel=1e-9)


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          phases=[Phase.explicit, Phase.generate], suppress_health_check=[HealthCheck.too_slow])
@given(altitude=st.floats(0.0, 300.0), vertical=st.floats(-150.0, 30.0),
       horizontal=st.floats(0.0, 80.0), tilt=st.floats(0.0, 179.0),
       throttle=st.floats(0.0, 1.0), dt=st.sampled_from([0.02, 0.05, 0.1, 0.5, 1.0]),
       slope=st.sampled_from([0.0, 0.0, 20.0, 55.0]), azimuth=st.floats(-180.0, 180.0),
       heading=st.floats(-180.0, 180.0), east=st.floats(-500.0, 500.0))
def test_coarse_flight_is_never_caught_below_the_ground(altitude, vertical, horizontal, tilt,
                                                        throttle, dt, slope, azimuth, heading,
                                                        east):
    """A ship the step judges far from the ground (one step, no contact work) never ends the tick
    with a foot below it: the near-ground test is conservative for any speed, attitude, thrust,
    tick, slope and place on it."""
    scn = scene({"altitude": altitude, "vertical_speed": vertical, "horizontal_speed": horizontal,
                 "tilt_deg": tilt, "heading_deg": heading, "east": east},
                inputs=[{"t": 0.0, "throttle": throttle}],
                sim={"dt": dt, "on_unstable": "allow"}, contact={"align_on_touchdown": False},
                body={"terrain": {"slope_deg": slope, "slope_azimuth_deg": azimuth}},
                duration=dt)
    inp = scn.inputs_at(0)
    here, ship, rec = one_ship(scn.params, scn.initial, inp)
    far = not near_ground(here, ship, commands(here, ship, rec))
    _, out, _ = step(scn.params, scn.initial, inp)
    if far:
        assert out.altitude_m[0] > 0.0


@settings(max_examples=120, deadline=None, derandomize=True, database=None,
          phases=[Phase.explicit, Phase.generate], suppress_health_check=[HealthCheck.too_slow])
@given(altitude=st.floats(0.0, 8.0), vertical=st.floats(-30.0, 10.0),
       horizontal=st.floats(0.0, 20.0), tilt=st.floats(0.0, 120.0),
       spin=st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3),
       throttle=st.floats(0.0, 1.0), rcs=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
       dt=st.sampled_from([0.02, 0.05, 0.1, 0.25]),
       slope=st.sampled_from([0.0, 0.0, 6.0, 20.0, 40.0]), azimuth=st.floats(-180.0, 180.0),
       heading=st.floats(-180.0, 180.0))
def test_a_tick_judged_clear_touches_nothing(altitude, vertical, horizontal, tilt, spin,
                                             throttle, rcs, dt, slope, azimuth, heading):
    """sim.clear_tick (MODEL-NOTES 63): a flying ship near the ground that the step judges clear of
    it for the whole tick (one step, no contact work) is one that the sub-stepped flight with
    every contact evaluation (sim.clear_tick false) finds touching nothing in that tick: no
    transition, every foot still above the ground at its end; starts low and turning, under
    thrust and RCS, on slopes, where the feet's bound is tight. (Its one step's error is the far
    flight's: a ship tumbling at 2 rad/s under RCS ends 0.1 mm from the sub-steps' height.)"""
    def scn(clear):
        return scene({"altitude": altitude, "vertical_speed": vertical,
                      "horizontal_speed": horizontal, "tilt_deg": tilt, "heading_deg": heading,
                      "angular_velocity": spin},
                     inputs=[{"t": 0.0, "throttle": throttle, "rcs": rcs}],
                     sim={"dt": dt, "on_unstable": "allow", "clear_tick": clear},
                     contact={"align_on_touchdown": False},
                     body={"terrain": {"slope_deg": slope, "slope_azimuth_deg": azimuth}},
                     duration=dt)
    judged = scn(True)
    inp = judged.inputs_at(0)
    here, ship, rec = one_ship(judged.params, judged.initial, inp)
    cmd = commands(here, ship, rec)
    if not (near_ground(here, ship, cmd) and clear_tick(here, ship, cmd)):
        return
    full = scn(False)
    _, out, evs = step(full.params, full.initial, full.inputs_at(0))
    assert evs == [] and out.altitude_m[0] > 0.0
    _, out_clear, evs_clear = step(judged.params, judged.initial, inp)
    assert evs_clear == [] and out_clear.altitude_m[0] > 0.0


def test_a_ship_hovering_near_the_ground_flies_its_ticks_whole():
    """sim.clear_tick (MODEL-NOTES 63): a ship hovering with its feet a metre up is judged clear
    (its feet cannot reach the ground in a tick), one with them 5 cm up is not; the hover and a
    slow descent onto the ground make the same transitions at the same instants (1e-7 s) with and
    without it, and heights within a micrometre."""
    hover = [{"t": 0.0, "throttle": 10000.0 * G / 60000.0}]
    for alt, clear in ((1.0, True), (0.05, False)):
        scn = scene({"altitude": alt, "vertical_speed": 0.0}, inputs=hover)
        inp = scn.inputs_at(0)
        here, ship, rec = one_ship(scn.params, scn.initial, inp)
        cmd = commands(here, ship, rec)
        assert near_ground(here, ship, cmd) and bool(clear_tick(here, ship, cmd)) == clear
    descent = [{"t": 0.0, "throttle": 0.9 * 10000.0 * G / 60000.0}, {"t": 2.5, "throttle": 0.0}]
    runs = {c: records(scene({"altitude": 1.5, "vertical_speed": -0.5, "tilt_deg": 3.0},
                             inputs=descent, sim={"clear_tick": c}, duration=10.0))
            for c in (False, True)}
    _same_flight(runs, False, True, 1e-7, 1e-6)


# -- pivot ----------------------------------------------------------------------------------------------
def test_the_pivot_model_of_a_tipped_ship_matches_the_full_model():
    """A lander toppling from 5 deg past its critical angle: the default hands it to the pivot
    model at tipped_angle (80 deg); a second run keeps the full model (feet, springs, friction) to
    89 deg. Both reach 85 and 88 deg within two ticks of each other."""
    crit = math.degrees(math.atan2(2.26, 3.0))
    start = {"state": "contact", "altitude": -G / 100.0, "tilt_deg": crit + 5.0}
    pivot = records(scene(start, duration=6.0))
    full = records(scene(start, duration=6.0, contact={"tipped_angle_deg": 89.0,
                                                        "tipped_rest_deg": 90.0}))
    assert "ship.tipped" in topics(pivot)
    dt = 0.05
    for angle in (85.0, 88.0):
        t_pivot = int(np.argmax(tilt_deg(pivot) >= angle)) * dt
        t_full = int(np.argmax(tilt_deg(full) >= angle)) * dt
        assert t_pivot > 0 and t_full > 0
        assert abs(t_pivot - t_full) <= 2 * dt + 1e-9, (angle, t_pivot, t_full)


# -- an impact's clear stretches ----------------------------------------------------------------------
#: fast approaches to a touchdown: (initial, body)
FAST_APPROACHES = [
    # the envelope's worst corner: 12 m/s down, 6 m/s downhill, tilted, onto 6 degrees
    ({"altitude": 0.5, "vertical_speed": -12.0, "horizontal_speed": 6.0, "tilt_deg": 15.0,
      "heading_deg": 90.0}, {"terrain": {"slope_deg": 6.0, "slope_azimuth_deg": 90.0}}),
    # a fall from 2 m onto level ground, tilted a little
    ({"altitude": 2.0, "vertical_speed": -6.0, "tilt_deg": 5.0}, {}),
    # a fast approach from 1.5 m onto 12 degrees, moving across the slope
    ({"altitude": 1.5, "vertical_speed": -8.0, "horizontal_speed": 5.0, "tilt_deg": 10.0,
      "heading_deg": 45.0}, {"terrain": {"slope_deg": 12.0}}),
]


def _same_flight(runs, a, b, instant_s, altitude_m):
    """Runs ``runs[a]`` and ``runs[b]`` make the same transitions on the same ticks (two at least),
    each at its instant to ``instant_s``, and keep the altitude within ``altitude_m`` at every
    tick; they are not the same bits."""
    ev = {c: [(r.tick, EventKind(e.kind).topic, float(e.t_event_s)) for r in runs[c]
              for e in r.events] for c in runs}
    assert [(k, n) for k, n, _ in ev[a]] == [(k, n) for k, n, _ in ev[b]]
    assert len(ev[a]) >= 2
    assert [t for _, _, t in ev[a]] == pytest.approx([t for _, _, t in ev[b]], abs=instant_s)
    alt = {c: series(runs[c], "altitude_m") for c in runs}
    assert np.max(np.abs(alt[a] - alt[b])) <= altitude_m
    assert np.any(alt[a] != alt[b])


@pytest.mark.parametrize("initial,body", FAST_APPROACHES)
def test_an_impacts_clear_stretches_taken_whole_move_no_event(initial, body):
    """sim.coarse_when_clear (MODEL-NOTES 54): in an impact's tick a flying ship whose feet cannot
    reach the ground within a max_substep takes it as one sub-step. Against every sub-step at
    impact_substep: the same transitions on the same ticks, each at its instant to 1e-6 s (they
    are located, whatever the sub-step), and the altitude within 1 mm at every tick; the runs are
    not the same bits (the coarse stretches were taken). With its centre's speed deciding whether
    a flying ship strikes (sim.flying_strike_by_centre, 0.8's), where such stretches are many."""
    runs = {c: records(scene(initial, body=body, duration=8.0,
                             sim={"coarse_when_clear": c, "flying_strike_by_centre": True}))
            for c in (True, False)}
    _same_flight(runs, True, False, 1e-6, 1e-3)


@pytest.mark.parametrize("initial,body", FAST_APPROACHES)
def test_a_flying_ship_strikes_only_where_a_foot_can_meet_the_ground(initial, body):
    """MODEL-NOTES 60: a flying ship takes the impact's 5 ms sub-steps only where one of its feet
    can meet the ground within the tick (sim.phases.striking), not wherever its centre of mass
    falls faster than 1 m/s near the ground (sim.flying_strike_by_centre, 0.8's). The approach
    to a fast touchdown and a bounce's flight are free flight either way: the same transitions on
    the same ticks, each at its instant to 1e-7 s, the altitude within a micrometre at every
    tick (measured: 4e-9 s, 3.3e-9 m); not the same bits (the approach was stepped otherwise)."""
    runs = {c: records(scene(initial, body=body, duration=8.0,
                             sim={"flying_strike_by_centre": c})) for c in (False, True)}
    _same_flight(runs, False, True, 1e-7, 1e-6)


# -- coarse contact sub-steps -----------------------------------------------------------------------
@pytest.mark.parametrize("initial,body", [
    # sliding downhill at 3 m/s on the envelope's 6 degree slope, until it trips
    ({"state": "contact", "altitude": -0.01625, "horizontal_speed": 3.0, "heading_deg": 90.0},
     {"terrain": {"slope_deg": 6.0, "slope_azimuth_deg": 90.0}}),
    # the envelope's base case: 2 m/s down, 1 m/s downhill
    ({"altitude": 0.5, "vertical_speed": -2.0, "horizontal_speed": 1.0, "heading_deg": 90.0},
     {"terrain": {"slope_deg": 6.0, "slope_azimuth_deg": 90.0}}),
    # a tilted touchdown with sideways speed onto level ground
    ({"altitude": 1.0, "vertical_speed": -3.0, "horizontal_speed": 2.0, "tilt_deg": 8.0,
      "heading_deg": 30.0}, {}),
    # standing tilted 20 degrees: it rocks down onto its feet and settles
    ({"state": "contact", "altitude": -0.01625, "tilt_deg": 20.0}, {}),
])
def test_coarse_contact_sub_steps_follow_the_fine_ones(initial, body):
    """sim.coarse_substep (MODEL-NOTES 57): a ship in contact takes one 50 ms sub-step a tick
    where nothing the 25 ms ones resolve can happen in it. Against max_substep's sub-steps
    throughout: the same transitions on the same ticks, each at its instant to 1e-4 s (measured:
    4.2e-5 at most), the centre of mass within 1 mm at every tick (7.3e-5 m); the runs are not
    the same bits (the coarse sub-steps were taken)."""
    runs = {c: records(scene(initial, body=body, duration=12.0, sim={"coarse_substep": c}))
            for c in (0.05, 0.0)}
    ev = {c: [(r.tick, EventKind(e.kind).topic, float(e.t_event_s)) for r in runs[c]
              for e in r.events] for c in runs}
    assert [(k, n) for k, n, _ in ev[0.05]] == [(k, n) for k, n, _ in ev[0.0]]
    assert len(ev[0.05]) >= 1
    assert [t for _, _, t in ev[0.05]] == pytest.approx([t for _, _, t in ev[0.0]], abs=1e-4)
    pos = {c: np.array([r.state.rows[0]["pos_m"] for r in runs[c]]) for c in runs}
    assert np.max(np.linalg.norm(pos[0.05] - pos[0.0], axis=1)) <= 1e-3
    assert np.any(pos[0.05] != pos[0.0])


@pytest.mark.parametrize("initial, changes", [
    # bench/states.py's sliding row: its side feet press 8-10 mm, pushing, near no release
    # (16 of its first 40 ticks now take the coarse sub-step)
    ({"state": "contact", "altitude": -0.01625, "horizontal_speed": 3.0}, True),
    # the same sliding downhill on the envelope's slope (no tick takes the new sub-step)
    ({"state": "contact", "altitude": -0.01625, "horizontal_speed": 3.0, "heading_deg": 90.0},
     False),
])
def test_coarse_sub_steps_with_a_release_follow_the_fine_ones(initial, changes):
    """sim.coarse_release (MODEL-NOTES 68): a quiet contact tick's coarse sub-step is no longer
    refused for a pressing foot near its release (the release is located inside it). Against
    max_substep's sub-steps throughout: the same transitions on the same ticks, each at its
    instant to 1e-4 s, the centre of mass within 1 mm at every tick; against the setting false,
    within the same 1 mm, and not the same bits where a tick took the new coarse sub-step."""
    body = {"terrain": {"slope_deg": 6.0, "slope_azimuth_deg": 90.0}} if initial.get(
        "heading_deg") else {}
    runs = {k: records(scene(initial, body=body, duration=4.0, sim=sim)) for k, sim in (
        ("new", {}), ("old", {"coarse_release": False}), ("fine", {"coarse_substep": 0.0}))}
    ev = {k: [(r.tick, EventKind(e.kind).topic, float(e.t_event_s)) for r in runs[k]
              for e in r.events] for k in runs}
    assert [(k, n) for k, n, _ in ev["new"]] == [(k, n) for k, n, _ in ev["fine"]]
    assert [t for _, _, t in ev["new"]] == pytest.approx([t for _, _, t in ev["fine"]], abs=1e-4)
    pos = {k: np.array([r.state.rows[0]["pos_m"] for r in runs[k]]) for k in runs}
    assert np.max(np.linalg.norm(pos["new"] - pos["fine"], axis=1)) <= 1e-3
    assert np.max(np.linalg.norm(pos["new"] - pos["old"], axis=1)) <= 1e-3
    assert np.any(pos["new"] != pos["old"]) == changes


@pytest.mark.parametrize("initial, duration", [
    # case 252 of the envelope's 300: its margin sinks back to zero 0.37 s into its run of
    # samples and dips under inside a tick (by the time held alone it landed 0.415 s early)
    ({"altitude": 0.5, "vertical_speed": -4.189924582420963,
      "horizontal_speed": 4.892093374164177, "heading_deg": 90.0,
      "tilt_deg": 7.945431338442698}, 15.0),
    # the envelope's base case: it rocks back through a threshold 0.2 s into its first run (by
    # the margin alone its landing moved 2e-4 s from max_substep's sub-steps')
    ({"altitude": 0.5, "vertical_speed": -2.0, "horizontal_speed": 1.0, "heading_deg": 90.0},
     12.0),
])
def test_a_ship_at_rest_takes_the_coarse_sub_step(initial, duration):
    """sim.coarse_held (MODEL-NOTES 69): a contact tick that starts with the settle thresholds
    held for 0.1 s already, and by over a quarter of each, takes the coarse sub-step. Two
    envelope touchdowns make the same transitions on the same ticks as with the setting off and
    as with max_substep's sub-steps throughout, and land: each instant within 1e-4 s of the
    setting off's (measured 3.9e-5) and no further from max_substep's than the setting off's
    plus 1e-4 s (case 252's 1.0 ms is note 57's coarse sub-steps'), the centre of mass within
    1 mm of max_substep's at every tick (note 57's); not the setting off's bits."""
    body = {"terrain": {"slope_deg": 6.0, "slope_azimuth_deg": 90.0}}
    runs = {k: records(scene(initial, body=body, duration=duration, sim=sim)) for k, sim in (
        ("new", {}), ("old", {"coarse_held": 0.0}), ("fine", {"coarse_substep": 0.0}))}
    ev = {k: [(r.tick, EventKind(e.kind).topic, float(e.t_event_s)) for r in runs[k]
              for e in r.events] for k in runs}
    assert ev["new"][-1][1] == "ship.landed"
    t = {k: np.array([x for _, _, x in ev[k]]) for k in runs}
    for other in ("old", "fine"):
        assert [(k, n) for k, n, _ in ev["new"]] == [(k, n) for k, n, _ in ev[other]]
    assert np.max(np.abs(t["new"] - t["old"])) <= 1e-4
    assert np.max(np.abs(t["new"] - t["fine"])) <= np.max(np.abs(t["old"] - t["fine"])) + 1e-4
    pos = {k: np.array([r.state.rows[0]["pos_m"] for r in runs[k]]) for k in runs}
    assert np.max(np.linalg.norm(pos["new"] - pos["fine"], axis=1)) <= 1e-3
    assert np.any(pos["new"] != pos["old"])


@pytest.mark.parametrize("ratio, turning", [(0.5 * (1.0 - 1e-9), False), (0.5 * (1.0 + 1e-9), True)])
def test_a_stopping_slip_that_turns_past_turn_reach_is_stepped_in_pieces(ratio, turning):
    """Outside an impact, a foot coming to a stop takes note 51's half-approach pieces only where
    its slip turns on its way (MODEL-NOTES 58): what turns it, over what slows it, past
    TURN_REACH = 0.5 (about the angle it turns through before it stops). Its edge, for one
    foot slowing at 3 m/s^2 while another foot, not stopping, turns fast."""
    assert TURN_REACH == 0.5
    z = (0.0, 0.0, 0.0)
    stop = FootEvents((False,) * 4, (False,) * 4, (False, True, False, False),
                      (z, (1.0, 0.0, 0.0), z, z), (0.0, 0.2, 0.0, 0.0), 0.0, True)
    sr = SlipRates((0.3, 0.2, 0.0, 0.0), (1.0, -3.0, 0.0, 0.0), (2.0, 4.0, 0.0, 0.0),
                   (50.0, 3.0 * ratio, 0.0, 0.0))
    assert turns(stop, sr) is turning


# -- the stick/slip transition's pieces (MODEL-NOTES 58, 61) ---------------------------------------
@numba.njit(inline="always")
def _standing(here, s, inp, slip_mps, hold_of_cone):
    """``s`` standing on level ground, its four feet pressing, as a piece's start: foot 0 holding
    with ``hold_of_cone`` of its static cone mu_s N (``slip_mps`` 0), or sliding at ``slip_mps``
    and dragged. Returns (its FreeBody, the sim.flight.PieceStart, foot 0's N). (Inlined into
    compiled probes: a FreeBody holds a record, which numba cannot return from a call.)"""
    cmd = commands(here, s, inp)
    m0 = s.motion
    m = Motion(m0.p, (m0.v[0], m0.v[1] + slip_mps, m0.v[2]), m0.q, m0.w)
    sliding = (slip_mps > 0.0, False, False, False)
    fb = with_feet(free_body(here, s, cmd, True, RK4), ENGAGE_AT_GROUND, sliding)
    ce = contact_at(fb, ground_at(fb, 0.0), m, False, ENGAGE_AT_GROUND)
    load_n = ce.foot_force_n[0] * ce.push_norm[0]
    z = (0.0, 0.0, 0.0)
    hold_w = ((0.0, hold_of_cone * here.cfg.friction_static * load_n, 0.0), z, z, z)
    ft = s.footing
    ship = Ship(s.surface_state, m, s.mass_kg, s.fuel_kg,
                Footing(ft.absorbing, sliding, ft.settle_ticks, ft.settle_for_s, ft.settle_margin,
                        hold_w), s.pin)
    start = PieceStart(ship, 0.0, ENGAGE_AT_GROUND, sliding, ce, NO_HOLD, False,
                       EnergyRef(0.0, 0.0, 0.0), False, no_memo(m))
    return fb, start, load_n


@numba.njit(cache=True)  # in sim.compiled.cache_dir(), named after sim/'s sources
def _at_transition_standing(here, s, inp, slip_mps, hold_of_cone, h_of_edge):
    """sim.flight.at_transition at :func:`_standing`'s start, foot 0 not slowing, asked for a
    piece of ``h_of_edge`` times the one in whose TRANSITION_PIECE its own kinetic friction would
    stop it (sliding) or of 1 ms (holding). Returns (at_transition, foot 0's N)."""
    fb, start, load_n = _standing(here, s, inp, slip_mps, hold_of_cone)
    h_s = 1e-3
    if slip_mps > 0.0:
        t_stop = _stop_time(here.cfg, fb, start.ce, start.ship.motion.q, 0)
        h_s = h_of_edge * t_stop / (DRAG_REACH * TRANSITION_PIECE)
    return at_transition(here.cfg, fb, start, NO_RATES, h_s), load_n


@numba.njit(cache=True)
def _stiff_feet_standing(here, s, inp, slip_mps, floor_s):
    """sim.flight.stiff_feet at :func:`_standing`'s start, foot 0 sliding at ``slip_mps``, not
    slowing, over a 25 ms sub-step. Returns (the shortest stop time of the feet that take pieces,
    foot 0's own stop time)."""
    fb, start, _ = _standing(here, s, inp, slip_mps, 0.0)
    t_stop = _stop_time(here.cfg, fb, start.ce, start.ship.motion.q, 0)
    return stiff_feet(here.cfg, fb, start, NO_RATES, 0.025, NO_SLIP, floor_s), t_stop


RK4 = int(Integrator.RK4)


@pytest.fixture(scope="module")
def standing():
    """A lander standing on level ground after a 1 m/s touchdown (contact, before it lands)."""
    scn = scene({"altitude": 0.0, "vertical_speed": -1.0}, duration=0.6)
    rec = [r for r in records(scn) if int(r.state.surface_state[0]) == 1][-1]
    return one_ship(scn.params, rec.state)


@pytest.mark.parametrize("of_cone, at", [(NEAR_CONE * (1.0 - 1e-9), False),
                                         (NEAR_CONE * (1.0 + 1e-9), True)])
def test_a_foot_holding_near_its_cone_is_at_its_transition(standing, of_cone, at):
    """A stiff foot's pieces go down to its stop time while another foot holds with NEAR_CONE =
    0.9 of mu_s N or more (it may break away inside the piece: MODEL-NOTES 58). Its edge."""
    assert NEAR_CONE == 0.9
    found, load_n = _at_transition_standing(*standing, 0.0, of_cone, 1.0)
    assert load_n > 1000.0  # the foot presses: the lander's weight over four feet
    assert found is at


@pytest.mark.parametrize("of_edge, at", [(1.0 - 1e-9, False), (1.0 + 1e-9, True)])
def test_a_foot_just_broken_away_is_at_its_transition(standing, of_edge, at):
    """... or while a foot slides, not slowing, so slowly that its own friction could stop it
    within TRANSITION_PIECE = 0.1 of the piece: it has just broken away. Its edge."""
    assert TRANSITION_PIECE == 0.1
    assert _at_transition_standing(*standing, 0.05, 0.0, of_edge)[0] is at


@pytest.mark.parametrize("slip_mps, pieces", [(MICRO_SLIP_MPS * (1.0 - 1e-9), False),
                                              (MICRO_SLIP_MPS * (1.0 + 1e-9), True)])
def test_a_micro_slip_takes_no_pieces_outside_an_impact(standing, slip_mps, pieces):
    """Outside an impact a sliding foot whose friction could stop it within the sub-step, not
    slowing, takes pieces of its stop time (sim.stiff_substep) unless it slips slower than
    MICRO_SLIP_MPS = 1 mm/s (MODEL-NOTES 61): its edge, for a foot whose stop time is over the
    floor either way; in an impact (floor 0) it takes them at any speed."""
    assert MICRO_SLIP_MPS == 1e-3
    floor_s = 1e-4
    shortest, t_stop = _stiff_feet_standing(*standing, slip_mps, floor_s)
    assert floor_s < t_stop < 0.025
    assert (shortest == t_stop) is pieces and (shortest == math.inf) is not pieces
    assert _stiff_feet_standing(*standing, slip_mps, 0.0)[0] == t_stop
