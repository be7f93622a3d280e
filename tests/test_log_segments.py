"""Logs that start at any tick with any fleet: rotating files (logs.rotating), each of which
verifies alone and which together hold exactly the run's numbers; a log starting with no ships;
and `touchdown incident`, a checked cut of one ship around an incident."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from touchdown.cli import main
from touchdown.logs.codec import encode_tick
from touchdown.logs.decode import decode_tick
from touchdown.logs.header import (LOG_FORMAT_VERSION, TOPIC_SUMMARY, TOPIC_TICKS, ShipTable,
                                   world_header)
from touchdown.logs.reader import LogReader
from touchdown.logs.writer import LogWriter
from touchdown.logs.rotating import RotatingLog
from touchdown.proto import touchdown_pb2 as pb
from touchdown.replay.verify import verify
from touchdown.sim.scenario import parse_text
from touchdown.sim.world import World

from test_replay import rewrite_topic

ROOT = Path(__file__).resolve().parents[1]

SCENE = """
name = "segments"
duration = 20.0
[[ships]]
id = "a"
[ships.initial]
altitude = 30.0
vertical_speed = -4.0
[[ships]]
id = "b"
[ships.initial]
state = "landed"
east = 25.0
[[ships]]
id = "c"
spawn_t = 2.0
[ships.initial]
altitude = 3.0
vertical_speed = -12.0
north = 20.0
"""
N_TICKS = 400
KEYFRAMES = 25
#: the keyframes' phase (log format 5): keyframes at ticks 7, 32, 57, ... and each file's first
PHASE = 7


def _fly(make_log) -> None:
    """The run: 3 ships of a scenario (one joining at tick 40 by its spawn_t), a ship spawned and
    one retired through the API, and commands, stepped in blocks of at most 10 ticks into the
    log ``make_log(world)`` (a LogWriter or a RotatingLog), which is closed at the end."""
    world = World.of(parse_text(SCENE, "segments.toml"))
    log = make_log(world)
    log.write_block(world.first_block())
    for t in range(0, N_TICKS, 10):
        if t == 30:
            world.command("a", throttle=0.25, hold=2)
        if t == 100:
            world.spawn({"id": "d", "initial": {"altitude": 3.0, "vertical_speed": -15.0,
                                                 "east": -30.0}})
        if t == 120:
            world.command("d", rcs=(0.0, 0.4, 0.0))
        if t == 150:
            world.retire("b")
        if t == 200:
            world.command("a", throttle=0.0)
        for block in world.blocks(t + 10, max_ticks=10):
            log.write_block(block)
    log.close()


def _rotated(directory: Path, max_bytes: int) -> list[Path]:
    logs = []
    _fly(lambda world: logs.append(RotatingLog(directory, world, keyframe_interval=KEYFRAMES,
                                               keyframe_phase=PHASE, max_bytes=max_bytes))
         or logs[0])
    return logs[0].files


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    d = tmp_path_factory.mktemp("segments")
    single = d / "single.mcap"
    _fly(lambda world: LogWriter(single, world_header(world, "segments", "segments.toml",
                                                      KEYFRAMES, keyframe_phase=PHASE)))
    return {"single": single, "files": _rotated(d / "flight", 20_000), "dir": d / "flight"}


def _ticks(path: Path) -> dict[int, dict[str, dict[str, np.ndarray]]]:
    """tick -> ship id -> field -> that ship's numbers."""
    out = {}
    with LogReader(path) as r:
        ids = r.ship_table().ids
        for td in r.ticks():
            n = td.ship_count
            out[td.tick] = {ids[k]: {name: a.reshape(n, -1)[i] for name, a in td.arrays.items()
                                     if name != "ship_key"}
                            for i, k in enumerate(td.keys.tolist())}
    return out


def _summary(path: Path) -> pb.LogSummary:
    with LogReader(path) as r:
        return r.read_summary()


