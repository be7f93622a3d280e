"""Hostile input (issue 13): a log or scenario from outside may be damaged, cut or made to hurt the
tool. Every command answers in bounded time and memory, with one line and exit 2 for bad input,
exit 1 for a failure of the work, says when it read or checked only part of a log, and never
leaves a half-written file.

The fuzz campaign (bench/fuzz.py) runs thousands of generated files; the tests after it pin each
finding of the issue to the behaviour a user sees."""
import json
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from touchdown.bench import fuzz
from touchdown.cli import main
from touchdown.logs.reader import LogReader
from touchdown.proto import touchdown_pb2 as pb

ROOT = Path(__file__).resolve().parents[1]


def invoke(*args, **kw):
    r = CliRunner().invoke(main, [str(a) for a in args], **kw)
    assert r.exception is None or isinstance(r.exception, SystemExit), r.exception
    return r


def assert_refused(r, *needles):
    """Exit 2, one line, no traceback, naming what it must."""
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in r.output, r.output
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


@pytest.fixture(scope="module")
def bounce(tmp_path_factory):
    path = tmp_path_factory.mktemp("hostile") / "bounce.mcap"
    assert invoke("record", "bounce", "--set", "duration=8", "-o", path).exit_code == 0
    return path


@pytest.fixture(scope="module")
def bombs(bounce) -> dict[str, bytes]:
    """bench/fuzz.py's bombs of ``bounce`` by name, made once a module (a worker's): making them
    compresses hundreds of MiB of zeros (~2 s), which each test that wanted one bomb paid again.
    Each test writes the bomb it reads to its own tmp_path (bytes: nothing can change them)."""
    return dict(fuzz.bombs(bounce.read_bytes()))


def rewrite(src: Path, dst: Path, edit) -> Path:
    """``src`` rewritten through the stock mcap writer, each message passed through
    ``edit(topic, bytes) -> list of (topic, bytes)``."""
    dst.write_bytes(fuzz.rewrite_log(src.read_bytes(), edit))
    return dst


def with_record(src: Path, dst: Path, change) -> Path:
    """``src`` with its ScenarioRecord changed by ``change(record)``."""
    def edit(topic, data):
        if topic == "/touchdown/scenario":
            rec = pb.ScenarioRecord.FromString(data)
            change(rec)
            data = rec.SerializeToString()
        return [(topic, data)]
    return rewrite(src, dst, edit)


# -- the campaign -----------------------------------------------------------------------------
@pytest.mark.slow
def test_a_fuzz_campaign_of_2000_files_finds_no_hang_traceback_blowup_or_silent_result():
    """2,000+ generated files of every class (bench/fuzz.py's docstring lists them), each run
    through verify, export or record in one process whose address space is capped at 1.5 GiB,
    each within 10 s. A defect is a hang, an escaped exception, MemoryError, an exit 0 whose
    content differs from the original's without saying so, or a recorded log that does not
    verify or export valid JSON."""
    r = subprocess.run([sys.executable, "cli.py", "bench", "fuzz", "--files", "2000",
                        "--seconds", "10", "--memory-gib", "1.5", "--json"], cwd=ROOT, capture_output=True,
                       text=True, timeout=1200)
    assert r.stdout.strip(), r.stderr[-3000:]
    result = json.loads(r.stdout.strip().splitlines()[-1])
    counts = result["counts"]
    print(f"{sum(map(sum, (c.values() for c in counts.values())))} files in "
          f"{result['seconds']:.1f} s")
    assert sum(sum(c.values()) for c in counts.values()) >= 2000
    assert set(counts) == set(fuzz.LOG_CLASSES + fuzz.SCENARIO_CLASSES)
    defects = {f"{cls}/{o}": n for cls, c in counts.items() for o, n in c.items()
               if o in fuzz.BAD and n}
    assert not defects, (defects, result["examples"])
    assert r.returncode == 0
    # the corpus reaches the guards it is for, not only the magic-number check
    assert counts["bomb"]["refused"] >= 40
    assert counts["truncate"]["partial"] > 0 and counts["concat"]["partial"] > 0
    assert counts["events"]["diverged"] > 0 and counts["tick"]["diverged"] > 0
    assert counts["scenario_file"]["refused"] > 0 and counts["set"]["refused"] > 0


# -- bounded reading -----------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("framing", ["indexed", "unindexed"])
def test_every_decompression_bomb_is_refused_naming_the_limit(bombs, tmp_path, framing):
    for name, data in bombs.items():
        if not name.endswith(framing) or name.startswith("tick-100MiB"):
            continue
        path = tmp_path / f"{name}.mcap"
        path.write_bytes(data)
        line = assert_refused(invoke("replay", path, "--verify"), path.name)
        assert any(w in line for w in ("claims", "declares", "records (TOUCHDOWN_MAX_RECORDS",
                                       "lz4", "runs past", "damaged fleet record",
                                       "damaged command record")), line


def test_a_bomb_in_a_cut_log_ends_what_is_read_and_export_says_so(bombs, tmp_path):
    data = bombs["zstd-claims-1000-walked"]
    path = tmp_path / "bomb.mcap"
    path.write_bytes(data)
    assert_refused(invoke("replay", path, "--verify"), "no tick records", "declares 1,000 bytes")
    r = invoke("export", path)
    assert r.exit_code == 0 and r.stdout == ""
    assert "read only part of the log" in r.stderr and "declares 1,000 bytes" in r.stderr


#: opens a log (argv[2] "open") or verifies it (replay --verify's call: "verify") in a fresh
#: process: "<peak RSS before, KiB> <peak RSS after, KiB> <what it said>". The peak is the
#: process's own (VmHWM); getrusage's ru_maxrss is not: Linux hands a child the resident size its
#: parent had when it forked (pytest's, a few hundred MiB), hiding the growth. What verify does
#: for any log before it reads one (its imports, the scenario's code: ~50 MiB) is done first,
#: from the log's header, and not counted
_OPEN_RSS = """
import re, sys
from touchdown.logs import LogError
from touchdown.logs.reader import LogReader
from touchdown.replay.verify import scenario_of, verify
def peak_kib():
    with open("/proc/self/status") as f:
        return int(re.search(r"VmHWM:\\s+(\\d+) kB", f.read()).group(1))
if sys.argv[2] == "verify":
    with LogReader(sys.argv[1]) as r:
        scenario_of(r)
before = peak_kib()
try:
    if sys.argv[2] == "verify":
        verify(sys.argv[1])
        said = "verified"
    else:
        LogReader(sys.argv[1]).close()
        said = "opened"
except LogError as exc:
    said = str(exc)
print(before, peak_kib(), said)
"""


