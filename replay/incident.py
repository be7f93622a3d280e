"""``touchdown incident LOG [LOG ...] --ship ID --around TICK``: a standalone log of one ship
around an incident, cut from a run's log (or its rotated files).

The cut is re-run, never copied: it starts from the recording's keyframe at or before the
window's first tick (that tick's record, the ship's row of it, as recorded), and every later tick
is the fold verify does for one ship (``replay --verify --ship``): the ship's recorded joins,
leaves and commands, stepped alone. Each tick and each of the ship's events is compared with the
recording, bit for bit, before it is kept; the first difference refuses the cut (nothing is
written). So the cut holds only numbers the recording holds, or numbers a replay of it re-derives
identically (the keyframe-only fields between the recording's keyframes are not written: the cut
has the same keyframe ticks), and ``touchdown replay OUT --verify`` passes on it.

The logs given (files, or directories of rotated files) are one run's (a live shard's files of
several takes: each only up to where a later take went on, logs.shards): the file whose first tick
is the latest at or before the window's start holds its start, and the window goes on into the
file that continues it (whose first tick is at or before the last tick of the one before), as
far as the files go. The window is clipped to what they hold, and to the ship's time in the
fleet: a ship that leaves ends the cut at its last tick; one that joins later is in the cut from
the tick it joins (the cut's first ticks then hold no ship).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from touchdown.logs import LogError
from touchdown.logs.encode_events import event_messages
from touchdown.logs.header import TOPIC_EVENTS, tick_arrays, world_header
from touchdown.logs.reader import LogReader
from touchdown.logs.rebuild import keyframe_world, scenario_of
from touchdown.logs.shards import shard_file, world_until
from touchdown.logs.writer import LogWriter
from touchdown.proto import touchdown_pb2 as pb
from touchdown.sim.errors import TouchdownError
from touchdown.replay.verify import WIDTH, first_difference
from touchdown.sim.scenario import ScenarioError
from touchdown.sim.timeline import CommandError, Timeline
from touchdown.sim.world import Block, World


class Diverged(TouchdownError):
    """The recording differs from its re-run: nothing was cut. ``str()``: one line; exit 1."""

    exit_code = 1


@dataclass
class Segment:
    """One file of the run: its reader, its first and last tick, and the ticks the cut takes
    from it (``lo..hi``)."""

    reader: LogReader
    first: int
    last: int
    lo: int = 0
    hi: int = -1

    @property
    def name(self) -> str:
        return str(self.reader.path)


@dataclass
class Cut:
    out: Path
    ship_id: str
    around: int
    first_tick: int
    last_tick: int
    dt_s: float
    sources: list[str]
    events: int = 0
    ticks: int = 0
    notes: list[str] = field(default_factory=list)

    def report(self) -> str:
        lines = [f"{self.out}: ship {self.ship_id}, ticks {self.first_tick}..{self.last_tick} "
                 f"(t = {self.first_tick * self.dt_s:.3f}..{self.last_tick * self.dt_s:.3f} s) "
                 f"around tick {self.around}, from {', '.join(self.sources)}; {self.ticks} tick(s) "
                 f"and {self.events} event(s) re-run and checked against the recording bit for "
                 f"bit"]
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)


def log_files(paths: list[str], exclude: Path | None = None) -> list[Path]:
    """The logs named: files, and the ``*.mcap`` files of directories."""
    out: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            found = sorted(f for f in p.glob("*.mcap") if f.is_file())
            if not found:
                raise LogError(f"{p}: no .mcap files in this directory")
            out += found
        elif p.exists():
            out.append(p)
        else:
            raise LogError(f"{p}: cannot open: no such file or directory")
    if exclude is not None:
        out = [p for p in out if p.resolve() != exclude.resolve()]
    if not out:
        raise LogError(f"{', '.join(paths)}: no log besides the output")
    return out


def _last_tick(reader: LogReader) -> int:
    """The last tick a file holds: its summary's, or (no summary: cut) its last tick record's."""
    summary = reader.read_summary() if reader.status.complete else None
    if summary is not None:
        return int(summary.last_tick)
    last = -1
    for td in reader.ticks():
        last = td.tick_from_time
    return last


def _world_segments(readers: list[LogReader]) -> tuple[list[Segment], list[str]]:
    """The files as segments of the world's run, by first tick: a live shard's file read only up
    to its ``superseded_after_tick`` and to the first tick of a later take of its shard
    (logs.shards: what it holds after that is a history the world did not keep); a file with
    nothing of the world's left out. And a note for each file so clipped."""
    until = world_until(shard_file(r, r) for r in readers)
    segs, notes = [], []
    for r in readers:
        last = _last_tick(r)
        end = until[r] - 1
        if end < last:
            notes.append(f"{r.path}: its ticks after {end} are superseded (its shard went on "
                         f"from there: logs.shards)")
            last = int(end)
        if last >= r.start_tick:
            segs.append(Segment(r, r.start_tick, last))
    return sorted(segs, key=lambda s: s.first), notes


