"""``touchdown replay LOG --verify``: re-run a log from what it recorded and compare everything it
can re-derive, bit for bit, with today's code: every tick's numbers, every transition event
(re-encoded as the writer encodes it) and, when the whole run is checked, the summary.

The re-run is a fold of the step over the log's own records (sim.world): the ships of its header,
the ships that joined and left, and the commands, wherever they came from (a scenario, the Python
API, a live service). The scenario is only where they came from. A log of format 1 or 2, which
recorded no commands, replays its scenario's inputs instead, with a notice.

The log is self-sufficient: its ScenarioRecord holds the resolved scenario (every default filled in),
so no other file is read. A window ``first..last`` starts from the keyframe at or before ``first``.
The re-run is driven by the recorded ticks, so it does no more ticks than the log holds; a check of
less than the run (a cut log, a stopped run, a window) says so in its report.

A log that starts at a tick T > 0 (ScenarioRecord.start_tick: a rotated segment of a longer run,
a worker that took ships over, a cut around an incident) is re-run from its first tick record, a
keyframe of the header's ships, as a window is from its keyframe: that record is the start (its
state, and the commands in force), not re-derived; ticks T + 1 on, their events and the summary
are compared. A whole log's summary must say where the file ends and why: ``complete`` with reason
"" at the run's last tick (``n_ticks``; for an open-ended run, the last tick recorded), "rotated"
(the run goes on in the next file), "stopped" (a live run stopped), "handed over" or "lost" (a
live run goes on in another worker's log) at the last tick recorded; ``complete = false`` with
"interrupted", "stopped" or "recovered" (``touchdown recover``: the whole ticks of a cut or
damaged file) (REASONS).
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from touchdown.logs import LogError
from touchdown.logs.codec import PACKED
from touchdown.logs.encode_block import BlockEncoder
from touchdown.logs.encode_events import event_messages
from touchdown.logs.header import (KEYFRAME_ONLY, LOG_FORMAT_VERSION, TOPIC_EVENTS, TOPIC_SUMMARY,
                         ShipTable, tick_arrays)
from touchdown.logs.reader import LogReader
from touchdown.logs.rebuild import keyframe_world, recorded_world, scenario_of
from touchdown.proto import touchdown_pb2 as pb
from touchdown.sim import __version__ as PROJECT_VERSION
from touchdown.sim import fields
from touchdown.sim.scenario import Scenario, ScenarioError
from touchdown.sim.timeline import CommandError
from touchdown.sim.world import World

#: per-ship width of each packed field
WIDTH = {name: fields.per_ship(name) for _, name, _ in PACKED}
_EMPTY = np.zeros(0)


@dataclass
class Divergence:
    tick: int
    t_s: float
    ship_id: str
    field: str  # e.g. "vel_mps[2]", "event", "summary.event_count"
    recorded: float | str
    replayed: float | str


@dataclass
class VerifyResult:
    log_version: str
    log_method: str
    log_dt_s: float
    first_tick: int
    last_tick: int
    ships: list[str]
    ticks_compared: int = 0
    numbers_compared: int = 0
    divergence: Divergence | None = None
    recent_events: list[str] = field(default_factory=list)
    recovered_note: str = ""
    n_ticks: int = 0  # the run's last tick, as its scenario says
    events_compared: int = 0
    summary_compared: bool = False
    #: why less than the whole run was checked ("" when all of it was)
    partial_note: str = ""
    #: how the inputs were found, when not from the log's own records (an older format)
    inputs_note: str = ""
    #: the file's MCAP structure is damaged, its content read all the same (logs.structure)
    structure_note: str = ""
    #: a file rotated at its run's last tick: the whole run is here, and the next file repeats it
    segment_note: str = ""
    #: the whole file was read (not cut, nothing damaged in its way) and its summary says it
    #: is complete (LogSummary.complete): what --require-complete asks for
    file_complete: bool = False
    #: why file_complete is False ("" when it is)
    incomplete_why: str = ""

    @property
    def verified_whole(self) -> bool:
        """Identical, and the whole log, as its writer finished it, was checked."""
        return self.identical and self.file_complete

    @property
    def identical(self) -> bool:
        return self.divergence is None and self.ticks_compared > 0

    def report(self) -> str:
        head = (f"log: touchdown {self.log_version}, method {self.log_method}, dt {self.log_dt_s:g} s;"
                f" today: touchdown {PROJECT_VERSION}")
        lines = [head]
        if self.log_version != PROJECT_VERSION and self.divergence is None:
            lines.append(f"note: this log was written by touchdown {self.log_version}; "
                         f"{PROJECT_VERSION} re-runs it to the same bits")
        elif self.log_version != PROJECT_VERSION:
            lines.append(f"note: this log was written by touchdown {self.log_version}, whose physics "
                         f"differs from {PROJECT_VERSION}'s (docs/MODEL-NOTES.md), so a divergence is "
                         f"expected; `touchdown replay LOG -o NEW.mcap` re-runs its scenario and "
                         f"inputs under today's physics")
        if self.inputs_note:
            lines.append(self.inputs_note)
        if self.recovered_note:
            lines.append(self.recovered_note)
        if self.divergence is None:
            what = [f"{self.numbers_compared:,} numbers", f"{self.events_compared:,} event(s)"]
            if self.summary_compared:
                what.append("the summary")
            lines.append(f"identical: ticks {self.first_tick}..{self.last_tick}, "
                         f"{len(self.ships)} ship(s), {', '.join(what[:-1])} and {what[-1]} "
                         f"compared bit for bit")
            if self.partial_note:
                lines.append(f"only part of the run was checked: {self.partial_note}")
            if self.structure_note:
                lines.append(f"note: {self.structure_note}")
            if self.segment_note:
                lines.append(f"note: {self.segment_note}")
            return "\n".join(lines)
        d = self.divergence
        lines.append(f"DIVERGED at tick {d.tick} (t = {d.t_s:.4f} s), ship {d.ship_id}, "
                     f"field {d.field}")
        if isinstance(d.recorded, str) or isinstance(d.replayed, str):
            lines.append(f"  recorded {d.recorded}")
            lines.append(f"  replayed {d.replayed}")
            return "\n".join(lines)
        lines.append(f"  recorded {d.recorded!r}")
        lines.append(f"  replayed {d.replayed!r}  (difference {d.replayed - d.recorded:.3e})")
        if self.recent_events:
            lines.append("  last transitions of that ship before it:")
            lines += [f"    {e}" for e in self.recent_events]
        else:
            lines.append("  no transition of that ship before it")
        return "\n".join(lines)


def first_difference(rec_arrays: dict, new_arrays: dict, ship_slice, n_new: int,
                      older_format: bool = False):
    """(ship, field, component, recorded, replayed) of the first differing number, or None. In a
    log of an older format a field whose layout has changed since (``sliding``: one per ship in
    format 1, one per foot now) cannot be compared and is skipped."""
    best = None
    for _, name, _ in PACKED:
        w = WIDTH[name]
        if name not in rec_arrays:  # not on this tick (a field written on keyframes only)
            continue
        recorded = np.asarray(rec_arrays[name])
        replayed = np.asarray(new_arrays[name])
        if ship_slice is not None:
            recorded = recorded.reshape(-1, w)[ship_slice].ravel() if recorded.size else recorded
        replayed = replayed.reshape(n_new * w)
        if recorded.shape != replayed.shape:
            if older_format:
                continue
            return (0, name, 0, float("nan"), float("nan"))
        if replayed.dtype.kind == "f":
            diff = recorded.astype(np.float64).view(np.uint64) != replayed.view(np.uint64)
        else:
            diff = recorded.astype(np.int64) != replayed.astype(np.int64)
        hits = np.flatnonzero(diff)
        if hits.size:
            k = int(hits[0])
            cand = (k // w, name, k % w, float(recorded[k]), float(replayed[k]))
            if best is None or cand[0] < best[0]:
                best = cand
    return best


def verify(path: str, first: int | None = None, last: int | None = None,
           ship_id: str | None = None) -> VerifyResult:
    """Re-run the log (or the window ``first..last``, or one ship) and compare, in order: the
    ticks, the transition events, the summary. The first difference found is the divergence."""
    with LogReader(path) as reader:
        sr = reader.scenario
        scn, _ = scenario_of(reader)
        table = reader.ship_table()
        if ship_id is not None and ship_id not in table:
            raise LogError(f"{reader.path}: no ship {ship_id!r} in this log (ships: "
                           f"{', '.join(table.ids[:20])}{', ...' if len(table) > 20 else ''})")
        index = None if ship_id is None else table.key(ship_id)
        if reader.log_format >= 3:
            reader.timeline()  # read now, not between the tick records (a cut file: one pass)
        start = reader.start_tick
        window = first is not None and first > start
        # from the log's first tick (0, or its keyframe at start_tick), or from the nearest
        # keyframe at or before ``first``
        first = reader.keyframe_at_or_before(first) if window else (start or None)
        window = window and first > start
        n_ticks = _run_end(reader)
        res = VerifyResult(sr.project_version, sr.integrator, sr.dt_s, first or 0,
                           min(last, n_ticks) if last is not None else n_ticks,
                           [ship_id] if ship_id is not None else list(table.ids),
                           n_ticks=n_ticks)
        if reader.log_format < 3:
            res.inputs_note = (f"note: log format {reader.log_format} recorded inputs per tick, "
                               f"not commands: its scenario's inputs were replayed")
        target = res.last_tick
        replayed = _compare_ticks(reader, scn, table, ship_id, res, first)
        # a cut log may have lost the events of its last tick with the next chunk
        events_to = res.last_tick if reader.status.complete else res.last_tick - 1
        if res.divergence is None:
            _compare_events(reader, res, replayed, first, events_to, index)
        whole = not window and index is None and last is None and reader.status.complete
        if res.divergence is None and whole:
            _compare_summary(reader, res, len(replayed))
        _say_what_was_checked(reader, res, target, events_to)
        if whole:  # every chunk was read: the data section's CRC says if anything else changed
            reader.check_data_crc()
        res.structure_note = reader.structure_note()
        _say_if_complete(reader, res, not window and index is None and last is None)
        return res


#: an open-ended run cut before its summary: the re-run goes as far as the recorded ticks
UNBOUNDED = 1 << 62


def _run_end(reader: LogReader) -> int:
    """The run's last tick: its scenario's (n_ticks), or for an open-ended run (a live service)
    the summary's last tick (none: as far as the log goes)."""
    if not reader.open_ended:
        return int(reader.scenario.n_ticks)
    summary = reader.read_summary() if reader.status.complete else None
    return int(summary.last_tick) if summary is not None else UNBOUNDED