def read_in_a_fresh_process(path: Path, read: str = "open") -> tuple[float, float, str]:
    """_OPEN_RSS's ``read`` of ``path``: (peak RSS before, MiB; what the read grew it by, MiB;
    what it said)."""
    r = subprocess.run([sys.executable, "-c", _OPEN_RSS, str(path), read], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    before, after, said = r.stdout.split(" ", 2)
    return int(before) / 1024, (int(after) - int(before)) / 1024, said.strip()


#: how a crafted chunk reaches the readers (bench/fuzz.py's _crafted_log): indexed, its index
#: listing no channel (read by every read) or the fleet's (read by the fleet's), a finished file
#: without a summary, a cut file (no footer: walked)
FRAMINGS = ["indexed", "fleet-indexed", "unindexed", "walked"]


@pytest.mark.parametrize("framing", FRAMINGS)
def test_a_bomb_in_the_header_s_chunk_is_not_inflated_to_read_the_header(bounce, tmp_path,
                                                                          framing):
    """The chunk holding the header declares 200 MiB (within the general 256 MiB bound): the
    header is read from it as a stream, the rest of it not inflated (before, opening the log
    took its peak RSS up by the whole 200 MiB). A read of its ticks then refuses the chunk by
    what a chunk of this log's one ship can hold."""
    path = tmp_path / f"header-bomb-{framing}.mcap"
    path.write_bytes(fuzz.header_bomb(bounce.read_bytes(), framing, mib=200))
    before, grew_mib, said = read_in_a_fresh_process(path, "open")
    print(f"{framing}: opening took the peak RSS from {before:.1f} MiB up by "
          f"{grew_mib:.1f} MiB ({said})")
    assert said == "opened" and grew_mib < 20, (grew_mib, said)
    line = assert_refused(invoke("replay", path, "--verify"), path.name)
    assert "claims 209,7" in line and "this log's 1 ship(s) can hold" in line, line


@pytest.mark.parametrize("framing", FRAMINGS)
def test_replay_verify_of_a_header_chunk_bomb_never_inflates_it(bounce, tmp_path, framing):
    """The same bomb, verified: the fleet's read (ship_table) reads the header's chunk too (its
    index lists the fleet's channel, or none; unindexed or cut, every chunk), within what the
    fleet read so far bounds (here one ship: 1.3 MB), as a stream: its last record, past what
    a writer fills before it closes a chunk and not a fleet record, is not inflated, and the
    chunk is then refused by the whole fleet's bound. Before, ship_table inflated the 200 MiB
    (peak RSS +202 MiB) before that bound refused it."""
    path = tmp_path / f"header-bomb-{framing}.mcap"
    path.write_bytes(fuzz.header_bomb(bounce.read_bytes(), framing, mib=200))
    before, grew_mib, said = read_in_a_fresh_process(path, "verify")
    print(f"{framing}: verify took the peak RSS from {before:.1f} MiB up by {grew_mib:.1f} MiB "
          f"({said})")
    assert grew_mib < 5, (grew_mib, said)
    assert "claims 209,7" in said and "this log's 1 ship(s) can hold" in said, said
    line = assert_refused(invoke("replay", path, "--verify"), path.name)
    assert "claims 209,7" in line and "this log's 1 ship(s) can hold" in line, line


@pytest.mark.parametrize("framing", FRAMINGS)
def test_a_fleet_record_bomb_is_refused_at_its_first_piece(bombs, tmp_path, framing):
    """The header's chunk ends in a message on the fleet's channel of 150 MiB of zeros (within
    what a fleet record may hold, what a header may): the fleet's read takes it as it is
    inflated, a piece at a time, and the first piece is no fleet record (field 0). Cut (walked),
    the refusal ends the part read, and the chunk is then refused by the fleet's bound."""
    path = tmp_path / f"fleet-bomb-{framing}.mcap"
    path.write_bytes(bombs[f"fleet-record-150MiB-{framing}"])
    before, grew_mib, said = read_in_a_fresh_process(path, "verify")
    print(f"{framing}: verify took the peak RSS from {before:.1f} MiB up by {grew_mib:.1f} MiB "
          f"({said})")
    assert grew_mib < 5, (grew_mib, said)
    needle = "claims 157,2" if framing == "walked" else "damaged fleet record (field 0"
    assert needle in said, said
    assert needle in assert_refused(invoke("replay", path, "--verify"), path.name)


def _streamed_chunks(monkeypatch) -> list[int]:
    """The declared sizes of the chunks read as a stream from now on (safe_read._grown_records,
    the reads bounded by the fleet), appended as each is read."""
    from touchdown.logs import safe_read
    streamed = []
    real = safe_read._grown_records

    def spy(chunk, *args):
        streamed.append(chunk.uncompressed_size)
        return real(chunk, *args)
    monkeypatch.setattr(safe_read, "_grown_records", spy)
    return streamed


def _joining_log(path: Path, joins: int, inputs: int) -> None:
    """A log of one ship, then ``joins`` ships joining at once at tick 4 (each with ``inputs``
    commands in its table: a larger fleet record), written as the service writes (LogWriter)."""
    from touchdown.logs.header import scenario_message
    from touchdown.logs.writer import LogWriter
    from touchdown.sim.scenario import parse
    from touchdown.sim.world import World
    scn = parse({"name": "joins", "duration": 0.5,
                 "ships": [{"id": "s0", "initial": {"altitude": 2.0}}]}, "joins")
    world = World.of(scn)
    with LogWriter(path, scenario_message(scn, "joins", keyframe_interval=10)) as writer:
        writer.write_block(world.first_block())
        for t in (0, 4, 8):
            if t == 4:
                for i in range(joins):
                    world.spawn({"id": f"j{i}", "initial": {"altitude": 1.0 + i % 5,
                                                            "east": 3.0 * i},
                                 "inputs": [{"t": 0.3 + 0.01 * k, "throttle": 0.5}
                                            for k in range(inputs)]})
            for block in world.blocks(min(t + 4, 10), max_ticks=4):
                writer.write_block(block)


@pytest.mark.parametrize("joins, inputs", [(2500, 0), (4000, 10)],
                         ids=["its-ticks-past-the-bound", "its-fleet-record-past-the-bound"])
def test_ships_joining_within_a_chunk_over_the_fleet_s_bound_read(tmp_path, monkeypatch, joins,
                                                                  inputs):
    """Ships joining at once: the chunk holding their joins ends past what the fleet before it
    (one ship) bounds, with a tick of the ships that joined in it (2,500 ships: a chunk of 1.6
    MB) or with the fleet record itself (4,000 joins, each ship with its commands: 1.7 MB). The
    fleet's read takes it as a stream (the joins it holds bound the rest), and the log reads as
    written: verify finds it identical, and its cut copy (no footer: walked) the same ships and
    ticks."""
    from touchdown.replay.verify import verify
    streamed = _streamed_chunks(monkeypatch)
    path = tmp_path / "joins.mcap"
    _joining_log(path, joins, inputs)
    res = verify(str(path))
    assert res.divergence is None and res.ticks_compared == 11, res.divergence
    assert streamed, "no chunk was over the fleet's bound when the fleet's read reached it"
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[:-1])
    with LogReader(path) as whole, LogReader(cut) as part:
        assert list(part.ship_table().ids) == list(whole.ship_table().ids)
        assert len(whole.ship_table()) == joins + 1
        assert [t.raw for t in part.ticks()] == [t.raw for t in whole.ticks()]
        assert not part.status.complete


