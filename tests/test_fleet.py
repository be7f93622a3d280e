"""A fleet with identity (issue 10): ships join and leave between ticks without changing any other
ship's bits; commands from anywhere are the recorded input, and a log of them verifies bit for
bit, whole, for one ship and from a keyframe."""
from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from touchdown.cli import main
from touchdown.logs.header import scenario_message
from touchdown.logs.reader import LogReader
from touchdown.logs.writer import LogWriter
from touchdown.replay.verify import verify
from touchdown.sim.scenario import ScenarioError, parse
from touchdown.sim.timeline import CommandError
from touchdown.sim.world import World

from test_determinism import varied_fleet

TURNING = {"rotation_period": 20000.0}


def _bits(a: np.ndarray) -> list[bytes]:
    """Each field's bytes (a record's padding is not part of its value)."""
    return [np.ascontiguousarray(a[name]).tobytes() for name in a.dtype.names]


def _by_ship(blocks) -> dict[str, dict[int, tuple]]:
    """ship id -> tick -> (state bits, outputs bits, inputs bits)."""
    out: dict[str, dict[int, tuple]] = {}
    for b in blocks:
        for k in range(len(b)):
            for i, sid in enumerate(b.ship_ids):
                out.setdefault(sid, {})[b.first_tick + k] = (
                    _bits(b.states[k, i:i + 1]), _bits(b.outputs[k, i:i + 1]),
                    _bits(b.inputs[k, i:i + 1]))
    return out


def _run(doc: dict) -> dict[str, dict[int, tuple]]:
    scn = parse(doc, "test")
    world = World.of(scn)
    return _by_ship([world.first_block(), *world.blocks(scn.params.sim.n_ticks, max_ticks=7)])


@pytest.mark.parametrize("body", [{}, TURNING])
def test_a_ship_joining_or_leaving_changes_no_other_ships_bits(body):
    """Varied classes, every state, a turning body: the fleet run with a ship joining at tick 13
    and another leaving at tick 21 gives every other ship the bits it gets without them."""
    ships = varied_fleet(24)
    base = {"name": "f", "duration": 1.5, "body": body, "ships": ships}
    joiner = {**ships[5], "id": "joiner", "spawn_t": 13 * 0.05, "inputs": [
        {"t": 0.9, "throttle": 0.4}]}
    changed = {**base, "ships": [*ships[:9], {**ships[9], "retire_t": 21 * 0.05}, *ships[10:],
                                 joiner]}
    a, b = _run(base), _run(changed)
    leaver = ships[9]["id"]
    assert sorted(b["joiner"]) == list(range(13, 31))  # present from its tick to the end
    assert sorted(b[leaver]) == list(range(0, 21))  # last in the record of tick 20
    for sid, ticks in a.items():
        for tick, bits in ticks.items():
            if sid == leaver and tick >= 21:
                continue
            assert b[sid][tick] == bits, (sid, tick)
    # the joiner itself: as it would be in a fleet of its own, joining at the same tick
    alone = _run({**base, "ships": [joiner]})
    assert alone["joiner"] == b["joiner"]


def test_a_joining_ship_starts_where_its_table_places_it_on_a_turning_body():
    """A ship that joins at tick T on a turning body sits at its landing site as the body has
    carried it by then: the same site-frame position as a ship placed there at tick 0."""
    from touchdown.sim import measure
    doc = {"name": "f", "duration": 2.0, "body": TURNING, "ships": [
        {"id": "early", "initial": {"state": "landed", "east": 40.0}},
        {"id": "late", "spawn_t": 1.0, "initial": {"state": "landed", "east": 40.0}}]}
    scn = parse(doc, "t")
    world = World.of(scn)
    blocks = [world.first_block(), *world.blocks(40)]
    rec = next(r for b in blocks for r in b.records() if r.tick == 20)
    assert rec.ship_ids == ("early", "late")
    pos, _ = measure.site_frame(world.params, rec.state.pos_m, rec.state.vel_mps, 20 * 0.05)
    # the landed ship has not moved relative to the ground; the new one is where it stands
    assert np.allclose(pos[0], pos[1], atol=1e-6), pos
    assert abs(pos[0, 0] - 40.0) < 1e-3


