"""The landing autopilot (service.autopilot): from several starts it flies a ship down to LANDED
with a soft touchdown, reports how an autolanding ended, fails as the physics says when it cannot
land, and its commands are a ship's own bits whatever else it flies. Pure World, no Redis."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from scenes import scene
from touchdown.service.autopilot import (TOUCHDOWN_SPEED_MPS, AutolandCommand, AutolandOutcome,
                               autoland_commands, guidance, throttle_law)
from touchdown.sim.enums import EventKind, HoldMode, SurfaceState
from touchdown.sim.state import State
from touchdown.sim.step import outputs_at
from touchdown.sim.timeline import Timeline
from touchdown.sim.world import World

from test_determinism import varied_fleet

#: most ticks any autolanding here may take (120 s at the default 0.05 s tick)
MAX_TICKS = 2400
#: the touchdown the law must keep under, m/s (it aims at TOUCHDOWN_SPEED_MPS)
SOFT_MPS = 3.0
EARTH = {"name": "Earth", "radius": 6378137.0, "gm": 3.986004418e14}  # scenarios/earth.toml
#: a small moon turning once an hour (scenarios/spinning-moon.toml) with a hill at the site
TURNING_HILL = {"radius": 200000.0, "surface_gravity": 1.0, "rotation_period": 3600.0,
                "terrain": {"bumps": [{"east": 3.0, "north": 1.0, "radius": 30.0, "height": 0.8}]}}


@dataclasses.dataclass
class Flight:
    outcomes: dict[str, AutolandOutcome]
    ticks: dict[str, int]  # ship id -> the tick its outcome was reported at
    events: list  # every transition (sim.state.Event)
    commands: list  # every command the world applied (sim.timeline.Command)
    world: World

    def contacts(self, ship_id: str) -> list[float]:
        return [e.v_radial_mps for e in self.events
                if e.ship_id == ship_id and e.kind == EventKind.CONTACT]

    def states(self, ship_id: str) -> list[int]:
        return [e.to_state for e in self.events if e.ship_id == ship_id]


def autoland(world: World, ids: list[str], max_ticks: int = MAX_TICKS) -> Flight:
    """Engage the autopilot for ``ids`` at the world's tick and fly one tick at a time, as the
    service does, until every autolanding has ended or ``max_ticks``."""
    engaged = list(ids)
    outcomes, ticks, events, applied = {}, {}, [], []
    for _ in range(max_ticks):
        commands, ended = autoland_commands(world, engaged)
        for c in commands:
            world.command(c.ship_id, throttle=c.throttle, rcs=(0.0, 0.0, 0.0), hold=c.hold)
        for sid, outcome in ended.items():
            outcomes[sid], ticks[sid] = outcome, world.tick
        engaged = [s for s in engaged if s not in ended]
        if not engaged:
            break
        for block in world.blocks(world.tick + 1):
            events.extend(block.events)
            applied.extend(block.commands)
    return Flight(outcomes, ticks, events, applied, world)


def _bits(rows: np.ndarray) -> list[bytes]:
    """Each field's bytes (a record's padding is not part of its value)."""
    return [np.ascontiguousarray(rows[name]).tobytes() for name in rows.dtype.names]


def one_ship(initial: dict, ship: dict | None = None, body: dict | None = None,
             sim: dict | None = None) -> World:
    return World.of(scene(initial, ship=ship, body=body, sim=sim, duration=MAX_TICKS * 0.05))


STARTS = {
    "moon 300 m, descending 20 m/s": ({"altitude": 300.0, "vertical_speed": -20.0}, None, None),
    "moon 50 m, at rest": ({"altitude": 50.0}, None, None),
    "moon 1000 m, descending 60 m/s": ({"altitude": 1000.0, "vertical_speed": -60.0}, None, None),
    "moon 100 m, climbing 15 m/s": ({"altitude": 100.0, "vertical_speed": 15.0}, None, None),
    "moon 300 m, tilted 30 deg and turning": (
        {"altitude": 300.0, "vertical_speed": -20.0, "tilt_deg": 30.0,
         "angular_velocity": [0.1, -0.05, 0.02]}, None, None),
    "moon 100 m, 6 m/s sideways": (
        {"altitude": 100.0, "vertical_speed": -5.0, "horizontal_speed": 6.0, "heading_deg": 90.0},
        None, None),
    # the built-in earth scene's lander (max_thrust 200 kN: T/W 2)
    "earth 200 m, descending 10 m/s": ({"altitude": 200.0, "vertical_speed": -10.0},
                                       {"max_thrust": 200000.0}, EARTH),
    "turning moon with a hill, 300 m, descending 20 m/s": (
        {"altitude": 300.0, "vertical_speed": -20.0}, None, TURNING_HILL),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(STARTS))
def test_lands_softly_from(name):
    initial, ship, body = STARTS[name]
    flight = autoland(one_ship(initial, ship, body), ["s"])
    assert flight.outcomes == {"s": AutolandOutcome.LANDED}, flight.states("s")
    assert SurfaceState.CRASHED not in flight.states("s")
    assert SurfaceState.TIPPED not in flight.states("s")
    touchdowns = flight.contacts("s")
    assert touchdowns, "never touched down"
    for v in touchdowns:  # v_radial at the contact transition: the impact, + up
        assert -SOFT_MPS < v < 0.0, touchdowns
    assert flight.world.state.rows["surface_state"][0] == SurfaceState.LANDED
    # reported at the first tick the state is LANDED (the landing happened in the step into it)
    landed = [e.tick for e in flight.events if e.to_state == SurfaceState.LANDED]
    assert flight.ticks["s"] == landed[-1]


def test_the_touchdown_is_at_the_aimed_speed():
    """Below the gate the ship descends at the touchdown speed: it touches at that speed."""
    flight = autoland(one_ship({"altitude": 300.0, "vertical_speed": -20.0}), ["s"])
    assert flight.contacts("s") == pytest.approx([-TOUCHDOWN_SPEED_MPS], abs=0.05)


def test_a_ship_too_weak_for_its_weight_crashes_and_is_reported_crashed():
    """Max thrust below the weight (12 kN against 16 kN on the Moon): the autopilot gives it full
    throttle all the way, and the ship crashes faster than crash_speed."""
    world = one_ship({"altitude": 1000.0, "vertical_speed": -60.0}, {"max_thrust": 12000.0})
    flight = autoland(world, ["s"])
    assert flight.outcomes == {"s": AutolandOutcome.CRASHED}
    assert flight.states("s") == [SurfaceState.CRASHED]
    assert {c.throttle for c in flight.commands} == {1.0}  # its best, every tick


def test_a_ship_without_fuel_crashes_and_is_reported_crashed():
    flight = autoland(one_ship({"altitude": 1000.0, "vertical_speed": -60.0}, {"fuel_mass": 0.0}),
                      ["s"])
    assert flight.outcomes == {"s": AutolandOutcome.CRASHED}


@pytest.mark.parametrize("state, outcome", [("landed", AutolandOutcome.LANDED),
                                            ("tipped", AutolandOutcome.TIPPED)])
def test_a_ship_already_down_ends_at_once(state, outcome):
    initial = {"state": state, **({"tilt_deg": 85.0} if state == "tipped" else {})}
    world = one_ship(initial)
    commands, ended = autoland_commands(world, ["s"])
    assert ended == {"s": outcome}
    assert commands == [AutolandCommand("s", 0.0, int(HoldMode.OFF))]
    assert ended["s"].label == state


def test_a_ship_in_contact_gets_no_thrust_and_settles():
    world = one_ship({"state": "contact", "altitude": -0.01, "vertical_speed": -2.0})
    commands, ended = autoland_commands(world, ["s"])
    assert ended == {} and commands == [AutolandCommand("s", 0.0, int(HoldMode.RADIAL))]
    assert autoland(world, ["s"]).outcomes == {"s": AutolandOutcome.LANDED}


def test_ids_not_in_the_fleet_are_skipped_and_repeats_count_once():
    world = one_ship({"altitude": 300.0})
    commands, ended = autoland_commands(world, ["gone", "s", "s"])
    assert [c.ship_id for c in commands] == ["s"] and ended == {}
    assert autoland_commands(world, []) == ([], {})


def test_its_altitude_is_the_telemetrys():
    """The law's height is the lowest foot above the terrain under it, the step's own altitude
    (bit for bit on a still body; on a turning one the body's angle comes from a series instead of
    libm), and its descent speed and tilt are the telemetry's."""
    for body, tol in (({}, 0.0), (TURNING_HILL, 1e-9)):
        ships = [{"id": f"s{i}", "initial": {"altitude": 0.5 + i, "tilt_deg": 7.0 * i,
                                             "heading_deg": 30.0 * i, "horizontal_speed": 3.0,
                                             "east": 2.0 * i}} for i in range(6)]
        world = World.of(scene(ships=ships, body=body, duration=10.0))
        for _ in world.blocks(37):
            pass
        g = guidance(world, np.arange(world.state.n))
        out = outputs_at(world.params, world.state)
        assert np.abs(g.h_m - out.altitude_m).max() <= tol
        assert np.abs(g.cos_tilt - out.cos_tilt).max() <= 1e-15
        assert np.abs(g.v_down_mps + out.v_radial_mps).max() <= 1e-12