@pytest.mark.parametrize("bomb", ["zstd-claims-true-walked", "empty-records-walked"])
def test_replay_verify_of_a_second_chunk_bomb_in_a_cut_log_never_inflates_it(bombs, tmp_path,
                                                                             bomb):
    """A cut log (no footer: every read walks it) whose second chunk declares 64 MiB of zeros
    (or 20 MiB: millions of empty records), its size and CRC true. The fleet's read refuses
    it, which ends the part it reads; each read after it (the commands', the ticks', the
    events') walks the file again, and bounds that chunk by the whole fleet (one ship: 1.3 MB)
    too, save a chunk ending in a tick's commands: read as a stream, its records past what a
    writer fills before it closes a chunk are refused, not inflated. Before, the commands'
    read inflated the whole chunk (peak RSS +64.5 MiB; the 20 MiB one +20.5 MiB)."""
    path = tmp_path / f"{bomb}.mcap"
    path.write_bytes(bombs[bomb])
    before, grew_mib, said = read_in_a_fresh_process(path, "verify")
    print(f"{bomb}: verify took the peak RSS from {before:.1f} MiB up by {grew_mib:.1f} MiB "
          f"({said})")
    assert grew_mib < 5, (grew_mib, said)
    needle = "a record runs past the 1,310,720 bytes a writer fills before it ends a chunk"
    assert said.startswith(str(path)) and needle in said, said
    assert needle in assert_refused(invoke("replay", path, "--verify"), path.name)


def _commands_log(path: Path, commands: int, id_chars: int, keyframe_interval: int = 10
                  ) -> None:
    """A log of one ship (its id ``id_chars`` long) given ``commands`` commands at tick 4 (World
    .commands takes any number a ship a tick, as a scenario's inputs at one time do), written
    as the service writes (LogWriter): its command batch is a record of about ``commands`` x
    (45 + ``id_chars``) bytes, ending the chunk that holds ticks 1 to 3 before it."""
    from touchdown.logs.header import scenario_message
    from touchdown.logs.writer import LogWriter
    from touchdown.sim.scenario import parse
    from touchdown.sim.world import World
    sid = "s" * id_chars
    scn = parse({"name": "commands", "duration": 0.5,
                 "ships": [{"id": sid, "initial": {"altitude": 2.0}}]}, "commands")
    world = World.of(scn)
    with LogWriter(path, scenario_message(scn, "commands",
                                          keyframe_interval=keyframe_interval)) as writer:
        writer.write_block(world.first_block())
        for t in range(0, 10, 2):
            if t == 4:
                world.commands([(sid, 0.5, (0.0, 0.1, 0.0), 0)] * commands)
            for block in world.blocks(min(t + 2, 10), max_ticks=2):
                writer.write_block(block)


@pytest.fixture(scope="module")
def commands_20k(tmp_path_factory) -> Path:
    """_commands_log's 20,000 commands of one ship with a 200-character id at tick 4 (a 4.9 MB
    batch; keyframe interval 2), written once a module (a worker's) for the tests that read it;
    read-only (a test that cuts it cuts a copy)."""
    path = tmp_path_factory.mktemp("commands") / "commands.mcap"
    _commands_log(path, 20_000, 200, keyframe_interval=2)
    path.chmod(0o444)
    return path


def test_a_tick_s_commands_past_the_fleet_s_bound_read(commands_20k, tmp_path, monkeypatch):
    """What the fleet does not bound: a tick's commands (any number a ship). 20,000 commands of
    one ship with a 200-character id are a command batch of 4.9 MB, ending a chunk over what
    a chunk of the one ship's ticks can hold (1.3 MB): every read takes it as a stream (its
    records before the batch within what a writer fills), the commands' read keeps the batch,
    the others pass over it, and the log reads as written: verify finds it identical, whole,
    cut (walked) and cut around tick 4 by `touchdown incident`. Before, the ticks' read refused
    the chunk ("claims 4,861,509 bytes")."""
    from touchdown.replay.verify import verify
    streamed = _streamed_chunks(monkeypatch)
    path = commands_20k
    res = verify(str(path))
    assert res.divergence is None and res.ticks_compared == 11, res.divergence
    assert streamed and max(streamed) > 4_000_000, streamed
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[:-1])
    res = verify(str(cut))
    assert res.divergence is None and res.ticks_compared == 11, res.divergence
    with LogReader(cut) as r:
        assert len(r.timeline().commands) == 20_000 and not r.status.complete
        assert len(list(r.events())) == 0 and r.read_summary().last_tick == 10
    around = tmp_path / "incident.mcap"
    assert invoke("incident", path, "--ship", "s" * 200, "--around", 4, "--before", 0.05,
                  "--after", 0.2, "-o", around).exit_code == 0
    res = verify(str(around))
    assert res.divergence is None and res.ticks_compared == 7, res.divergence
    with LogReader(around) as r:
        assert len(r.timeline().commands) == 20_000