def incident(paths: list[str], ship_id: str, around: int, before_s: float, after_s: float,
             out: str | Path) -> Cut:
    """Cut ship ``ship_id``'s ticks ``around - before .. around + after`` (seconds, as ticks of
    the run's dt, clipped to what the logs hold) from the logs ``paths`` into the log ``out``.
    LogError: bad input (one line); Diverged: the recording differs from its re-run."""
    out = Path(out)
    readers = []
    try:
        for p in log_files(paths, out):
            readers.append(LogReader(p))
        return _cut(readers, ship_id, around, before_s, after_s, out)
    finally:
        for r in readers:
            r.close()


def _cut(readers: list[LogReader], ship_id: str, around: int, before_s: float, after_s: float,
         out: Path) -> Cut:
    base = readers[0]
    sr = base.scenario
    for r in readers[1:]:
        s = r.scenario
        if (s.dt_s, s.integrator, s.body, s.keyframe_interval, s.keyframe_phase) != (
                sr.dt_s, sr.integrator, sr.body, sr.keyframe_interval, sr.keyframe_phase):
            raise LogError(f"{r.path}: not of the same run as {base.path} (tick, method, body or "
                           f"keyframes differ)")
        if r.log_format < 3:
            raise LogError(f"{r.path}: log format {r.log_format}: an incident cut needs format 3 "
                           f"(recorded commands)")
    if base.log_format < 3:
        raise LogError(f"{base.path}: log format {base.log_format}: an incident cut needs format "
                       f"3 (recorded commands)")
    dt = sr.dt_s
    segs, notes = _world_segments(readers)
    if not segs:
        raise LogError(f"{base.path}: the logs hold no tick of the world's run (every file is "
                       f"superseded)")
    for a, b in zip(segs, segs[1:]):
        if a.first == b.first:
            raise LogError(f"{a.name} and {b.name} both start at tick {a.first}: give the files "
                           f"of one run")
    if not any(ship_id in s.reader.ship_table() for s in segs):
        ids = sorted({sid for s in segs for sid in s.reader.ship_table().ids})
        raise LogError(f"{', '.join(s.name for s in segs)}: no ship {ship_id!r} in "
                       f"{'this log' if len(segs) == 1 else 'these logs'} (ships: "
                       f"{', '.join(ids[:20])}{', ...' if len(ids) > 20 else ''})")
    lo = around - int(math.floor(before_s / dt + 0.5))
    hi = around + int(math.floor(after_s / dt + 0.5))
    held_from, held_to = segs[0].first, max(s.last for s in segs)
    if hi < held_from or lo > held_to or around < held_from or around > held_to:
        raise LogError(f"--around {around}: the log{'s hold' if len(segs) > 1 else ' holds'} "
                       f"ticks {held_from}..{held_to}")
    if lo < held_from:
        notes.append(f"the window's start, tick {lo}, is before the logs' first tick "
                     f"{held_from}: clipped")
        lo = held_from
    # the file holding the window's start, then the files continuing it
    start = max(i for i, s in enumerate(segs) if s.first <= lo)
    if segs[start].last < lo:
        raise LogError(f"--around {around}: no log holds tick {lo}, the window's start "
                       f"({segs[start].name} ends at tick {segs[start].last})")
    chain = [segs[start]]
    chain[0].lo = segs[start].reader.keyframe_at_or_before(lo)
    chain[0].hi = min(hi, chain[0].last)
    while chain[-1].hi < hi:
        prev = chain[-1]
        nxt = [s for s in segs if prev.first < s.first <= prev.last and s.last > prev.last]
        if not nxt:
            notes.append(f"the logs hold no tick after {prev.last} continuing {prev.name}: the "
                         f"cut ends there")
            break
        seg = max(nxt, key=lambda s: s.last)
        seg.lo, seg.hi = prev.hi + 1, min(hi, seg.last)
        chain.append(seg)
    if len(chain) > 1:
        notes.append(f"the window spans {len(chain)} files: {', '.join(s.name for s in chain)}")
    first = chain[0]
    reader = first.reader
    scn, _ = scenario_of(reader)
    ticks = reader.ticks(first.lo, first.hi)
    keyframe = next(ticks, None)
    if keyframe is None or keyframe.tick_from_time != first.lo or not keyframe.is_keyframe:
        raise LogError(f"{reader.path}: no keyframe at tick {first.lo} (the log is damaged)")
    world = keyframe_world(reader, scn, keyframe)
    key = reader.ship_table().key(ship_id) if ship_id in reader.ship_table() else None
    rows = np.flatnonzero(keyframe.keys == key) if key is not None else np.zeros(0, np.int64)
    keep = _mask(world.state.n, rows)
    world = world.select(keep, _timeline(chain, ship_id, first.lo))
    ends = [r.tick for r in world.timeline.retires]
    last_wanted = chain[-1].hi
    if ends and ends[0] - 1 < last_wanted:
        notes.append(f"ship {ship_id} leaves the fleet at tick {ends[0]}: the cut ends at its "
                     f"last tick, {ends[0] - 1}")
        last_wanted = ends[0] - 1
    if last_wanted <= first.lo:
        raise LogError(f"--around {around}: ship {ship_id} is in the logs at no tick after "
                       f"{first.lo} within the window")
    joins = [s.tick for s in world.timeline.spawns]
    if world.state.n == 0:
        if not joins or joins[0] > last_wanted:
            raise LogError(f"--around {around}: ship {ship_id} is not in the fleet within ticks "
                           f"{first.lo}..{last_wanted}")
        notes.append(f"ship {ship_id} joins the fleet at tick {joins[0]}: the cut's ticks "
                     f"{first.lo}..{joins[0] - 1} hold no ship")
    snapshot = World(world.scene, world.params, world.state, world.inputs, Timeline(),
                     dict(world.known))
    kf_outputs = keyframe.outputs().select(_mask(keyframe.ship_count, rows))
    blocks = [Block(first.lo, world.state.rows[None, :].copy(), kf_outputs.rows[None, :].copy(),
                    world.inputs.rows[None, :].copy(), [], world.ship_ids)]
    n_events = _rerun(world, chain, ship_id, last_wanted, blocks)
    last = blocks[-1].last_tick
    if last < last_wanted:
        notes.append(f"the recording ends at tick {last}")
    if last <= first.lo:
        raise LogError(f"{reader.path}: the recording holds nothing after tick {first.lo}")
    header = world_header(
        snapshot, f"{reader.scenario.name}: {ship_id} around tick {around}",
        f"{', '.join(s.name for s in chain)} (incident)", reader.keyframe_interval,
        description=f"ship {ship_id}, ticks {first.lo}..{last}, cut from {first.name}",
        end_tick=last, keyframe_phase=reader.keyframe_phase)
    with LogWriter(out, header) as writer:
        for b in blocks:
            writer.write_block(b)
    return Cut(out, ship_id, around, first.lo, last, dt, [s.name for s in chain], n_events,
               sum(len(b) for b in blocks), notes)