def test_rotated_files_each_verify_alone_and_tile_the_run(run):
    files = run["files"]
    assert len(files) >= 3, files
    assert [f.name for f in files] == sorted(f.name for f in files)
    ranges = []
    for i, f in enumerate(files):
        res = verify(str(f))
        assert res.identical and res.summary_compared, res.report()
        with LogReader(f) as r:
            start = r.start_tick
            assert f.name == f"flight-{start:010d}.mcap"
            assert r.scenario.log_format_version == LOG_FORMAT_VERSION and not r.open_ended
            first = next(r.ticks())
            assert first.tick == start and first.is_keyframe
            assert list(r.scenario.ship_ids) == [r.ship_table().ids[k] for k in first.keys]
        s = _summary(f)
        last = i == len(files) - 1
        assert s.complete and s.reason == ("" if last else "rotated"), s
        ranges.append((start, s.last_tick))
        if not last:
            assert "the run goes on in the next file (rotated)" in res.report()
    # the files tile the run: each starts at the tick the one before ends (that tick in both)
    assert ranges[0][0] == 0 and ranges[-1][1] == N_TICKS
    for (_, end), (start, _) in zip(ranges, ranges[1:]):
        assert start == end, ranges
    from touchdown.view.scene import read_run
    assert read_run(files[1]).ships[0].tick[0] == ranges[1][0]
    # and the CLI says so of a file alone
    r = subprocess.run([sys.executable, str(ROOT / "cli.py"), "replay", str(files[1]),
                        "--verify"], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert r.returncode == 0 and f"identical: ticks {ranges[1][0]}..{ranges[1][1]}" in r.stdout, \
        (r.stdout, r.stderr)


def test_rotated_files_hold_the_numbers_of_one_unrotated_log(run):
    """Every number of every file, by ship id, is the single log's at that tick (the first tick
    of a file is a keyframe: it holds more fields than the single log has there)."""
    single = _ticks(run["single"])
    seen = set()
    for f in run["files"]:
        for tick, ships in _ticks(f).items():
            seen.add(tick)
            assert ships.keys() == single[tick].keys(), (f, tick)
            for sid, fields_ in ships.items():
                theirs = single[tick][sid]
                for name, a in fields_.items():
                    if name in theirs:
                        assert a.tobytes() == theirs[name].tobytes(), (f.name, tick, sid, name)
    assert seen == set(range(N_TICKS + 1))
    assert single[100].keys() == {"a", "b", "c"} and single[101].keys() == {"a", "b", "c", "d"}
    assert single[151].keys() == {"a", "c", "d"}
    # every event once, in the file of its tick (an event of a file's first tick is in the file
    # before, with the step that led to it)
    with LogReader(run["single"]) as r:
        events = [e.SerializeToString() for e in r.events()]
    rotated = []
    for f in run["files"]:
        with LogReader(f) as r:
            rotated += [e.SerializeToString() for e in r.events()]
    assert rotated == events and len(events) >= 3


def test_keyframes_fall_on_the_phase_and_a_window_replays_from_the_one_before(run):
    """Log format 5: the keyframes (every field) are the log's first tick and the ticks = PHASE
    (mod KEYFRAMES), in the single log and in each rotated file; a replay of a window starts
    from the keyframe at or before its first tick and verifies."""
    for path in [run["single"], *run["files"]]:
        with LogReader(path) as r:
            assert r.keyframe_phase == PHASE and r.keyframe_interval == KEYFRAMES
            start = r.start_tick
            kf = {td.tick for td in r.ticks() if td.is_keyframe}
            last = r.read_summary().last_tick
        assert kf == {start} | {t for t in range(start, last + 1) if t % KEYFRAMES == PHASE}
    for first, keyframe in [(31, 7), (32, 32), (33, 32), (6, 0), (399, 382)]:
        with LogReader(run["single"]) as r:
            assert r.keyframe_at_or_before(first) == keyframe
        res = verify(str(run["single"]), first=first)
        assert res.identical and res.first_tick == keyframe, res.report()


def test_a_header_whose_keyframe_phase_is_out_of_range_or_format_is_refused(run, tmp_path):
    for fmt, phase, needle in [(5, KEYFRAMES, "is not less than its keyframe_interval"),
                               (4, PHASE, "keyframe_phase in a log of format 4")]:
        bad = tmp_path / f"bad-{fmt}.mcap"

        def edit(data: bytes) -> bytes:
            sr = pb.ScenarioRecord.FromString(data)
            sr.log_format_version, sr.keyframe_phase = fmt, phase
            return sr.SerializeToString()

        rewrite_topic(run["single"], bad, "/touchdown/scenario", edit)
        r = CliRunner().invoke(main, ["replay", str(bad), "--verify"])
        assert r.exit_code == 2 and needle in r.output and "Traceback" not in r.output, r.output
    with pytest.raises(ValueError, match="keyframe phase 25"):
        world_header(World.of(parse_text(SCENE, "s.toml")), "s", "t", KEYFRAMES, keyframe_phase=25)


def test_every_block_boundary_can_end_a_file(tmp_path):
    """max_bytes = 1: a file per block, so files end after ticks where ships join and leave and
    begin with the ships that just joined; each verifies, whole, from a keyframe and per ship."""
    files = _rotated(tmp_path, 1)
    assert len(files) >= 40
    starts = []
    for f in files:
        res = verify(str(f))
        assert res.identical, (f.name, res.report())
        with LogReader(f) as r:
            starts.append((r.start_tick, list(r.scenario.ship_ids)))
    by_start = dict(starts)
    assert by_start[40] == ["a", "b", "c"]  # c joined at 40: a ship of the header there
    assert by_start[101] == ["a", "b", "c", "d"] and by_start[151] == ["a", "c", "d"]
    for f in files[10:13]:
        with LogReader(f) as r:
            sid = r.ship_table().ids[-1]
            start = r.start_tick
        assert verify(str(f), ship_id=sid).identical
        assert verify(str(f), first=start + 3).identical


FLEET = """
name = "fleet"
duration = 60.0
[[ships]]
id = "a"
player_id = "plåyer-a"
[ships.initial]
altitude = 6.0
vertical_speed = -9.0
[[ships]]
id = "b"
[ships.initial]
state = "landed"
east = 25.0
[[ships]]
id = "c"
[ships.initial]
altitude = 20.0
vertical_speed = -14.0
north = 20.0
"""


def test_each_rotated_files_header_and_event_ids_are_its_fleets(tmp_path):
    """A rotating log keeps its ship table (and the events' encoded ids) from one file to the
    next while the fleet is the one of the file before's header, and makes each header's ships
    (their ids and tables) on its writer's thread (session 36): ships join and leave between
    rotations (some in the middle of a file), some files begin with the fleet of the file
    before, some ids are not ASCII. Every file verifies alone, its header is world_header's of
    the world at its first tick, byte for byte, and its events name their ships and players."""
    world = World.of(parse_text(FLEET, "fleet.toml"))
    log = RotatingLog(tmp_path, world, keyframe_interval=KEYFRAMES, keyframe_phase=PHASE,
                      max_bytes=1)
    log.write_block(world.first_block())
    players = dict(zip(world.ship_ids, world.params.ships.player_id))
    headers = {0: world_header(world, "fleet", "", KEYFRAMES, keyframe_phase=PHASE)}
    joined = 0
    for t in range(1, 90):
        if t % 6 == 0:  # a ship joins, falling: events in later files
            sid = f"j{joined}-\u00e9" if joined % 2 else f"j{joined}"
            players[sid] = f"p\u00e9-{joined % 3}" if joined % 3 else f"q{joined}"
            world.spawn({"id": sid, "player_id": players[sid], "initial": {
                "altitude": 2.0 + joined % 4, "vertical_speed": -6.0, "east": 9.0 * joined}})
            joined += 1
        if t % 14 == 0:
            world.retire(world.ship_ids[0])
        # files of 1 to 3 ticks: ends at blocks of the same fleet as the file's start, and not
        ticks = 1 + t % 3
        for block in world.blocks(world.tick + ticks, max_ticks=ticks):
            files = len(log.files)
            log.write_block(block)
            if len(log.files) != files:
                headers[world.tick] = world_header(world, "fleet", "", KEYFRAMES,
                                                   keyframe_phase=PHASE, tables={})
    log.close(reason="stopped")
    assert len(log.files) >= 40 and joined >= 10
    events = 0
    same_fleet = 0
    last_ids = None
    for f in log.files:
        res = verify(str(f))
        assert res.identical and res.summary_compared, (f.name, res.report())
        with LogReader(f) as r:
            want = headers[r.start_tick]
            assert r.scenario.SerializeToString() == want.SerializeToString(), f.name
            table = r.ship_table()
            ids = list(r.scenario.ship_ids)
            same_fleet += ids == last_ids
            last_ids = ids
        for ev in _events(f):
            events += 1
            assert ev.ship_id in table and ev.ship.ship_id == ev.ship_id
            assert ev.player_id == ev.ship.player_id == players[ev.ship_id], ev
    assert events >= 10 and same_fleet >= 5, (events, same_fleet)


def test_a_ship_tables_keys_of_the_ids_it_was_made_of_are_its_keys():
    ids, players = ("x", "y", "\u00e9"), ("p", "q", "r")
    table = ShipTable(ids, players)
    table.add(3, {"id": "z"})
    assert table.keys(ids).tolist() == [0, 1, 2] and table.keys(ids).dtype == np.int64
    assert table.keys(("z", "x")).tolist() == [3, 0]
    assert table.keys(()).tolist() == [] and table.keys(()).dtype == np.int64
    twice = ShipTable(("x", "x"), ("p", "p"))  # (not a fleet: the look-up's keys)
    assert twice.keys(("x", "x")).tolist() == [1, 1]


def _rotating(directory: Path, fail_finish: bool = False):
    """A rotating log of the scene, stepped until its first rotation; returns it, its world and
    the path of the file the rotation closed."""
    world = World.of(parse_text(SCENE, "segments.toml"))
    log = RotatingLog(directory, world, keyframe_interval=KEYFRAMES, max_bytes=20_000)
    log.write_block(world.first_block())
    while len(log.files) < 2:
        for block in world.blocks(world.tick + 5, max_ticks=5):
            log.write_block(block)
    return log, world, log.files[0]


def test_a_rotation_finishes_the_file_before_on_its_writers_thread(tmp_path):
    """The rotation hands the file before to its writer's thread (summary, footer, rename: not
    on the caller's tick); flush() waits for it, and it verifies alone."""
    log, world, first = _rotating(tmp_path)
    assert log.closing_files in ([], [first])  # finished already, or being finished
    log.flush()
    assert log.closing_files == [] and first.exists()
    assert not first.with_name(first.name + ".partial").exists()
    assert verify(str(first)).identical
    log.close(reason="stopped")
    assert all(verify(str(f)).identical for f in log.files)


def test_a_rotated_file_that_cannot_be_finished_is_gone_and_the_next_call_says_so(
        tmp_path, monkeypatch):
    import errno
    import os
    import touchdown.logs.writer as writer_mod
    real = os.replace

    def full(src, dst):
        if "0000000000" in str(dst):  # the first file's rename: the disk is full
            raise OSError(errno.ENOSPC, "No space left on device", str(dst))
        return real(src, dst)
    monkeypatch.setattr(writer_mod.os, "replace", full)
    log, world, first = _rotating(tmp_path)
    with pytest.raises(OSError, match="No space left"):
        log.flush()
    assert first not in log.files and not first.exists()
    assert not first.with_name(first.name + ".partial").exists()
    log.close(reason="stopped")  # the next file goes on, and is finished
    assert len(log.files) == 1 and verify(str(log.files[0])).identical


def test_a_log_may_start_later_with_no_ships_and_ships_joining(tmp_path):
    """A live service's log: the world has no ships at its first tick (60), ships join later
    (by their scenario's spawn_t and by spawn), the run has no set end, and it is stopped."""
    scn = parse_text('name = "empty"\nduration = 1.0\n[[ships]]\nid = "x"\nspawn_t = 4.0\n'
                     '[ships.initial]\naltitude = 2.0\nvertical_speed = -6.0\n', "empty.toml")
    world = World.of(scn)
    for _ in world.blocks(60):
        pass
    assert world.ship_ids == () and world.tick == 60
    header = world_header(world, "service", "test", keyframe_interval=10, open_ended=True)
    assert header.start_tick == 60 and header.open_ended and list(header.ship_ids) == []
    assert json.loads(header.resolved_json)["ships"] == []
    path = tmp_path / "service.mcap"
    writer = LogWriter(path, header)
    writer.write_block(world.first_block())
    for block in world.blocks(75):
        writer.write_block(block)
    world.spawn({"id": "y", "initial": {"state": "landed", "north": 12.0}})
    for block in world.blocks(130):  # n_ticks is 20: an open-ended run goes past it
        writer.write_block(block)
    writer.close(complete=True, reason="stopped")
    res = verify(str(path))
    assert res.identical and res.summary_compared, res.report()
    assert res.first_tick == 60 and res.last_tick == 130 and res.events_compared >= 1
    with LogReader(path) as r:
        assert r.ship_table().ids == ["y", "x"] and r.ship_table().joined == [76, 80]
    for kwargs in ({"ship_id": "x"}, {"ship_id": "y"}, {"first": 95}, {"first": 10}):
        assert verify(str(path), **kwargs).identical, kwargs
    runner = CliRunner()
    r = runner.invoke(main, ["replay", str(path), "--verify"])
    assert r.exit_code == 0 and "identical: ticks 60..130" in r.output, r.output
    rows = [json.loads(x) for x in runner.invoke(main, ["export", str(path)]).output.splitlines()]
    assert {row["tick"] for row in rows} == set(range(76, 131))  # no ship before tick 76
    assert rows[0]["ship_id"] == "y" and rows[0]["east"] is not None
    # the view reads it from its first tick, the ships from the ticks they join
    from touchdown.view.scene import read_run
    tracks = {t.ship_id: t for t in read_run(path).ships}
    assert tracks["y"].tick[0] == 76 and tracks["x"].tick[0] == 80
    assert tracks["y"].tick[-1] == 130 and np.isfinite(tracks["y"].pos_site_m).all()
    # a what-if of it re-runs from its first tick; its new log verifies too
    out = tmp_path / "whatif.mcap"
    r = runner.invoke(main, ["replay", str(path), "--set", "sim.integrator=rk4", "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert verify(str(out)).identical


def test_summaries_say_where_and_why_a_file_ends(tmp_path, run):
    """A summary must say why its file ends where it does: an unknown reason, or "complete" with
    no reason short of the run's end, is a divergence."""
    src = run["files"][0]
    for reason, complete, ok in (("rotated", True, True), ("stopped", True, True),
                                 ("stopped", False, True), ("interrupted", False, True),
                                 ("handed over", True, True), ("lost", True, True),
                                 ("", True, False), ("bogus", True, False),
                                 ("rotated", False, False)):
        def edit(data: bytes, reason=reason, complete=complete) -> bytes:
            s = pb.LogSummary.FromString(data)
            s.reason, s.complete = reason, complete
            return s.SerializeToString()
        bad = tmp_path / f"{reason or 'none'}-{complete}.mcap"
        rewrite_topic(src, bad, TOPIC_SUMMARY, edit)
        res = verify(str(bad))
        assert res.identical == ok, (reason, complete, res.report())
        if not ok:
            assert res.divergence.field.startswith("summary"), res.report()


def test_the_writer_refuses_a_first_block_that_is_not_the_headers_tick(tmp_path):
    world = World.of(parse_text(SCENE, "segments.toml"))
    for _ in world.blocks(30):
        pass
    header = world_header(world, "s", "t")
    assert header.start_tick == 30 and list(header.ship_ids) == ["a", "b"]
    assert all(k not in s for s in json.loads(header.resolved_json)["ships"]
               for k in ("spawn_t", "retire_t", "inputs") if s.get(k))
    with LogWriter(tmp_path / "x.mcap", header) as w:
        with pytest.raises(ValueError, match="next tick is 30"):
            w.write_block(next(world.blocks(40)))
    log = RotatingLog(tmp_path / "rot", world)
    with pytest.raises(ValueError, match="world.first_block"):
        log.write_block(next(world.blocks(50)))
    log.abandon()
    assert log.files == [] and not list((tmp_path / "rot").glob("*"))


def test_flush_puts_every_tick_written_so_far_in_the_file(tmp_path):
    """A live service flushes its log before it checkpoints: the partial file then holds every
    tick written, readable (and verifiable) as a log whose writer was killed."""
    world = World.of(parse_text(SCENE, "segments.toml"))
    log = RotatingLog(tmp_path, world, keyframe_interval=KEYFRAMES, open_ended=True)
    log.write_block(world.first_block())
    for block in world.blocks(57, max_ticks=10):
        log.write_block(block)
    log.flush()
    partial = Path(str(log.files[-1]) + ".partial")
    res = verify(str(partial))
    assert res.identical and res.last_tick == 57, res.report()
    for block in world.blocks(80, max_ticks=10):
        log.write_block(block)
    log.close(complete=True, reason="stopped")
    assert not partial.exists() and verify(str(log.files[-1])).identical


# -- touchdown incident -----------------------------------------------------------------------
def _events(path: Path) -> list[pb.TransitionEvent]:
    with LogReader(path) as r:
        return list(r.events())


def _incident(*args) -> "object":
    return CliRunner().invoke(main, ["incident", *map(str, args)])


@pytest.mark.parametrize("ship", ["a", "d"])
def test_an_incident_cut_holds_one_ship_around_its_transition_and_verifies(run, tmp_path, ship):
    ev = next(e for e in _events(run["single"]) if e.ship_id == ship)
    out = tmp_path / f"cut-{ship}.mcap"
    r = _incident(run["dir"], "--ship", ship, "--around", ev.tick, "--before", "1",
                  "--after", "2", "-o", out)
    assert r.exit_code == 0, r.output
    lo, hi = ev.tick - 20, ev.tick + 40
    res = verify(str(out))
    assert res.identical and res.summary_compared, res.report()
    with LogReader(out) as rd:
        assert rd.ship_table().ids == [ship]
        start = rd.start_tick
        assert start <= lo and (start % KEYFRAMES == PHASE or start in
                                {f_start for f_start, _ in _file_ranges(run["files"])})
        ticks = _ticks(out)
        assert min(ticks) == start and max(ticks) == hi == rd.scenario.n_ticks
        assert [e.SerializeToString() for e in rd.events()] == [
            e.SerializeToString() for e in _events(run["single"])
            if e.ship_id == ship and start < e.tick <= hi]
    single = _ticks(run["single"])
    for tick, ships in ticks.items():
        assert set(ships) <= {ship}
        for name, a in ships.get(ship, {}).items():
            if name in single[tick][ship]:
                assert a.tobytes() == single[tick][ship][name].tobytes(), (tick, name)
    if ship == "d":  # it joins at tick 101, after the cut starts: the cut begins with no ship
        assert ticks[start] == {} and "joins the fleet at tick 101" in r.output


def _file_ranges(files):
    out = []
    for f in files:
        with LogReader(f) as r:
            out.append((r.start_tick, r.read_summary().last_tick))
    return out


def test_an_incident_window_across_two_files_is_cut_from_both(run, tmp_path):
    (_, end), _ = _file_ranges(run["files"])[:2]
    out = tmp_path / "across.mcap"
    r = _incident(*run["files"], "--ship", "a", "--around", end, "--before", "0.5", "--after",
                  "0.5", "-o", out)
    assert r.exit_code == 0, r.output
    assert "spans 2 files" in r.output
    res = verify(str(out))
    assert res.identical and res.last_tick == end + 10, res.report()


def test_an_incident_across_two_takes_of_a_shard_follows_the_later_take(tmp_path):
    """A live shard's files of two takes (logs.shards): worker 1 took it at tick 0 and ran on to
    tick 200 without ever marking its file (frozen, then killed); worker 2 took it later from
    Redis's checkpoint at tick 100 and gave ship a another throttle at tick 120. A cut from tick
    80 to 160 is worker 1's file up to tick 100 and worker 2's after it: worker 2's throttle,
    never worker 1's, whose file holds a history the world did not keep."""
    from touchdown.logs.shards import ShardTake
    takes = {1: ShardTake(0, "1:w1", 1_000), 2: ShardTake(0, "2:w2", 2_000)}

    def fly(take: int, start: int, directory: Path) -> None:
        world = World.of(parse_text(SCENE, "segments.toml"))
        log = None
        for t in range(0, 200, 10):
            if t == start:
                log = RotatingLog(directory, world, keyframe_interval=KEYFRAMES,
                                  keyframe_phase=PHASE, shard=takes[take], prefix=f"w{take}",
                                  open_ended=True)
                log.write_block(world.first_block())
            if t == 30:
                world.command("a", throttle=0.25, hold=2)
            if t == 120:
                world.command("a", throttle={1: 0.9, 2: 0.6}[take])
            for block in world.blocks(t + 10, max_ticks=10):
                if log is not None:
                    log.write_block(block)
        log.close()

    fly(1, 0, tmp_path / "shard-000")
    fly(2, 100, tmp_path / "shard-000")
    # touchdown doctor names a file's take (an operator's first look at a shard's folder)
    doc = CliRunner().invoke(main, ["doctor", str(next((tmp_path / "shard-000").glob("w2-*")))])
    assert ("shard: 0, take 2:w2 (granted 1970-01-01T00:00:00.002Z by Redis's clock"
            in doc.output), doc.output
    out = tmp_path / "cut.mcap"
    r = _incident(tmp_path / "shard-000", "--ship", "a", "--around", 130, "--before", "2.5",
                  "--after", "1.5", "-o", out)
    assert r.exit_code == 0, r.output
    assert "spans 2 files" in r.output and "after 100 are superseded" in r.output, r.output
    assert verify(str(out)).identical
    with LogReader(out) as rd:
        throttles = [(c.tick, c.throttle) for c in rd.timeline().commands]
    assert (120, 0.6) in throttles and all(v != 0.9 for _t, v in throttles), throttles


def test_an_incident_cut_from_a_tampered_recording_is_refused(run, tmp_path):
    """One number of the ship, one ulp off inside the window: the cut stops there, exit 1, one
    line naming the file, tick and field; nothing is written."""
    ev = next(e for e in _events(run["single"]) if e.ship_id == "a")
    src = next(f for f, (s, e) in zip(run["files"], _file_ranges(run["files"]))
               if s <= ev.tick <= e)
    with LogReader(src) as r:
        key = r.ship_table().key("a")

    def edit(data: bytes) -> bytes:
        t, t_s, n, arrays = decode_tick(data)
        if t != ev.tick:
            return data
        i = int(np.flatnonzero(arrays["ship_key"] == key)[0])
        a = arrays["altitude_m"].copy()
        a[i] = np.nextafter(a[i], np.inf)
        arrays["altitude_m"] = a
        return encode_tick(t, t_s, n, arrays)
    bad = tmp_path / "tampered.mcap"
    rewrite_topic(src, bad, TOPIC_TICKS, edit)
    out = tmp_path / "cut.mcap"
    r = _incident(bad, "--ship", "a", "--around", ev.tick, "--before", "0.2", "--after", "0.2",
                  "-o", out)
    assert r.exit_code == 1, r.output
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.output
    assert f"tick {ev.tick}" in lines[0] and "altitude_m" in lines[0] and "diverges" in lines[0]
    assert not out.exists() and not Path(str(out) + ".partial").exists()
    # the same window from the untouched file is cut
    assert _incident(src, "--ship", "a", "--around", ev.tick, "--before", "0.2", "--after",
                     "0.2", "-o", out).exit_code == 0


@pytest.mark.parametrize("args, needle", [
    (["--around", "100", "-o", "{out}"], "--ship"),
    (["--ship", "a", "-o", "{out}"], "--around"),
    (["--ship", "a", "--around", "100"], "-o"),
    (["--ship", "a", "--around", "ten", "-o", "{out}"], "--around"),
    (["--ship", "a", "--around", "-4", "-o", "{out}"], "--around"),
    (["--ship", "a", "--around", "100", "--before", "-1", "-o", "{out}"], "--before"),
    (["--ship", "a", "--around", "100", "--after", "nan", "-o", "{out}"], "--after"),
    (["--ship", "a", "--around", "100", "-o", "{dir}/cut.txt"], "cut.txt"),
    (["--ship", "nobody", "--around", "100", "-o", "{out}"], "nobody"),
    (["--ship", "a", "--around", "99999", "-o", "{out}"], "--around 99999"),
])
def test_bad_incident_flags_exit_2_with_one_line(run, tmp_path, args, needle):
    out = tmp_path / "cut.mcap"
    args = [a.format(out=out, dir=tmp_path) for a in args]
    r = _incident(run["dir"], *args)
    assert r.exit_code == 2, r.output
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.output and needle in lines[0], r.output
    assert not out.exists() and not Path(str(out) + ".partial").exists()


def test_incident_of_a_missing_or_broken_log_exits_2(tmp_path):
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not a log" * 100)
    for log in (tmp_path / "missing.mcap", junk, tmp_path):
        r = _incident(log, "--ship", "a", "--around", "5", "-o", tmp_path / "o.mcap")
        assert r.exit_code == 2, r.output
        lines = r.output.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in r.output, r.output


def test_a_file_rotated_at_the_runs_last_tick_says_so_and_the_next_verifies(tmp_path):
    """Rotation follows the file's size as the writer's thread last saw it, so it can fall at the
    run's very last tick: that file holds the whole rest of the run and says the run goes on; the
    next holds that tick alone, as a keyframe, and verifies too."""
    world = World.of(parse_text(SCENE, "segments.toml"))
    log = RotatingLog(tmp_path, world, keyframe_interval=KEYFRAMES, max_bytes=1 << 30)
    log.write_block(world.first_block())
    for t in range(0, N_TICKS, 10):
        if t == N_TICKS - 10:
            log.max_bytes = 1  # the last block puts it past the bound
        for block in world.blocks(t + 10, max_ticks=10):
            log.write_block(block)
    log.close()
    assert len(log.files) == 2
    first, last = (verify(str(f)) for f in log.files)
    assert first.identical and "the run goes on in the next file (rotated)" in first.report()
    assert last.identical, last.report()
    assert last.first_tick == last.last_tick == N_TICKS