def _compare_ticks(reader: LogReader, scn: Scenario, table: ShipTable, ship_id: str | None,
                   res: VerifyResult, first: int | None) -> list[tuple[int, str, bytes]]:
    """Compare every recorded tick with its re-run; returns the re-run's events, each as
    (tick, ship id, the TransitionEvent as the writer encodes it)."""
    path, sr = reader.path, reader.scenario
    ticks = reader.ticks(first, res.last_tick)
    keyframe = None
    if first:
        try:
            keyframe = next(ticks)
        except StopIteration:
            raise LogError(f"{path}: no tick {first} in this log") from None
        if keyframe.tick_from_time != first or not keyframe.is_keyframe:
            raise LogError(f"{path}: no keyframe at tick {first} (the log's "
                           f"{'first tick' if first == reader.start_tick else 'keyframes'} "
                           f"should be one); found tick {keyframe.tick_from_time}")
        if first == reader.start_tick and not np.array_equal(
                keyframe.keys, np.arange(len(sr.ship_ids))):
            raise LogError(f"{path}: tick {first}, the log's first, does not hold its header's "
                           f"{len(sr.ship_ids)} ship(s) in order")
        res.ticks_compared += 1
    world = _world(reader, scn, table, ship_id, keyframe)
    interval = reader.keyframe_interval
    with_keys = reader.log_format >= 3
    encoder = BlockEncoder(sr.dt_s, KEYFRAME_ONLY, interval, with_keys=with_keys,
                           keyframe_phase=reader.keyframe_phase)
    sim = _replayed(world, res.last_tick, encoder, table if with_keys else None)
    events: list[tuple[int, str, bytes]] = []
    compared_to = first or 0
    mine_key = None if ship_id is None else table.key(ship_id)
    for recorded in ticks:
        # driven by the recorded ticks: the re-run does no more ticks than the log holds
        step = next(sim, None)
        if step is None:
            raise LogError(f"{path}: a tick record at tick {recorded.tick_from_time}, after the "
                           f"run's last tick {res.last_tick}")
        mine, new, keys = step
        if new.tick != recorded.tick_from_time:
            raise LogError(f"{path}: tick records out of order (expected {new.tick}, "
                           f"found {recorded.tick_from_time})")
        res.ticks_compared += 1
        compared_to = new.tick
        if new.events:  # (as the writer made them: logs.encode_events, or an older format's)
            made = event_messages(table, sr.body, sr.dt_s, new.state.rows, new.tick, new.events,
                                  log_format=reader.log_format)
            events += [(new.tick, ev.ship_id, data) for ev, data in zip(new.events, made.datas)]
        if ship_id is None:
            # the whole batch: the replayed tick, encoded as the writer encodes it, must be
            # the recorded message byte for byte; only a mismatch is decoded and diagnosed
            on_keyframe = reader.is_keyframe_tick(new.tick)
            res.numbers_compared += _numbers_in(new.state.n, on_keyframe)
            if mine == recorded.raw:
                continue
            arrays = tick_arrays(new, keys)
            if not on_keyframe:
                for name in KEYFRAME_ONLY:
                    arrays[name] = _EMPTY
            rows = None
        else:
            arrays = tick_arrays(new, keys)
            rows = np.flatnonzero(recorded.keys == mine_key)
            res.numbers_compared += sum(np.size(arrays[k]) for k in recorded.arrays)
        hit = first_difference(recorded.arrays, arrays, rows, new.state.n,
                                sr.log_format_version < LOG_FORMAT_VERSION)
        if hit is None and ship_id is None:  # same numbers, different bytes
            hit = (0, "tick", 0, float(recorded.tick), float(new.tick))
        if hit is not None:
            ship, name, comp, a, b = hit
            fld = f"{name}[{comp}]" if WIDTH.get(name, 1) > 1 else name
            who = ship_id if ship_id is not None else (
                table.ids[int(recorded.keys[ship])] if ship < recorded.keys.size else "(log)")
            res.divergence = Divergence(recorded.tick, recorded.t_s, who, fld, a, b)
            res.recent_events = [
                f"tick {e.tick}: {e.event} {_label(e.from_state)} -> {_label(e.to_state)}"
                for e in reader.events() if e.ship_id == who and e.tick <= recorded.tick
            ][-3:]
            break
    res.last_tick = compared_to
    if res.ticks_compared == 0:
        why = f": {reader.status.damage}" if reader.status.damage else ""
        raise LogError(f"{path}: no tick records to compare (the log ends before its first "
                       f"tick{why})")
    return events