def _mask(n: int, rows: np.ndarray) -> np.ndarray:
    keep = np.zeros(n, dtype=bool)
    keep[rows] = True
    return keep


def _timeline(chain: list[Segment], ship_id: str, start: int) -> Timeline:
    """The ship's recorded joins, leaves and commands after ``start``, each from the file that
    holds the ticks it leads to (a file records only what comes after its first tick)."""
    spawns, retires, commands = [], [], []
    for i, seg in enumerate(chain):
        t = seg.reader.timeline().for_ship(ship_id)
        after = start if i == 0 else chain[i - 1].hi  # the ticks this file gives: after..hi
        spawns += [s for s in t.spawns if after < s.tick <= seg.hi]
        retires += [r for r in t.retires if after < r.tick <= seg.hi]
        commands += [c for c in t.commands if after <= c.tick < seg.hi]
    return Timeline.of(spawns, retires, commands)


def _recorded(chain: list[Segment]):
    """The recorded ticks the cut re-runs (after the keyframe), each with its file."""
    for i, seg in enumerate(chain):
        lo = seg.lo + 1 if i == 0 else seg.lo
        for b in seg.reader.blocks(lo, seg.hi):  # decoded a block at a time, compiled
            for k in range(b.ticks.shape[0]):
                yield seg, b.tick(k)


def _recorded_events(seg: Segment, ship_id: str, lo: int, hi: int) -> list[tuple[int, bytes]]:
    """(tick, message) of the ship's recorded events of ticks lo..hi in ``seg``."""
    r = seg.reader
    out = []
    if hi < lo:
        return out
    for _t, data in r.raw(TOPIC_EVENTS, r.tick_time_ns(lo), r.tick_time_ns(hi)):
        try:
            ev = pb.TransitionEvent.FromString(data)
        except Exception as exc:  # noqa: BLE001 - protobuf's DecodeError and friends
            raise LogError(f"{r.path}: damaged event record ({type(exc).__name__})") from None
        if ev.ship_id == ship_id:
            out.append((int(ev.tick), data))
    return out