def test_a_scenario_with_ships_joining_and_leaving_records_exports_and_verifies(tmp_path):
    """ships.spawn_t / retire_t: a ship joins at 3 s and leaves at 6 s; the log names each tick's
    ships, export follows them by id, and replay --verify passes whole, for one ship (each of
    them) and from a keyframe."""
    toml = tmp_path / "joins.toml"
    toml.write_text('''
name = "joins"
duration = 8.0
[[ships]]
id = "stays"
[ships.initial]
altitude = 5.0
vertical_speed = -3.0
[[ships]]
id = "visitor"
spawn_t = 3.0
retire_t = 6.0
[ships.initial]
altitude = 2.0
vertical_speed = -12.0
east = 10.0
[[ships.inputs]]
t = 4.0
throttle = 0.5
''')
    log = tmp_path / "joins.mcap"
    runner = CliRunner()
    r = runner.invoke(main, ["record", str(toml), "-o", str(log), "--keyframe-every", "40"])
    assert r.exit_code == 0, r.output
    with LogReader(log) as reader:
        assert list(reader.scenario.ship_ids) == ["stays"]  # present at tick 0
        table = reader.ship_table()
        assert table.ids == ["stays", "visitor"] and table.joined == [0, 0 + 60]
        counts = {td.tick: [table.ids[k] for k in td.keys] for td in reader.ticks()}
        timeline = reader.timeline()
    assert counts[59] == ["stays"] and counts[60] == ["stays", "visitor"]
    assert counts[119] == ["stays", "visitor"] and counts[120] == ["stays"]
    assert [(c.tick, c.ship_id, c.throttle) for c in timeline.commands] == [(80, "visitor", 0.5)]
    assert [(r_.tick, r_.ship_id) for r_ in timeline.retires] == [(120, "visitor")]

    rows = [json.loads(line) for line in
            runner.invoke(main, ["export", str(log)]).output.splitlines()]
    visitor = [row["tick"] for row in rows if row["ship_id"] == "visitor"]
    assert visitor == list(range(60, 120))
    assert sum(row["ship_id"] == "stays" for row in rows) == 161
    events = [json.loads(line) for line in
              runner.invoke(main, ["export", "--events", str(log)]).output.splitlines()]
    assert any(e["ship_id"] == "visitor" and e["event"] == "ship.contact" for e in events)

    for args in ([], ["--ship", "visitor"], ["--ship", "stays"], ["--from-tick", "100"],
                 ["--from-tick", "90", "--ship", "visitor"], ["--from-tick", "40"]):
        r = runner.invoke(main, ["replay", str(log), "--verify", *args])
        assert r.exit_code == 0 and "identical" in r.output, (args, r.output)
    whole = verify(str(log))
    assert whole.events_compared == len(events) and whole.summary_compared


def test_a_log_of_commands_from_the_python_api_verifies_bit_for_bit(tmp_path):
    """Commands, a spawn and a retire given through the API between blocks, none of them in any
    scenario: the log records them and replay folds over them, whole, for one ship and from a
    keyframe."""
    scn = parse({"name": "api", "duration": 6.0, "ships": [
        {"id": "a", "initial": {"altitude": 40.0, "vertical_speed": -2.0}},
        {"id": "b", "initial": {"state": "landed", "east": 20.0}}]}, "api")
    world = World.of(scn)
    path = tmp_path / "api.mcap"
    header = scenario_message(scn, "api", keyframe_interval=25)
    with LogWriter(path, header) as writer:
        writer.write_block(world.first_block())
        for t in range(0, 120, 10):
            if t == 10:
                world.command("a", throttle=0.9, hold=2)
            if t == 30:
                world.spawn({"id": "c", "initial": {"altitude": 3.0, "vertical_speed": -15.0,
                                                     "north": 30.0}})
            if t == 50:
                world.command("b", throttle=1.0)
                world.command("c", rcs=(0.0, 0.5, 0.0))
            if t == 70:
                world.retire("b")
            if t == 80:
                world.command("a", throttle=0.0)
            for block in world.blocks(t + 10):
                writer.write_block(block)
    assert "inputs" not in json.dumps(scn.resolved["ships"][0]["inputs"])  # none in the scenario
    with LogReader(path) as reader:
        timeline = reader.timeline()
    assert [(c.tick, c.ship_id) for c in timeline.commands] == [
        (10, "a"), (50, "b"), (50, "c"), (80, "a")]
    assert [s.ship_id for s in timeline.spawns] == ["c"] and timeline.spawns[0].tick == 31
    assert [(r.tick, r.ship_id) for r in timeline.retires] == [(71, "b")]
    for kwargs in ({}, {"ship_id": "a"}, {"ship_id": "c"}, {"ship_id": "b"}, {"first": 60},
                   {"first": 90, "ship_id": "c"}):
        res = verify(str(path), **kwargs)
        assert res.identical, (kwargs, res.report())
    assert verify(str(path)).events_compared > 0


