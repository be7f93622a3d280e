"""A block's transition events written by logs.encode_events are, byte for byte, what
logs.header.event_message(...).SerializeToString() gives: for the events of real fleets (the
bench's fleet, arrivals at 2-49 m/s, unicode and long ids) and for made-up records that reach
every corner of the wire (negative zeros, zeros left out, NaNs, infinities, every state, every
kind, large ticks); an older format's events and anything the module does not write go through
event_message; the messages, players and Redis entries are event_message's."""
from __future__ import annotations

import math
import struct
from unittest import mock

import numpy as np
import pytest

from touchdown.bench.speed import fleet_doc
from touchdown.logs import encode_events as EE
from touchdown.logs import header as H
from touchdown.logs.encode_events import (ENCODED_FORMAT, RAD_TO_DEG, EventMessages,
                                          event_messages)
from touchdown.logs.redis_stream import entry_fields, event_entry
from touchdown.sim.enums import EventKind, SurfaceState
from touchdown.sim.scenario import parse
from touchdown.sim.state import STATE_DTYPE, State, event_of
from touchdown.sim.world import World

BODIES = ("Luna", "", "Mōnд-β " + "x" * 300)


def _reference(ships, body, dt_s, states, first_tick, events, log_format=H.LOG_FORMAT_VERSION):
    states = states.reshape(1, -1) if states.ndim == 1 else states
    return [H.event_message(ships, body, dt_s, State(rows=states[ev.tick - first_tick],
                                                     tick=ev.tick), ev,
                            log_format=log_format) for ev in events]


def _check(ships, body, dt_s, states, first_tick, events, log_format=H.LOG_FORMAT_VERSION,
           written=True, keys=None):
    """event_messages's against event_message's; ``written``: by logs.encode_events itself
    (event_message not called); ``keys``: each column's ship's key (as the writer gives)."""
    if written and log_format == ENCODED_FORMAT:
        with mock.patch.object(EE, "event_message", side_effect=AssertionError("not written")):
            got = event_messages(ships, body, dt_s, states, first_tick, events,
                                 log_format=log_format, keys=keys)
    else:
        got = event_messages(ships, body, dt_s, states, first_tick, events,
                             log_format=log_format, keys=keys)
    ref = _reference(ships, body, dt_s, states, first_tick, events, log_format)
    assert got.datas == [m.SerializeToString() for m in ref]
    assert got.player_ids == [m.player_id for m in ref]
    assert got.body == body
    return got, ref


def _arrivals(n: int) -> dict:
    """The bench's fleet of landers arriving at 2-49 m/s from 0.5-30 m (bench.mujoco_side),
    with long and unicode ship and player ids."""
    rng = np.random.default_rng(11)
    ships = []
    for i, (h, v) in enumerate(zip(rng.uniform(0.5, 30.0, n), rng.uniform(2.0, 49.0, n))):
        sid = f"s{i}" if i % 3 else f"лэндер-{i}-{'ü' * (i % 200)}"
        ship = {"id": sid, "initial": {"altitude": float(h), "vertical_speed": -float(v),
                                       "east": float(10.0 * i), "tilt_deg": float(i % 7),
                                       "horizontal_speed": float(i % 5)}}
        if i % 4 == 1:
            ship["player_id"] = f"игрок-{i % 13}-🚀" + "p" * (i % 150)
        ships.append(ship)
    return {"name": "arrivals", "duration": 3.0, "ships": ships}


@pytest.mark.parametrize("doc", ["fleet", "arrivals"])
def test_the_events_of_real_fleets_are_event_message_bytes(doc):
    if doc == "fleet":
        d = fleet_doc(2000, 60.0)
        d["sim"] = {"dt": 0.1}
    else:
        d = _arrivals(1500)
    w = World.of(parse(d, "events"))
    ships = H.ShipTable(w.ship_ids, list(w.params.ships.player_id))
    n, kinds, states = 0, set(), set()
    for b, block in enumerate(w.blocks(60)):
        body = BODIES[b % len(BODIES)]
        keys = ships.keys(block.ship_ids) if b % 2 else None  # (the writer's way, and not)
        got, ref = _check(ships, body, w.params.sim.dt_s, block.states, block.first_tick,
                          block.events, keys=keys)
        for k, (ev, m) in enumerate(zip(block.events, ref)):
            kinds.add(int(ev.kind))
            states.add(m.ship.state)
            if k < 3:  # the messages read back are event_message's, and so the entries
                assert got[k] == m
                data = got.datas[k]
                assert event_entry(ev, got.player_ids[k], got.body, data) == \
                    entry_fields(m, data) == entry_fields(got[k])
        n += len(block.events)
    assert n > 300
    assert len(kinds) >= 3 and len(states) >= 3