def _world(reader: LogReader, scn: Scenario, table: ShipTable, ship_id: str | None,
           keyframe) -> World:
    """The world to re-run: the log's recorded joins, leaves and commands (format 3; before it,
    the scenario's), from tick 0 or from ``keyframe``'s state, all ships or ``ship_id`` alone."""
    world = recorded_world(reader, scn) if keyframe is None else \
        keyframe_world(reader, scn, keyframe)
    if ship_id is not None:
        keep = np.array([sid == ship_id for sid in world.ship_ids], dtype=bool)
        world = world.select(keep, world.timeline.for_ship(ship_id))
    return world


def _replayed(world: World, last_tick: int, encoder: BlockEncoder, table: ShipTable | None):
    """The re-run, tick by tick: (the tick encoded as the writer encodes it, its record, the
    ships' keys)."""
    blocks = world.blocks(last_tick, ramp=True)
    first = world.tick == 0
    if first:  # from the start: the tick-0 record is replayed too (a keyframe, as the first)
        blocks = itertools.chain([world.first_block()], blocks)
    try:
        for block in blocks:
            keys = None if table is None else table.keys(block.ship_ids)
            data, offsets = encoder.encode(block.first_tick, block.states, block.outputs,
                                           block.inputs, keys, first_keyframe=first)
            first = False
            view = memoryview(data)
            for k, rec in enumerate(block.records()):
                yield bytes(view[offsets[k]:offsets[k + 1]]), rec, keys
    except (CommandError, ScenarioError) as exc:
        raise LogError(f"the log's recorded input cannot be replayed: {exc}") from None


