"""A flight log's header tables made from a scenario's resolved tables (logs.header.header_table,
as the live service seeds its logs' caches) are the tables the header resolves itself, byte for
byte; and sim.scenario.resolve is parse's resolved document."""
from __future__ import annotations

import glob
import json
import tomllib
from pathlib import Path

import pytest

from touchdown.bench.speed import fleet_doc
from touchdown.logs.encode import ShipTables, canonical_json, resolved_json_bytes
from touchdown.logs.header import (header_table, record_bytes, world_header, world_header_later,
                                   world_record_later)
from touchdown.sim.scenario import parse, resolve
from touchdown.sim.world import World

ROOT = Path(__file__).resolve().parents[1]
TIMED = {"name": "timed", "duration": 2.0, "ships": [
    {"id": "a", "spawn_t": 0.5, "retire_t": 1.5, "initial": {"altitude": 3.0},
     "inputs": [{"t": 0.6, "throttle": 0.5}]},
    {"id": "b", "player_id": "p", "mass": 9000.0, "fuel_mass": 1000.0,
     "initial": {"state": "landed", "north": 4.0}},
    {"id": "c", "inertia": [3.0e4, 3.0e4, 2.0e4], "retire_t": 1.0,
     "initial": {"altitude": 5.0, "vertical_speed": -2.0, "tilt_deg": 4.0}}]}


def _docs() -> list[dict]:
    docs = [fleet_doc(120, 60.0), TIMED]
    for f in sorted(glob.glob(str(ROOT / "scenarios" / "*.toml"))):
        docs.append(tomllib.loads(Path(f).read_text()))
    return docs


@pytest.mark.parametrize("doc", _docs(), ids=lambda d: str(d.get("name", "?")))
def test_header_tables_from_resolved_tables_are_the_headers_own(doc):
    scn = parse(doc, "x")
    assert json.dumps(resolve(doc, "x"), sort_keys=True) == json.dumps(scn.resolved,
                                                                       sort_keys=True)
    world = World.of(scn)
    for _ in world.blocks(world.tick + 12):  # (ships joined and left: the fleet of tick 12)
        pass
    seeded = ShipTables({sid: header_table(world.known[sid]) for sid in world.ship_ids})
    a = world_header(world, "n", "s", 10, True, tables=seeded)
    b = world_header(world, "n", "s", 10, True, tables={})
    assert a.SerializeToString() == b.SerializeToString()
    later, json_of = world_header_later(world, "n", "s", 10, True, tables=ShipTables(
        {sid: header_table(world.known[sid]) for sid in world.ship_ids}))
    assert record_bytes(later, json_of()) == b.SerializeToString()


@pytest.mark.parametrize("known", ["all", "some", "none"])
def test_a_header_made_on_the_writers_thread_is_world_headers_own(known, monkeypatch):
    """world_record_later's bytes (a rotating log's header: its ships' ids and tables made on
    the writer's thread, a piece of the ships at a time) are world_header's, with every ship's
    table cached, some (ships joined since) or none; a shard's take stamped on the header
    after the call is in them."""
    import touchdown.logs.header as header_mod
    monkeypatch.setattr(header_mod, "_PIECE", 7)  # (pieces of 7: the last one short)
    world = World.of(parse(fleet_doc(60, 60.0), "x"))
    for sid in ("n1", "n2", "n3"):
        world.spawn({"id": sid, "player_id": "q-" + sid, "initial": {"altitude": 4.0}})
    for _ in world.blocks(world.tick + 3):
        pass
    ids = world.ship_ids[:{"all": None, "some": 40, "none": 0}[known]]
    tables = ShipTables({sid: header_table(world.known[sid]) for sid in ids
                         if sid in world.known and not sid.startswith("n")})
    if known == "all":
        world_header(world, "n", "s", 10, True, tables=tables)  # (the joined ones resolved)
    assert len(world.ship_ids) == 63
    later, record = world_record_later(world, "n", "s", 10, True, description="d",
                                       tables=tables, keyframe_phase=3)
    assert list(later.ship_ids) == [] and not later.resolved_json
    later.shard = 2
    whole = world_header(world, "n", "s", 10, True, description="d", tables={},
                         keyframe_phase=3)
    whole.shard = 2
    assert record() == whole.SerializeToString()
    assert list(world.ship_ids) == [sid for sid in world.ship_ids if sid in tables]


def test_a_header_s_json_is_sorted_compact_and_one_writer_s_whole():
    """A header's scenario is canonical_json's: keys sorted, no spaces, orjson's spelling
    (0.00001), the same bytes whether joined from cached ship tables or written whole; a document
    orjson cannot write (an integer past 64 bits) is the standard library's, whole, on both paths
    (never a mix of the two spellings in one header)."""
    resolved = {"z": 1e-05, "a": {"y": 1, "b": [0.5]},
                "ships": [{"id": "s1", "v": 1e-05}, {"id": "s2", "v": 2.0}]}
    assert canonical_json(resolved) == (b'{"a":{"b":[0.5],"y":1},"ships":[{"id":"s1","v":0.00001},'
                                        b'{"id":"s2","v":2.0}],"z":0.00001}')
    assert resolved_json_bytes(resolved, ["s1", "s2"], ShipTables()) == canonical_json(resolved)
    big = {**resolved, "ships": [{"id": "s1", "v": 1e-05}, {"id": "s2", "seed": 2**70}]}
    spelled = canonical_json(big)
    assert spelled.startswith(b'{"a":{"b":[0.5],"y":1},"ships":[{"id":"s1","v":1e-05}')
    assert json.loads(spelled) == big
    assert resolved_json_bytes(big, ["s1", "s2"], ShipTables()) == spelled