def test_a_recovered_log_whose_first_chunk_ends_in_a_tick_s_commands_verifies(commands_20k,
                                                                              tmp_path):
    """`touchdown recover` rewrites a log with the library's writer, which does not end the
    first chunk after the first tick: the header's chunk then holds ticks 0 to 3 and ends in
    tick 4's 20,000 commands (a 4.9 MB batch), over what a chunk of the one ship's ticks can
    hold (1.3 MB). The header's chunk is checked as every read after the fleet's reads a
    chunk: its last record a tick's commands, passed over. Before, `replay --verify` of the
    recovered log refused it ("a chunk claims 4,882,224 bytes uncompressed")."""
    recovered = tmp_path / "recovered.mcap"
    assert invoke("recover", commands_20k, "-o", recovered).exit_code == 0
    r = invoke("replay", recovered, "--verify")
    assert r.exit_code == 0 and "identical: ticks 0..10" in r.output, r.output
    with LogReader(recovered) as log:
        assert log._header_chunk is not None and log._header_chunk[1] > 4_000_000
        assert len(log.timeline().commands) == 20_000


@pytest.mark.parametrize("cut", [False, True])
def test_a_tick_s_commands_past_the_fleet_s_bound_are_inflated_once_a_read(commands_20k,
                                                                            tmp_path,
                                                                            monkeypatch, cut):
    """The chunk ending in 20,000 commands (4.9 MB) is read to its end, its size and CRC
    checked, by the first read that reaches it; the reads after it that do not want the
    commands (the ticks', the events', the summary's) stop where the batch begins. verify then
    inflates it once (indexed: the commands' read) or twice (cut: the fleet's check, then the
    commands' read), not once for every read (cut: 4 before), and finds the log identical."""
    from touchdown.logs import safe_read
    from touchdown.replay.verify import verify
    path = commands_20k
    if cut:
        path = tmp_path / "cut.mcap"
        path.write_bytes(commands_20k.read_bytes()[:-1])
    ends = []
    real = safe_read._nothing_past

    def spy(r, piece, declared, where):
        ends.append(declared)
        return real(r, piece, declared, where)
    monkeypatch.setattr(safe_read, "_nothing_past", spy)
    res = verify(str(path))
    assert res.divergence is None and res.ticks_compared == 11, res.divergence
    assert sum(d > 4_000_000 for d in ends) == (2 if cut else 1), ends


def test_a_log_of_more_commands_than_a_timeline_may_hold_is_refused(tmp_path, monkeypatch):
    """timeline() holds every command (~140 bytes each in memory at its peak, ~390 if all
    differ), so the commands a log may hold are bounded (TOUCHDOWN_MAX_COMMANDS, 4,000,000 by
    default): a 36 kB log of 5 million well-formed commands took timeline()'s peak RSS up by
    2.4 GB (4 million now: 525 MiB). Beyond the
    bound the log is refused with one line naming the file and the setting, before the batch
    past it is parsed; at the bound (the 20,000 commands of one tick, exactly) it verifies."""
    path = tmp_path / "commands.mcap"
    _commands_log(path, 20_000, 8, keyframe_interval=2)
    monkeypatch.setenv("TOUCHDOWN_MAX_COMMANDS", "19999")
    assert_refused(invoke("replay", path, "--verify"), path.name,
                   "more than 19,999 commands (TOUCHDOWN_MAX_COMMANDS)")
    monkeypatch.setenv("TOUCHDOWN_MAX_COMMANDS", "20000")
    r = invoke("replay", path, "--verify")
    assert r.exit_code == 0 and "identical: ticks 0..10" in r.output, r.output


def test_a_timeline_of_50_000_commands_holds_them_in_under_250_bytes_each(tmp_path):
    """timeline() holds a log's commands in little memory: each command compact (no __dict__),
    the values commands repeat (ticks, ship ids, numbers, vectors) held once, the batch parsed
    from where it lies in its chunk a megabyte at a time. 50,000 commands of one tick (a 2.4 MB
    batch: three pieces) written by the project's writer: timeline()'s peak (tracemalloc) was
    ~380 bytes a command, ~130 now (held: 280, now 80). Those are per command, the same at
    50,000, 200,000 (this test's count until session 31: 4x the time under tracemalloc) and
    1,000,000 commands (docs/issue36/session25-timeline.txt, session26-fastpart.txt)."""
    import tracemalloc
    path = tmp_path / "commands.mcap"
    _commands_log(path, 50_000, 8, keyframe_interval=2)
    with LogReader(path) as r:
        r.ship_table()
        tracemalloc.start()
        try:
            before = tracemalloc.get_traced_memory()[0]
            commands = r.timeline().commands
            held, peak = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
    per, held_per = (peak - before) / len(commands), (held - before) / len(commands)
    print(f"timeline() of {len(commands):,} commands: peak {per:.0f} B a command, "
          f"{held_per:.0f} held")
    assert len(commands) == 50_000 and per < 250, per
    assert commands[0] == commands[-1] and commands[-1].rcs == (0.0, 0.1, 0.0)


def _log_of_commands(path: Path, given: list) -> None:
    """A log of one ship ("s") given the commands ``given`` (World.commands' form) at tick 4,
    written by the project's writer."""
    from touchdown.logs.header import scenario_message
    from touchdown.logs.writer import LogWriter
    from touchdown.sim.scenario import parse
    from touchdown.sim.world import World
    scn = parse({"name": "zeros", "duration": 0.5,
                 "ships": [{"id": "s", "initial": {"altitude": 2.0}}]}, "zeros")
    world = World.of(scn)
    with LogWriter(path, scenario_message(scn, "zeros", keyframe_interval=2)) as writer:
        writer.write_block(world.first_block())
        for block in world.blocks(4, max_ticks=4):
            writer.write_block(block)
        world.commands(given)
        for block in world.blocks(10, max_ticks=6):
            writer.write_block(block)