def test_a_log_whose_recorded_command_was_changed_diverges(tmp_path):
    """The check above can fail: a log whose command record says another throttle than the one
    the recorded ticks show diverges at the first tick it changes."""
    from touchdown.proto import touchdown_pb2 as pb
    from test_replay import rewrite_topic

    scn = parse({"name": "api", "duration": 2.0, "ships": [
        {"id": "a", "initial": {"altitude": 40.0}}]}, "api")
    world = World.of(scn)
    path = tmp_path / "api.mcap"
    with LogWriter(path, scenario_message(scn, "api")) as writer:
        writer.write_block(world.first_block())
        for block in world.blocks(10):
            writer.write_block(block)
        world.command("a", throttle=0.9)
        for block in world.blocks(40):
            writer.write_block(block)
    assert verify(str(path)).identical

    def edit(data: bytes) -> bytes:
        batch = pb.CommandBatch.FromString(data)
        batch.commands[0].throttle = 0.8
        return batch.SerializeToString()
    bad = tmp_path / "edited.mcap"
    rewrite_topic(path, bad, "/touchdown/commands", edit)
    res = verify(str(bad))
    assert not res.identical and res.divergence.tick == 11, res.report()


def test_bad_commands_spawns_and_retires_are_refused_with_one_line():
    scn = parse({"name": "x", "duration": 1.0, "ships": [{"id": "a"}]}, "x")
    world = World.of(scn)
    for call, words in [
        (lambda: world.command("nobody", throttle=0.5), "no ship 'nobody'"),
        (lambda: world.command("a", throttle=float("nan")), "throttle must be 0..1"),
        (lambda: world.command("a", throttle=2.0), "throttle must be 0..1"),
        (lambda: world.command("a", rcs=(0.0, 3.0, 0.0)), "rcs must be three numbers"),
        (lambda: world.command("a", hold=7), "hold must be one of"),
        (lambda: world.spawn({"id": "a"}), "ship id 'a' is taken"),
        (lambda: world.retire("nobody"), "no ship 'nobody'"),
    ]:
        with pytest.raises(CommandError) as exc:
            call()
        assert words in str(exc.value) and "\n" not in str(exc.value)
    with pytest.raises(ScenarioError, match=r"ships\[0\]\.mass"):
        world.spawn({"id": "z", "mass": -1.0})
    assert world.timeline.commands == () and world.timeline.spawns == ()


@pytest.mark.parametrize("ship, key, words", [
    ({"spawn_t": 3.0, "retire_t": 3.0}, "retire_t", "at least a tick after spawn_t"),
    ({"spawn_t": 3.0, "inputs": [{"t": 1.0, "throttle": 1.0}]}, "inputs[0].t", "before the ship joins"),
    ({"retire_t": 2.0, "inputs": [{"t": 2.0, "throttle": 1.0}]}, "inputs[0].t", "after the ship leaves"),
    ({"spawn_t": -1.0}, "spawn_t", "must be >= 0"),
])
def test_scenario_spawn_and_retire_keys_are_checked(ship, key, words):
    with pytest.raises(ScenarioError) as exc:
        parse({"name": "x", "duration": 5.0, "ships": [{"id": "a", **ship}]}, "x.toml")
    assert f"ships[0].{key}" in str(exc.value) and words in str(exc.value)