def _made_up(rng, n_ticks: int, n_ships: int) -> np.ndarray:
    """State records whose numbers reach every case of the wire: 0.0 (left out), -0.0 (kept),
    NaN, infinities, subnormals, large and ordinary numbers, every surface state."""
    specials = np.array([0.0, -0.0, np.nan, np.inf, -np.inf, 5e-324, -1e300, 1.0, 1e-7])
    states = np.zeros((n_ticks, n_ships), STATE_DTYPE)
    for name in ("pos_m", "vel_mps", "quat", "omega_body_radps", "mass_kg", "fuel_kg"):
        a = states[name]
        normal = rng.normal(0.0, 1e3, a.shape)
        pick = rng.random(a.shape)
        a[...] = np.where(pick < 0.25, rng.choice(specials, a.shape),
                          np.where(pick < 0.45, 0.0, normal))
    # some ships upright and at rest: whole vectors of zeros (empty sub-messages)
    states["quat"][:, ::5] = (1.0, 0.0, 0.0, 0.0)
    states["vel_mps"][:, ::4] = 0.0
    states["omega_body_radps"][:, 1::4] = -0.0
    states["pos_m"][:, ::7] = (0.0, 0.0, 1737.4e3)
    states["surface_state"] = rng.integers(0, len(SurfaceState), states.shape)
    return states


def test_made_up_records_and_events_are_event_message_bytes():
    rng = np.random.default_rng(36)
    n_ticks, n_ships = 6, 300
    states = _made_up(rng, n_ticks, n_ships)
    ids = [f"ship-{i}" if i % 2 else f"корабль-{i}-" + "ß" * (i % 97) + "🛰" * (i % 5)
           for i in range(n_ships)]
    players = ["" if i % 11 == 0 else f"p{i % 17}" + "é" * (i % 140) for i in range(n_ships)]
    order = rng.permutation(n_ships)  # the table's keys not the columns (ships that joined)
    ships = H.ShipTable([ids[i] for i in order], [players[i] for i in order])
    keys = ships.keys(ids)
    specials = [0.0, -0.0, 1.5, -3.25, math.nan, math.inf, 5e-324]
    for first_tick in (0, 1, 200, 2**40):
        events = []
        for k in range(n_ticks):
            for i in rng.choice(n_ships, 60, replace=False):
                events.append(event_of(
                    first_tick + k, int(i), int(rng.integers(1, 7)),
                    int(rng.integers(0, 5)), int(rng.integers(0, 5)),
                    float(rng.choice(specials)) if rng.random() < 0.5 else float(rng.normal()),
                    ship_id=ids[i],
                    t_event_s=float(rng.choice(specials)) if rng.random() < 0.3 else
                    float(rng.uniform(0, 10))))
        for body in BODIES:
            for dt_s in (0.05, 0.1, 1.0 / 3.0):
                _check(ships, body, dt_s, states, first_tick, events)
                _check(ships, body, dt_s, states, first_tick, events, keys=keys)
    # the kind of every event and every state were there
    assert set(np.unique(states["surface_state"])) == set(range(len(SurfaceState)))


def test_one_tick_of_records_and_an_older_format():
    w = World.of(parse(_arrivals(300), "events"))
    ships = H.ShipTable(w.ship_ids, list(w.params.ships.player_id))
    seen = 0
    for block in w.blocks(60, max_ticks=1):
        for log_format in (ENCODED_FORMAT, 5, 4):  # 5 and 4: event_message's own
            _check(ships, "Luna", 0.05, block.states[0], block.first_tick, block.events,
                   log_format)
        seen += len(block.events)
    assert seen > 100