def _rerun(world: World, chain: list[Segment], ship_id: str, last: int,
           blocks: list[Block]) -> int:
    """Step ``world`` (the ship alone) to ``last``, comparing each tick and event with the
    recording; append the checked blocks to ``blocks`` (a block the recording ends inside is cut
    at its last recorded tick). Returns the events kept. Diverged on the first difference."""
    # the ship's recorded events, read before the ticks are (a file is read by one pass at a time)
    theirs = {id(seg): _recorded_events(seg, ship_id, seg.lo + (i == 0), seg.hi)
              for i, seg in enumerate(chain)}
    recorded = _recorded(chain)
    n_events = 0
    try:
        for block in world.blocks(last):
            kept = 0
            seg_of: dict[int, Segment] = {}
            for rec in block.records():
                nxt = next(recorded, None)
                if nxt is None:
                    break
                seg, td = nxt
                if td.tick_from_time != rec.tick:
                    raise LogError(f"{seg.name}: tick records out of order (expected {rec.tick}, "
                                   f"found {td.tick_from_time})")
                _compare_tick(seg, td, rec, ship_id)
                seg_of[rec.tick] = seg
                kept += 1
            if kept == 0:
                break
            short = kept < len(block)
            if short:
                block = _head(block, kept)
            n_events += _compare_events(block, seg_of, ship_id, theirs)
            blocks.append(block)
            if short or block.last_tick >= last:
                break
    except (CommandError, ScenarioError) as exc:
        raise LogError(f"the log's recorded input cannot be replayed: {exc}") from None
    return n_events


def _compare_tick(seg: Segment, td, rec, ship_id: str) -> None:
    table = seg.reader.ship_table()
    key = table.key(ship_id) if ship_id in table else -1
    rows = np.flatnonzero(td.keys == key)
    where = f"{seg.name}: tick {td.tick_from_time}, ship {ship_id}"
    if rows.size != rec.state.n:
        raise Diverged(f"{where}: the recording has the ship {'in' if rows.size else 'out of'} "
                       f"the fleet, its re-run {'in' if rec.state.n else 'out of'} it; nothing "
                       f"was cut")
    if rows.size == 0:
        return
    arrays = tick_arrays(rec, np.array([key], np.int64))
    hit = first_difference(td.arrays, arrays, rows, 1)
    if hit is not None:
        _ship, name, comp, a, b = hit
        fld = f"{name}[{comp}]" if WIDTH.get(name, 1) > 1 else name
        raise Diverged(f"{where}, field {fld}: recorded {a!r}, re-run {b!r}: the recording "
                       f"diverges from its re-run; nothing was cut")


def _compare_events(block: Block, seg_of: dict, ship_id: str, recorded: dict) -> int:
    """The ship's events of the block's ticks, re-run and recorded, byte for byte."""
    n = 0
    by_seg: dict[int, list] = {}
    for tick in range(block.first_tick, block.last_tick + 1):
        by_seg.setdefault(id(seg_of[tick]), [seg_of[tick], tick, tick])[2] = tick
    mine = {}
    by_seg_events: dict[int, tuple] = {}
    for ev in block.events:
        seg = seg_of[ev.tick]
        by_seg_events.setdefault(id(seg), (seg, []))[1].append(ev)
    for k, (seg, evs) in by_seg_events.items():  # (each segment's events as its writer made them)
        sr = seg.reader.scenario
        mine[k] = event_messages(seg.reader.ship_table(), sr.body, sr.dt_s, block.states,
                                 block.first_tick, evs, log_format=seg.reader.log_format).datas
    for k, (seg, lo, hi) in by_seg.items():
        theirs = [data for tick, data in recorded[k] if lo <= tick <= hi]
        ours = mine.get(k, [])
        if theirs != ours:
            raise Diverged(f"{seg.name}: ticks {lo}..{hi}, ship {ship_id}: the recorded events "
                           f"({len(theirs)}) differ from the re-run's ({len(ours)}); nothing was "
                           f"cut")
        n += len(ours)
    return n


def _head(block: Block, k: int) -> Block:
    """The first ``k`` ticks of ``block``."""
    last = block.first_tick + k - 1
    return Block(block.first_tick, block.states[:k], block.outputs[:k], block.inputs[:k],
                 [e for e in block.events if e.tick <= last], block.ship_ids, block.spawned,
                 block.retired, tuple(c for c in block.commands if c.tick < last))


__all__ = ["incident", "Cut", "Diverged", "log_files"]
