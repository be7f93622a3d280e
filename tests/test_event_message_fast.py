"""A transition's message (logs.header.event_message, ship_state_message) made from the ship's
record row with Python floats gives the bytes of the field-by-field way on numpy's scalars, and
the event stream's fields (logs.redis_stream.entry_fields) name the states as the enum does."""
from __future__ import annotations

import numpy as np
import pytest

from touchdown.bench.speed import fleet_doc
from touchdown.logs import header as H
from touchdown.logs.redis_stream import entry_fields, event_entry
from touchdown.sim.enums import EventKind, SurfaceState
from touchdown.sim.scenario import parse
from touchdown.sim.state import State
from touchdown.sim.world import World


def _world(n: int = 400) -> World:
    doc = fleet_doc(n, 60.0)
    doc["sim"] = {"dt": 0.1}
    return World.of(parse(doc, "events"))


@pytest.mark.parametrize("log_format", [5, 6])  # 6: the tilt without the host's BLAS and libm
def test_ship_state_message_is_the_field_by_field_message(log_format):
    w = _world()
    seen_states = set()
    for block in w.blocks(30, max_ticks=1):
        st = State(rows=block.states[0], tick=block.first_tick)
        for i in range(st.n):
            fast = H.ship_state_message("s", "p", "Luna", st, i, log_format=log_format)
            slow = H._ship_state_message_fields("s", "p", "Luna", st, i, log_format)
            assert fast.SerializeToString() == slow.SerializeToString(), (block.first_tick, i)
            seen_states.add(int(st.surface_state[i]))
    assert {int(SurfaceState.FLYING), int(SurfaceState.LANDED), int(SurfaceState.TIPPED)} <= \
        seen_states


def test_event_messages_and_entries_as_before():
    w = _world()
    ships = H.ShipTable(w.ship_ids, list(w.params.ships.player_id))
    count = 0
    for block in w.blocks(30, max_ticks=1):
        for ev in block.events:
            st = State(rows=block.states[ev.tick - block.first_tick], tick=ev.tick)
            m = H.event_message(ships, "Luna", 0.1, st, ev)
            assert m.event == EventKind(ev.kind).topic
            assert m.ship.SerializeToString() == H._ship_state_message_fields(
                m.ship_id, m.player_id, "Luna", st, ev.ship).SerializeToString()
            fields = entry_fields(m)
            assert fields["from_state"] == SurfaceState(m.from_state).label
            assert fields["to_state"] == SurfaceState(m.to_state).label
            assert fields["proto"] == m.SerializeToString()
            # the service's entry, made from the event's own numbers: the same fields
            data = m.SerializeToString()
            assert event_entry(ev, m.player_id, m.body, data) == entry_fields(m, data)
            count += 1
    assert count > 20  # the fleet's arriving ships touch down


def test_surface_state_look_up_is_the_enum():
    for x in SurfaceState:
        assert H.surface_state(int(x)) is x
        assert H.surface_state(np.int8(int(x))) is x
    try:
        H.surface_state(99)
    except ValueError:
        pass
    else:  # pragma: no cover
        raise AssertionError("a state outside the enum must raise ValueError, as SurfaceState()")


def test_ship_hash_names_the_state_as_the_enum_does():
    from touchdown.service.shard import ship_hash
    for x in SurfaceState:
        h = ship_hash(x, "Luna", 7, "player-1", 2)
        assert h == {"state": x.label, "surface_contact_state": x.seed_string,
                     "landed_body_name": "" if x is SurfaceState.FLYING else "Luna",
                     "tick": "7", "player_id": "player-1", "shard": "2"}