def test_signed_zeros_in_commands_come_back_from_the_log_bit_for_bit(tmp_path):
    """0.0 and -0.0 are equal (one dict key), but a command's -0.0 is recorded as it is, and the
    timeline, which holds a value many commands give once, gives each command its own zero back:
    the log replays bit for bit."""
    import struct
    given = [("s", t, (a, b, c), 0) for t in (0.0, -0.0) for a in (0.0, -0.0)
             for b in (-0.0, 0.0, 0.5) for c in (0.0, -0.0)] * 2
    path = tmp_path / "zeros.mcap"
    _log_of_commands(path, given)

    def bits(throttle, rcs):
        return struct.pack("<4d", throttle, *rcs)
    with LogReader(path) as r:
        got = r.timeline().commands
    assert [bits(c.throttle, c.rcs) for c in got] == [bits(t, v) for _s, t, v, _h in given]
    assert len({bits(c.throttle, c.rcs) for c in got}) == 24
    r = invoke("replay", path, "--verify")
    assert r.exit_code == 0 and "identical" in r.output, r.output


@pytest.mark.parametrize("refused_first", [False, True])
def test_a_command_batch_damaged_in_its_second_megabyte_says_so_as_before(tmp_path,
                                                                           refused_first):
    """A batch over 1 MB is parsed a megabyte at a time; damage in its second piece (a ship id
    that is not UTF-8, 1.5 MB into a 2.2 MB batch of 45,000 commands) is said as when the batch
    was parsed whole: one line naming the file, "damaged command record (DecodeError)", even
    when a command of the first piece is out of range (the damage is said, not the range)."""
    import struct

    from touchdown.logs import LogError
    src = tmp_path / "commands.mcap"
    _commands_log(src, 45_000, 8, keyframe_interval=2)
    spots = []

    def edit(topic, data):
        if topic == "/touchdown/commands" and len(data) > 2_000_000:
            data = bytearray(data)
            at = data.index(b"s" * 8, 1_500_000)
            data[at] = 0xFF  # (a ship id not UTF-8: only the full parse of its command sees it)
            if refused_first:
                half = struct.pack("<d", 0.5)
                throttle = data.index(b"\x19" + half, 1000) + 1
                data[throttle:throttle + 8] = struct.pack("<d", 2.0)
            spots.append((len(data), at))
            data = bytes(data)
        return [(topic, data)]
    path = rewrite(src, tmp_path / "damaged.mcap", edit)
    assert spots and spots[0][0] > 2_000_000 and 1 << 20 < spots[0][1] < 2 << 20, spots
    with LogReader(path) as r, pytest.raises(LogError) as err:
        r.timeline()
    assert str(err.value) == f"{path}: damaged command record (DecodeError)", str(err.value)
    assert_refused(invoke("replay", path, "--verify"), path.name,
                   "damaged command record (DecodeError)")


@pytest.mark.parametrize("framing", FRAMINGS)
def test_a_commands_bomb_ending_the_header_s_chunk_is_refused_at_its_first_piece(
        bounce, tmp_path, framing):
    """The header's chunk ending in a message of 200 MiB of zeros on the commands' channel
    (size and CRC true): a tick's commands may run past the fleet's bound, but each field of
    the batch is checked as it is inflated, so the zeros are refused at their first piece
    (verify's peak RSS grows < 5 MiB), with one line naming the file."""
    scn = fuzz._scenario_msg_of(bounce.read_bytes())
    path = tmp_path / f"header-commands-{framing}.mcap"
    path.write_bytes(fuzz._crafted_log(scn, fuzz._chunk(b""), framing,
                                       first=fuzz.header_chunk(scn, 200 << 20, commands=True)))
    before, grew_mib, said = read_in_a_fresh_process(path, "verify")
    print(f"{framing}: verify took the peak RSS from {before:.1f} MiB up by {grew_mib:.1f} MiB "
          f"({said})")
    assert grew_mib < 5, (grew_mib, said)
    assert said.startswith(str(path)) and "damaged command record (field 0" in said, said
    assert_refused(invoke("replay", path, "--verify"), path.name, "damaged command record")


@pytest.mark.parametrize("compression", ["zstd-streamed", "zstd-whole", ""])
@pytest.mark.parametrize("framing", ["indexed", "unindexed", "walked"])
def test_a_header_s_chunk_with_a_flipped_byte_is_reported_damaged_on_opening(
        bounce, tmp_path, framing, compression):
    """The header is read from its chunk as a stream, stopping after it (a chunk over 1 MiB:
    here 1.08 MiB, within the 1.26 MiB a chunk of the header's one ship may hold): the chunk is
    then read in full (its CRC checked) within what a chunk of the log can hold. A byte flipped
    after the header, where zstd stores random bytes as they are (the frame decodes, a byte of
    the records differs), is found by the CRC. A smaller chunk (300 kB) is read whole at once."""
    import random
    import zlib

    from touchdown.logs import LogError
    scn = fuzz._scenario_msg_of(bounce.read_bytes())
    rng = random.Random(7)
    if compression.startswith("zstd"):
        after = (1 << 20) + (64 << 10) if compression == "zstd-streamed" else 300 << 10
        first = bytearray(fuzz.header_chunk(scn, after, rng))
    else:
        records = fuzz._header_records(scn) + fuzz._rec(0x80, rng.randbytes(4096))
        first = bytearray(fuzz._chunk(records, crc=zlib.crc32(records)))
    path = tmp_path / "sound.mcap"
    path.write_bytes(fuzz._crafted_log(scn, fuzz._chunk(b""), framing, first=bytes(first)))
    LogReader(path).close()
    first[-10] ^= 0x01
    path = tmp_path / "flipped.mcap"
    path.write_bytes(fuzz._crafted_log(scn, fuzz._chunk(b""), framing, first=bytes(first)))
    with pytest.raises(LogError, match="CRC does not match"):
        LogReader(path)