def _numbers_in(n_ships: int, keyframe: bool) -> int:
    """How many numbers a tick record of ``n_ships`` holds."""
    return n_ships * sum(WIDTH[name] for _, name, _ in PACKED
                         if keyframe or name not in KEYFRAME_ONLY)


def _compare_events(reader: LogReader, res: VerifyResult, replayed: list[tuple[int, str, bytes]],
                    first: int | None, to_tick: int, index: int | None) -> None:
    """The recorded transition events of ticks (first, to_tick] (one ship's, with --ship), in
    order, must be the re-run's byte for byte: none missing, none added, none altered."""
    lo = (first or -1) + 1  # a window's keyframe tick is read, not re-stepped
    if to_tick < lo:
        return
    mine = [e for e in replayed if lo <= e[0] <= to_tick]
    k = 0
    for t_ns, data in reader.raw(TOPIC_EVENTS, reader.tick_time_ns(lo), reader.tick_time_ns(to_tick)):
        if index is not None and _event(reader, data).ship_id != res.ships[0]:
            continue
        if k >= len(mine) or mine[k][2] != data:
            _event_divergence(reader, res, data, mine[k][2] if k < len(mine) else None)
            return
        k += 1
    if k < len(mine):
        _event_divergence(reader, res, None, mine[k][2])
        return
    res.events_compared = k