def test_what_the_module_does_not_write_is_event_message_s():
    states = _made_up(np.random.default_rng(3), 1, 4)
    states["surface_state"] = (0, 1, 2, 3)
    ships = H.ShipTable(["a", "b", "c", "d"], ["pa", "pb", "pc", "pd"])
    ev = event_of(5, 1, 1, 0, 1, -1.5, ship_id="b", t_event_s=0.25)
    # a field given None is left out (protobuf's), a NaN is kept
    for changed in ({"t_event_s": None}, {"v_radial_mps": None}, {"t_event_s": math.nan}):
        other = event_of(**{**dict(tick=5, ship=2, kind=2, from_state=1, to_state=2,
                                   v_radial_mps=0.5, ship_id="c", t_event_s=0.5), **changed})
        got, ref = _check(ships, "Luna", 0.1, states, 5, [ev, other],
                          written=changed.get("t_event_s", 0) is not None
                          and changed.get("v_radial_mps", 0) is not None)
    # a state past the enum, and a ship the log does not know: event_message's errors
    bad = states.copy()
    bad["surface_state"][0, 1] = 9
    with pytest.raises(ValueError):
        event_messages(ships, "Luna", 0.1, bad, 5, [ev])
    with pytest.raises(KeyError):
        event_messages(ships, "Luna", 0.1, states, 5,
                       [event_of(5, 0, 1, 0, 1, 0.0, ship_id="zz", t_event_s=0.0)])
    assert event_messages(ships, "Luna", 0.1, states, 5, []).datas == []


def test_the_tilt_is_math_degrees_of_the_format_s_kernel():
    rng = np.random.default_rng(5)
    x = np.concatenate([rng.uniform(0.0, math.pi, 100_000), rng.uniform(0.0, 1e-6, 10_000),
                        [0.0, -0.0, math.pi, 1e-300, 5e-324]])
    assert all(struct.pack("<d", math.degrees(v)) == struct.pack("<d", v * RAD_TO_DEG)
               for v in x.tolist())
    assert np.array_equal((x * RAD_TO_DEG).view(np.int64),
                          np.array([math.degrees(v) for v in x.tolist()]).view(np.int64))


def test_the_format_written_is_today_s():
    """A new log format's events go through event_message until this module writes them."""
    assert ENCODED_FORMAT == H.LOG_FORMAT_VERSION


def test_event_messages_read_back_as_a_sequence():
    w = World.of(parse(_arrivals(200), "events"))
    ships = H.ShipTable(w.ship_ids, list(w.params.ships.player_id))
    block = next(b for b in w.blocks(60) if len(b.events) >= 3)
    got, ref = _check(ships, "Luna", 0.05, block.states, block.first_tick, block.events)
    assert isinstance(got, EventMessages) and len(got) == len(ref)
    assert got == ref and list(got) == ref and got[1:3] == ref[1:3] and got[-1] == ref[-1]
    assert got[0] is got[0]  # parsed once
    assert [m.event for m in got] == [EventKind(ev.kind).topic for ev in block.events]
    assert all(m.HasField("t_event_s") for m in got)


def test_the_table_s_names_follow_ships_that_join():
    """The writer's table grows as ships join: their ids are written as event_message's."""
    states = _made_up(np.random.default_rng(8), 1, 3)
    states["surface_state"] = 1
    ships = H.ShipTable(["a", "b", "c"], ["pa", "pb", "pc"])
    evs = [event_of(1, i, 1, 0, 1, -2.0, ship_id=sid, t_event_s=0.5)
           for i, sid in enumerate(["a", "b", "c"])]
    _check(ships, "Luna", 0.1, states, 1, evs, keys=ships.keys(["a", "b", "c"]))
    for j in range(3000):  # past the names' first room
        ships.add(2, {"id": f"joined-{j}-" + "ω" * (j % 50), "player_id": "q" * (j % 70)})
    ids = ["c", "joined-2999-" + "ω" * (2999 % 50), "joined-7-" + "ω" * 7]
    evs = [event_of(1, i, 5, 1, 4, -9.0, ship_id=sid, t_event_s=0.75)
           for i, sid in enumerate(ids)]
    _check(ships, "Luna", 0.1, states, 1, evs, keys=ships.keys(ids))