@pytest.mark.parametrize("framing", ["indexed", "walked"])
def test_a_flipped_header_chunk_over_the_header_s_bound_is_damage_at_the_first_read(
        bounce, tmp_path, framing):
    """A header chunk over what the header's one ship fills (3 MiB: ships may join within it
    from format 3) is checked once the fleet is known: opening reads the header only, the first
    read of the log's records finds the flipped byte."""
    import random

    from touchdown.logs import LogError
    scn = fuzz._scenario_msg_of(bounce.read_bytes())
    first = bytearray(fuzz.header_chunk(scn, 3 << 20, random.Random(3)))
    first[-10] ^= 0x01
    path = tmp_path / "flipped.mcap"
    path.write_bytes(fuzz._crafted_log(scn, fuzz._chunk(b""), framing, first=bytes(first)))
    for read in (lambda r: list(r.ticks()), lambda r: r.read_summary(),
                 lambda r: list(r.raw("/touchdown/ticks"))):
        with LogReader(path) as r, pytest.raises(LogError, match="CRC does not match|damaged"):
            read(r)


def test_the_read_limits_are_settings(bounce):
    env = {**os.environ, "TOUCHDOWN_MAX_CHUNK_MIB": "0.001"}
    r = subprocess.run([sys.executable, str(ROOT / "cli.py"), "replay", str(bounce), "--verify"],
                       capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 2 and "TOUCHDOWN_MAX_CHUNK_MIB" in r.stderr, r.stderr
    env["TOUCHDOWN_MAX_CHUNK_MIB"] = "lots"
    r = subprocess.run([sys.executable, str(ROOT / "cli.py"), "export", str(bounce)],
                       capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 2 and r.stderr.strip() == (
        "touchdown: TOUCHDOWN_MAX_CHUNK_MIB='lots': must be a positive number"), r.stderr


def test_a_chunk_index_outside_the_data_is_damage_said_plainly_and_a_redeclared_channel_refused(
        bounce, tmp_path):
    """The summary is damaged (its CRC, and a chunk index pointing past the data), the data
    section whole: the content is read by walking it, verifies, and the damage is one line."""
    data = bytearray(bounce.read_bytes())
    for off, op, _ in fuzz._records_of(bytes(data)):
        if op == 0x08:  # ChunkIndex: start, end, chunk_start_offset, chunk_length
            data[off + 9 + 24:off + 9 + 32] = (1 << 40).to_bytes(8, "little")
            break
    bad = tmp_path / "index.mcap"
    bad.write_bytes(bytes(data))
    r = invoke("replay", bad, "--verify")
    assert r.exit_code == 0 and "identical" in r.output, r.output
    assert "note: the log's structure is damaged: summary" in r.output
    import random
    redeclared = tmp_path / "channel.mcap"
    redeclared.write_bytes(fuzz._mutate_channel(bounce.read_bytes(), random.Random(0), 2))
    assert_refused(invoke("replay", redeclared, "--verify"), "is declared as")


# -- the scenario inside a log ---------------------------------------------------------------------
def _with_mass(resolved_json: str, text: str) -> str:
    """The resolved scenario with the first ship's mass written as ``text`` (any JSON number)."""
    doc = json.loads(resolved_json)
    doc["ships"][0]["mass"] = 123456.789
    out = json.dumps(doc)
    assert out.count("123456.789") == 1
    return out.replace("123456.789", text)


@pytest.mark.parametrize("change,needle", [
    (lambda rec: setattr(rec, "resolved_json", "[" * 100_000 + "]" * 100_000), "nested too deeply"),
    (lambda rec: setattr(rec, "resolved_json", _with_mass(rec.resolved_json, "9" * 5000)),
     "4300 digits"),
    (lambda rec: setattr(rec, "dt_s", float("nan")), "dt_s nan"),
    (lambda rec: setattr(rec, "dt_s", 1e300), "dt_s 1e+300"),
    (lambda rec: setattr(rec, "keyframe_interval", (1 << 31) - 1), "keyframe_interval"),
    (lambda rec: setattr(rec, "n_ticks", 10 ** 12), "disagrees with its own scenario"),
    (lambda rec: setattr(rec, "log_format_version", 99), "log format 99"),
])
def test_a_damaged_scenario_record_is_refused(bounce, tmp_path, change, needle):
    bad = with_record(bounce, tmp_path / "bad.mcap", change)
    assert_refused(invoke("replay", bad, "--verify"), "bad.mcap", needle)
    assert_refused(invoke("export", bad), "bad.mcap", needle)


@pytest.mark.parametrize("key,value", [("ships[0].mass", 1e308), ("ships[0].com_height", 1e308),
                                       ("body.radius", 1e308), ("sim.max_substep", 1e-300),
                                       ("contact.stiffness_per_kg", 1e308)])
def test_a_log_s_scenario_passes_the_same_rules_with_the_same_message(bounce, tmp_path, key,
                                                                       value):
    said_by_record = assert_refused(invoke("record", "bounce", "--set", f"{key}={value!r}", "-o",
                                           tmp_path / "x.mcap"))
    assert said_by_record.startswith(f"touchdown: bounce: {key}: ")
    problem = said_by_record.removeprefix("touchdown: bounce: ")

    def change(rec):
        doc = json.loads(rec.resolved_json)
        node, parts = doc, key.replace("[0]", ".0").split(".")
        for part in parts[:-1]:
            node = node[int(part)] if part.isdigit() else node[part]
        node[parts[-1]] = value
        rec.resolved_json = json.dumps(doc)
    bad = with_record(bounce, tmp_path / "bad.mcap", change)
    for cmd in (("replay", bad, "--verify"), ("export", bad), ("replay", bad, "--set",
                                                               "sim.dt=0.05")):
        line = assert_refused(invoke(*cmd))
        assert line == f"touchdown: {bad}: {problem}", line


# -- scenarios: every value is checked before anything runs --------------------------------------
@pytest.mark.parametrize("sets,key", [
    (["sim.dt=1e-308"], "sim.dt"), (["sim.dt=nan"], "sim.dt"), (["duration=1e300"], "duration"),
    (["sim.max_substep=1e-300"], "sim.max_substep"),
    (["sim.impact_substep=1e-308"], "sim.impact_substep"),
    (["sim.coarse_substep=1e-308"], "sim.coarse_substep"),
    (["sim.integrator=explicit_euler", "contact.damping_ratio=0",
      "contact.absorb_damping_ratio=0"], "sim.integrator"),
    (["contact.crash_speed=1e308"], "contact.crash_speed"),
    (["contact.settle_linear_vel=1e308"], "contact.settle_linear_vel"),
    (["contact.settle_angular_vel=1e308"], "contact.settle_angular_vel"),
    (["contact.stiffness_per_kg=1e308"], "contact.stiffness_per_kg"),
    (["ships[0].leg_radius=1e308"], "ships[0].leg_radius"),
    (["ships[0].mass=1e308"], "ships[0].mass"), (["ships[0].com_height=1e308"], "ships[0].com_height"),
    (["ships[0].inputs=[{t = 1e308, throttle = 1.0}]"], "ships[0].inputs[0].t"),
    (["body.radius=1e-308"], "body.radius"), (["body.radius=1e308"], "body.radius"),
    (["body.gm=1e308"], "body.gm"), (["body.surface_gravity=1e308", "body.gm=false"], "body."),
    (["body.rotation_period=1e-308"], "body.rotation_period"),
    (["ships[0].mass=" + "9" * 400], "ships[0].mass"),
    (["ships[0].mass=" + "9" * 5000], "ships[0].mass"),
    (["ships[0].inertia=[1, 1, 100]"], "ships[0].inertia"),
    (["body.terrain.bumps=[{radius = 1e-308, height = 1.0}]"], "body.terrain.bumps[0].radius"),
])
def test_a_hostile_value_is_refused_naming_its_key(tmp_path, sets, key):
    out = tmp_path / "x.mcap"
    args = [a for s in sets for a in ("--set", s)]
    assert_refused(invoke("record", "bounce", *args, "-o", out), key)
    assert not out.exists() and not Path(f"{out}.partial").exists()


@pytest.mark.parametrize("text,needle", [
    ("x = " + "[" * 1000 + "]" * 1000, "nested too deeply"),
    ("x = " + "{a=" * 1000 + "1" + "}" * 1000, "nested too deeply"),
    ('name = "n"\nduration = 1.0\n[' + "a." * 999 + "a]\nb = 1\n", "a: unknown key"),
    ('name = "n"\nduration = ' + "9" * 5000 + "\n", "4300 digits"),
])
def test_a_hostile_scenario_file_is_one_line(tmp_path, text, needle):
    path = tmp_path / "hostile.toml"
    path.write_text(text)
    assert_refused(invoke("record", path, "-o", tmp_path / "x.mcap"), "hostile.toml", needle)
    # the same file with a --set (which copies the document before applying it)
    assert_refused(invoke("record", path, "--set", "sim.dt=0.05", "-o", tmp_path / "x.mcap"),
                   "hostile.toml")


# -- verify compares all it can re-derive, and says what it did not ---------------------------------
def _events_changed(bounce, tmp_path, change):
    def edit(topic, data):
        if topic == "/touchdown/events":
            ev = pb.TransitionEvent.FromString(data)
            out = change(ev)
            return [] if out is None else [(topic, out.SerializeToString())]
        return [(topic, data)]
    return rewrite(bounce, tmp_path / "events.mcap", edit)


def _set(ev, **kw):
    for k, v in kw.items():
        setattr(ev, k, v)
    return ev


@pytest.mark.parametrize("change,field", [
    (lambda ev: _set(ev, to_state=(ev.to_state + 1) % 5), "event.to_state"),
    (lambda ev: _set(ev, ship_id="someone-else"), "event.ship_id"),
    (lambda ev: (ev.ship.position_m.__setattr__("z", ev.ship.position_m.z + 1e-9), ev)[1],
     "event.ship.position_m.z"),
    (lambda ev: None, "event"),
])
def test_an_altered_or_missing_event_is_a_divergence(bounce, tmp_path, change, field):
    bad = _events_changed(bounce, tmp_path, change)
    r = invoke("replay", bad, "--verify")
    assert r.exit_code == 1, r.output
    assert f"field {field}\n" in r.output and "DIVERGED at tick" in r.output, r.output


@pytest.mark.parametrize("change,field", [
    (lambda s: _set(s, event_count=s.event_count + 1), "summary.event_count"),
    (lambda s: _set(s, last_tick=s.last_tick - 1), "summary.last_tick"),
    (lambda s: _set(s, reason="made up"), "summary.reason"),
])
def test_an_altered_summary_is_a_divergence(bounce, tmp_path, change, field):
    def edit(topic, data):
        if topic == "/touchdown/summary":
            data = change(pb.LogSummary.FromString(data)).SerializeToString()
        return [(topic, data)]
    r = invoke("replay", rewrite(bounce, tmp_path / "s.mcap", edit), "--verify")
    assert r.exit_code == 1 and f"field {field}\n" in r.output, r.output


def test_a_whole_log_verifies_events_and_summary_too(bounce):
    r = invoke("replay", bounce, "--verify")
    assert r.exit_code == 0, r.output
    assert "2 event(s) and the summary compared bit for bit" in r.output
    assert "only part" not in r.output


def test_a_shortened_run_is_never_reported_as_the_whole(bounce, tmp_path):
    """The duration and tick count altered together (consistent with each other): the log now
    claims a longer run than it holds. Its summary says it was complete: a divergence."""
    def change(rec):
        doc = json.loads(rec.resolved_json)
        doc["duration"] *= 2
        rec.resolved_json = json.dumps(doc)
        rec.n_ticks *= 2
    bad = with_record(bounce, tmp_path / "longer.mcap", change)
    r = invoke("replay", bad, "--verify")
    assert r.exit_code == 1 and "field summary.complete" in r.output, r.output


def test_a_cut_log_says_what_it_checked_and_what_it_exported(tmp_path, fleet_log_20s):
    data = fleet_log_20s.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    r = invoke("replay", cut, "--verify")
    assert r.exit_code == 0, r.output
    k = int(r.output.split("identical: ticks 0..")[1].split(",")[0])
    assert 0 < k < 400
    assert (f"only part of the run was checked: the log ends at tick {k} of 400 (it was cut); "
            f"the events of tick {k} may have been lost") in r.output
    r = invoke("export", cut, "-o", tmp_path / "cut.jsonl")
    assert r.exit_code == 0
    assert "read only part of the log" in r.stderr and f"exported ticks 0..{k} of 400" in r.stderr
    rows = (tmp_path / "cut.jsonl").read_text().splitlines()
    assert json.loads(rows[-1])["tick"] == k and len(rows) == 6 * (k + 1)


def test_export_of_a_non_finite_number_is_refused_not_written_as_nan(bounce, tmp_path):
    from touchdown.logs.codec import encode_tick
    from touchdown.logs.decode import decode_tick

    def edit(topic, data):
        if topic == "/touchdown/ticks":
            tick, t_s, n, arrays = decode_tick(data)
            if tick == 3:
                arrays["normal_force_n"] = arrays["normal_force_n"].copy()
                arrays["normal_force_n"][0] = float("nan")
            data = encode_tick(tick, t_s, n, arrays)
        return [(topic, data)]
    bad = rewrite(bounce, tmp_path / "nan.mcap", edit)
    out = tmp_path / "nan.jsonl"
    assert_refused(invoke("export", bad, "-o", out), "tick 3", "normal_force is nan")
    assert not out.exists() and not Path(f"{out}.partial").exists()
    r = invoke("replay", bad, "--verify")
    assert r.exit_code == 1 and "field normal_force_n" in r.output


def test_numbers_that_overflow_in_export_give_one_line_not_numpy_warnings(bounce, tmp_path):
    """A position of 1e308 overflows the energy's squares: a fresh process (numpy warns once per
    process) must still print the one line naming the field, and nothing else."""
    from touchdown.logs.codec import encode_tick
    from touchdown.logs.decode import decode_tick

    def edit(topic, data):
        if topic == "/touchdown/ticks":
            tick, t_s, n, arrays = decode_tick(data)
            if tick == 2:
                arrays["pos_m"] = arrays["pos_m"].copy()
                arrays["pos_m"][1] = 1e308
            data = encode_tick(tick, t_s, n, arrays)
        return [(topic, data)]
    bad = rewrite(bounce, tmp_path / "huge.mcap", edit)
    r = subprocess.run([sys.executable, str(ROOT / "cli.py"), "export", str(bad), "-o",
                        str(tmp_path / "huge.jsonl")], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "tick 2, ship lander-1" in r.stderr and "(the log is damaged)" in r.stderr, r.stderr


# -- nothing half-written ------------------------------------------------------------------------
def _with_file_size_limit(argv, limit_bytes, cwd):
    """Run the CLI with the kernel refusing writes past ``limit_bytes`` (RLIMIT_FSIZE: write()
    fails with EFBIG, as it fails with ENOSPC on a full disk; Python ignores SIGXFSZ)."""
    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))
    return subprocess.run([sys.executable, str(ROOT / "cli.py"), *map(str, argv)], cwd=cwd,
                          preexec_fn=limit, capture_output=True, text=True, timeout=300)


@pytest.mark.slow
def test_a_full_disk_leaves_no_file_and_says_so(tmp_path):
    out = tmp_path / "full.mcap"
    r = _with_file_size_limit(["record", "fleet", "--set", "duration=60", "-o", out], 150_000,
                              tmp_path)
    assert r.returncode == 1, r.stderr
    assert r.stderr.strip() == (f"touchdown: {out}: cannot write: File too large; nothing was "
                                f"kept (no {out})"), r.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_an_export_or_what_if_that_cannot_be_written_leaves_nothing(tmp_path):
    log = tmp_path / "fleet.mcap"
    assert invoke("record", "fleet", "--set", "duration=60", "-o", log).exit_code == 0
    size = log.stat().st_size
    for argv, out in ((["export", log, "-o", tmp_path / "x.jsonl"], tmp_path / "x.jsonl"),
                      (["replay", log, "--set", "sim.dt=0.025", "-o", tmp_path / "w.mcap"],
                       tmp_path / "w.mcap")):
        r = _with_file_size_limit(argv, size // 2, tmp_path)
        assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1 and "nothing was kept" in r.stderr
        assert sorted(p.name for p in tmp_path.iterdir()) == ["fleet.mcap"], r.stderr


def _record_then_interrupt(tmp_path, n_signals, gap_s):
    """A slow-ticking run (3,000 ships) interrupted by n Ctrl-C, gap_s apart."""
    scn = tmp_path / "many.toml"
    scn.write_text('name = "many"\nduration = 100000.0\n' + "".join(
        f'[[ships]]\nid = "s{i}"\n[ships.initial]\naltitude = 5.0\nvertical_speed = -3.0\n'
        f"east = {30.0 * i}\n" for i in range(3000)))
    out = tmp_path / "many.mcap"
    partial = Path(f"{out}.partial")
    proc = subprocess.Popen([sys.executable, str(ROOT / "cli.py"), "record", str(scn), "-o",
                             str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not (partial.exists() and partial.stat().st_size > 0):
        time.sleep(0.05)
    time.sleep(0.5)
    for _ in range(n_signals):
        proc.send_signal(signal.SIGINT)
        time.sleep(gap_s)
    _, err = proc.communicate(timeout=120)
    return proc.returncode, err, out, partial


@pytest.mark.slow
@pytest.mark.parametrize("n_signals,gap_s", [(2, 0.002), (3, 0.0003)])
def test_repeated_ctrl_c_gives_exit_130_and_a_finished_log_or_none(tmp_path, n_signals, gap_s):
    """The first Ctrl-C asks the run to finish after the tick in hand; one more before it has
    finished stops at once and removes the partial file; any more are ignored while finishing or
    cleaning up. Which of the two happens depends on where in a tick the second one lands; either
    way the exit status is 130, no .partial is left, and stderr says which."""
    code, err, out, partial = _record_then_interrupt(tmp_path, n_signals, gap_s)
    assert code == 130 and "Traceback" not in err, err
    assert not partial.exists()
    if out.exists():
        assert "and is finished" in err, err
        with LogReader(out) as reader:
            assert reader.status.complete and reader.read_summary().reason == "interrupted"
    else:
        assert err.strip() == f"interrupted twice: stopped at once; nothing was kept (no {out})"