#: why a file ends where it does (LogSummary.reason), by its ``complete``: "" the run's end;
#: "rotated" the run goes on in the next file; "stopped" a live run was stopped (finished, or
#: not); "handed over", "lost" a live run's ships go on in another worker's log (touchdown
#: serve); "interrupted" Ctrl-C before the end; "recovered" the whole ticks of a cut or damaged
#: file, rewritten by ``touchdown recover``
REASONS = {True: ("", "rotated", "stopped", "handed over", "lost"),
           False: ("interrupted", "stopped", "recovered")}


def _compare_summary(reader: LogReader, res: VerifyResult, n_events: int) -> None:
    """The summary of a whole log: its last tick is the last tick recorded, its event count the
    re-run's, and its reason one the writers give for its ``complete`` (REASONS); ``complete``
    with no reason only at the run's last tick (an open-ended run's is the summary's own)."""
    where = lambda f, a, b: Divergence(res.last_tick, res.last_tick * res.log_dt_s, "(log)",  # noqa: E731
                                       f"summary.{f}" if f else "summary", a, b)
    found = [data for _t, data in reader.raw(TOPIC_SUMMARY)]
    if len(found) != 1:
        res.divergence = where("", f"{len(found)} summary records", "one")
        return
    rec = _decode(reader, pb.LogSummary, found[0], "summary")
    known = REASONS[rec.complete]
    mine = pb.LogSummary(last_tick=res.last_tick, complete=rec.complete,
                         reason=rec.reason if rec.reason in known else known[0],
                         event_count=n_events)
    if rec.HasField("superseded_after_tick") and rec.reason == "lost" and \
            rec.superseded_after_tick <= res.last_tick:  # a lost shard's (touchdown serve)
        mine.superseded_after_tick = rec.superseded_after_tick
    if rec.complete and not rec.reason and res.last_tick != res.n_ticks:
        res.divergence = where("complete", "true", f"false (the log ends at tick {res.last_tick} "
                                                   f"of {res.n_ticks})")
    elif mine.SerializeToString() != found[0]:
        name = _first_field(rec, mine) or "bytes"
        res.divergence = where(name, str(getattr(rec, name, "")), str(getattr(mine, name, "")))
    else:
        res.summary_compared = True