def test_the_law_is_bounded_and_sane():
    """Throttle in 0..1 everywhere; full when falling far faster than the profile, none when
    climbing or tilted past 60 degrees, none without an engine unless thrust is wanted."""
    rng = np.random.default_rng(7)
    n = 5000
    h = rng.uniform(-1.0, 5000.0, n)
    v = rng.uniform(-100.0, 200.0, n)
    g = rng.uniform(0.1, 25.0, n)
    a = rng.choice([0.0, 0.5, 6.0, 30.0], n)
    c = rng.uniform(-1.0, 1.0, n)
    v_ref, thr = throttle_law(h, v, g, a, c)
    assert np.all((thr >= 0.0) & (thr <= 1.0)) and np.all(np.isfinite(v_ref))
    assert np.all(v_ref >= TOUCHDOWN_SPEED_MPS)
    assert np.all(thr[c < 0.5] == 0.0)
    fast = (v > v_ref + 50.0) & (c > 0.9) & (a > 0.0)
    assert fast.any() and np.all(thr[fast] == 1.0)
    climbing = (v < -20.0) & (h > 10.0)
    assert climbing.any() and np.all(thr[climbing & (g < 20.0)] == 0.0)


@pytest.mark.parametrize("body", [{}, TURNING_HILL])
def test_a_ships_commands_are_its_own_bits_among_others(body):
    """One ship autolanded alone, and among a varied fleet that the autopilot also flies: the same
    throttle and hold bits at every tick, and the same state."""
    target = {"id": "target", "initial": {"altitude": 120.0, "vertical_speed": -12.0,
                                          "horizontal_speed": 1.0, "tilt_deg": 4.0}}
    others = [dict(s, inputs=[]) for s in varied_fleet(40)]
    alone = World.of(scene(ships=[target], body=body, duration=100.0))
    among = World.of(scene(ships=[*others[:17], target, *others[17:]], body=body, duration=100.0))
    ids_among = [s["id"] for s in others[::-1]] + ["target"]  # another order, too
    engaged = list(ids_among)
    for _ in range(MAX_TICKS):
        a_cmds, a_end = autoland_commands(alone, ["target"])
        b_cmds, b_end = autoland_commands(among, engaged)
        mine = [c for c in b_cmds if c.ship_id == "target"]
        assert len(mine) == 1 and a_cmds == mine
        assert np.float64(a_cmds[0].throttle).tobytes() == np.float64(mine[0].throttle).tobytes()
        assert a_end.get("target") == b_end.get("target")
        for w, cmds in ((alone, a_cmds), (among, b_cmds)):
            for c in cmds:
                w.command(c.ship_id, throttle=c.throttle, hold=c.hold)
        engaged = [s for s in engaged if s not in b_end]
        if "target" in a_end:
            break
        for w in (alone, among):
            for _ in w.blocks(w.tick + 1):
                pass
        i = among.ship_ids.index("target")
        assert _bits(alone.state.rows[0:1]) == _bits(among.state.rows[i:i + 1])
    assert a_end == {"target": AutolandOutcome.LANDED}


def test_the_recorded_commands_alone_replay_the_flight():
    """Every autopilot action is an ordinary command: the commands the world applied, given to a
    fresh world of the same scenario without the autopilot, give the same flight bit for bit."""
    scn = scene(ships=[{"id": "a", "initial": {"altitude": 80.0, "vertical_speed": -8.0}},
                       {"id": "b", "initial": {"altitude": 200.0, "horizontal_speed": 2.0}}],
                duration=200.0)
    flight = autoland(World.of(scn), ["a", "b"])
    assert flight.outcomes == {"a": AutolandOutcome.LANDED, "b": AutolandOutcome.LANDED}
    replay = dataclasses.replace(World.of(scn), timeline=Timeline.of(commands=flight.commands))
    events = [e for b in replay.blocks(flight.world.tick) for e in b.events]
    assert events == flight.events
    assert _bits(replay.state.rows) == _bits(flight.world.state.rows)
    assert State(rows=replay.state.rows).surface_state.tolist() == [SurfaceState.LANDED] * 2