def _say_what_was_checked(reader: LogReader, res: VerifyResult, target: int, events_to: int) -> None:
    if not reader.status.complete:
        res.recovered_note = (
            f"the log ends without a footer (cut, or its writer was killed): recovered "
            f"{res.ticks_compared} tick(s), {res.first_tick}..{res.last_tick}"
            + (f"; the rest is damaged ({reader.status.damage})" if reader.status.damage
               else ""))
    if res.divergence is not None:
        return
    gaps = []
    if res.last_tick < target:
        summary = reader.read_summary() if reader.status.complete else None
        stopped = summary is not None and (not summary.complete or summary.reason in (
            "stopped", "handed over", "lost"))
        rotated = summary is not None and summary.complete and summary.reason == "rotated"
        why = ("it was cut" if not reader.status.complete else
               "it is one file of a longer run: the run goes on in the next file (rotated)"
               if rotated else
               "it was recovered from a cut or damaged file: `touchdown recover` kept its "
               "whole ticks" if summary is not None and summary.reason == "recovered" else
               f"its run was stopped: {summary.reason or 'no reason given'}" if stopped
               else "it holds no more")
        of = "" if target >= UNBOUNDED else f" of {target}"
        gaps.append(f"the log ends at tick {res.last_tick}{of} ({why})")
    elif reader.status.complete:
        # rotated at the run's last tick: the next file holds that tick again, and nothing more
        summary = reader.read_summary()
        if summary is not None and summary.complete and summary.reason == "rotated":
            res.segment_note = (f"the run goes on in the next file (rotated), which holds tick "
                                f"{res.last_tick}, the run's last, again")
    if events_to < res.last_tick:
        gaps.append(f"the events of tick {res.last_tick} may have been lost with the cut and were "
                    f"not compared")
    res.partial_note = "; ".join(gaps)


def _say_if_complete(reader: LogReader, res: VerifyResult, all_asked: bool) -> None:
    """Whether the file was read whole and its summary says it is complete."""
    summary = reader.read_summary() if reader.status.complete else None
    res.incomplete_why = (
        "the log ends without a footer (cut, or its writer was killed)"
        if not reader.status.complete else
        "only part of the log was asked for (--from-tick, --to-tick or --ship)"
        if not all_asked else
        "the log holds no summary" if summary is None else
        f"its summary says it is incomplete ({summary.reason or 'no reason given'})"
        if not summary.complete else "")
    res.file_complete = not res.incomplete_why


def _decode(reader: LogReader, cls, data: bytes, what: str):
    try:
        return cls.FromString(data)
    except Exception as exc:  # protobuf's DecodeError and friends
        raise LogError(f"{reader.path}: damaged {what} record ({type(exc).__name__})") from None


def _event(reader: LogReader, data: bytes) -> pb.TransitionEvent:
    return _decode(reader, pb.TransitionEvent, data, "event")


def _describe(e: pb.TransitionEvent) -> str:
    return (f"tick {e.tick}: {e.event} of ship {e.ship_id}, {_label(e.from_state)} -> "
            f"{_label(e.to_state)}")


def _event_divergence(reader: LogReader, res: VerifyResult, recorded: bytes | None,
                      replayed: bytes | None) -> None:
    a = None if recorded is None else _event(reader, recorded)
    b = None if replayed is None else _event(reader, replayed)
    first = a if a is not None else b
    name = "event"
    if a is not None and b is not None:
        name = "event." + (_first_field(a, b) or "bytes")
    res.divergence = Divergence(
        int(first.tick), first.tick * res.log_dt_s, first.ship_id, name,
        "(no event)" if a is None else _describe(a) + _field_value(a, name),
        "(no event)" if b is None else _describe(b) + _field_value(b, name))


def _field_value(msg, name: str) -> str:
    """``; ship.tilt_deg = 3.1`` for a difference past what :func:`_describe` shows."""
    path = name.split(".")[1:]
    if not path or path[0] in ("tick", "event", "ship_id", "from_state", "to_state", "bytes"):
        return ""
    x = msg
    for part in path:
        x = getattr(x, part)
    return f"; {'.'.join(path)} = {x!r}"


def _first_field(a, b, prefix: str = "") -> str | None:
    """The dotted name of the first field (in field-number order) where messages a and b differ."""
    for fd in a.DESCRIPTOR.fields:
        x, y = getattr(a, fd.name), getattr(b, fd.name)
        if x == y:
            continue
        if fd.message_type is not None and not fd.is_repeated:
            return _first_field(x, y, f"{prefix}{fd.name}.") or f"{prefix}{fd.name}"
        return prefix + fd.name
    return None


def _label(state: int) -> str:
    from touchdown.sim.enums import SurfaceState
    try:
        return SurfaceState(state).label
    except ValueError:
        return f"state {state}"
