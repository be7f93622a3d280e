"""``touchdown replay LOG --verify``: re-run a log from its recorded scenario and compare every
recorded number, bit for bit, with today's code.

The log is self-sufficient: its ScenarioRecord holds the resolved scenario (every default filled in),
so no other file is read. Every TickBatch is a full-state keyframe, so a window ``first..last``
starts from the state recorded at ``first`` instead of tick 0.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from logs import LogError
from logs.codec import PACKED, encode_tick
from logs.mcap_log import (_EMPTY, KEYFRAME_ONLY, LOG_FORMAT_VERSION, WIDTH as _WIDTH, LogReader,
                           scenario_of, tick_arrays)
from sim import __version__ as PROJECT_VERSION
from sim.run import run

#: per-ship width of each packed field
WIDTH = {name: _WIDTH.get(name, 1) for _, name, _ in PACKED}


@dataclass
class Divergence:
    tick: int
    t_s: float
    ship_id: str
    field: str  # e.g. "vel_mps[2]"
    recorded: float
    replayed: float


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

    @property
    def identical(self) -> bool:
        return self.divergence is None and self.ticks_compared > 0

    def report(self) -> str:
        head = (f"log: touchdown {self.log_version}, method {self.log_method}, dt {self.log_dt_s:g} s;"
                f" today: touchdown {PROJECT_VERSION}")
        lines = [head]
        if self.log_version != PROJECT_VERSION:
            lines.append(f"note: this log was written by touchdown {self.log_version}, whose physics "
                         f"differs from {PROJECT_VERSION}'s (docs/MODEL-NOTES.md), so a divergence is "
                         f"expected; `touchdown replay LOG -o NEW.mcap` re-runs its scenario and "
                         f"inputs under today's physics")
        if self.recovered_note:
            lines.append(self.recovered_note)
        if self.divergence is None:
            lines.append(f"identical: ticks {self.first_tick}..{self.last_tick}, "
                         f"{len(self.ships)} ship(s), {self.numbers_compared:,} numbers compared "
                         f"bit for bit")
            return "\n".join(lines)
        d = self.divergence
        lines.append(f"DIVERGED at tick {d.tick} (t = {d.t_s:.4f} s), ship {d.ship_id}, "
                     f"field {d.field}")
        lines.append(f"  recorded {d.recorded!r}")
        lines.append(f"  replayed {d.replayed!r}  (difference {d.replayed - d.recorded:.3e})")
        if self.recent_events:
            lines.append("  last transitions of that ship before it:")
            lines += [f"    {e}" for e in self.recent_events]
        else:
            lines.append("  no transition of that ship before it")
        return "\n".join(lines)


def _first_difference(rec_arrays: dict, new_arrays: dict, ship_slice, n_new: int,
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
    with LogReader(path) as reader:
        sr = reader.scenario
        scn, index = scenario_of(reader, ship_id)
        ids = list(scn.params.ships.ship_id)
        if first:  # start from the nearest keyframe at or before ``first``
            first -= first % reader.keyframe_interval
        res = VerifyResult(sr.project_version, sr.integrator, sr.dt_s, first or 0,
                           last if last is not None else int(sr.n_ticks), ids)
        ticks = reader.ticks(first, last)
        start = None
        if first:
            try:
                key = next(ticks)
            except StopIteration:
                raise LogError(f"{path}: no tick {first} in this log") from None
            start = key.state()
            if index is not None:
                start = start.take(np.array([index]))
            res.ticks_compared += 1
        sim = run(scn, start=start, last_tick=res.last_tick)
        interval = reader.keyframe_interval
        ship_slice = None if index is None else index
        for recorded in ticks:
            try:
                new = next(sim)
            except StopIteration:
                break
            if new.tick != recorded.tick_from_time:
                raise LogError(f"{path}: tick records out of order (expected {new.tick}, "
                               f"found {recorded.tick_from_time})")
            arrays = tick_arrays(new)
            res.ticks_compared += 1
            res.last_tick = new.tick
            if ship_slice is None:
                # the whole batch: the replayed tick, encoded as the writer encodes it, must be
                # the recorded message byte for byte; only a mismatch is decoded and diagnosed
                if new.tick % interval:
                    for name in KEYFRAME_ONLY:
                        arrays[name] = _EMPTY
                mine = encode_tick(new.tick, new.tick * sr.dt_s, new.state.n, arrays)
                res.numbers_compared += sum(np.size(a) for a in arrays.values())
                if mine == recorded.raw:
                    continue
            else:
                res.numbers_compared += sum(np.size(arrays[k]) for k in recorded.arrays)
            hit = _first_difference(recorded.arrays, arrays, ship_slice, new.state.n,
                                    sr.log_format_version < LOG_FORMAT_VERSION)
            if hit is None and ship_slice is None:  # same numbers, different bytes
                hit = (0, "tick", 0, float(recorded.tick), float(new.tick))
            if hit is not None:
                ship, name, comp, a, b = hit
                fld = f"{name}[{comp}]" if WIDTH.get(name, 1) > 1 else name
                res.divergence = Divergence(recorded.tick, recorded.t_s, ids[ship], fld, a, b)
                res.recent_events = [
                    f"tick {e.tick}: {e.event} {_label(e.from_state)} -> {_label(e.to_state)}"
                    for e in reader.events() if e.ship_id == ids[ship] and e.tick <= recorded.tick
                ][-3:]
                break
        if not reader.status.complete:
            res.recovered_note = (
                f"the log ends without a footer (its writer was stopped): recovered "
                f"{res.ticks_compared} tick(s), {res.first_tick}..{res.last_tick}"
                + (f"; the rest is damaged ({reader.status.damage})" if reader.status.damage
                   else ""))
        return res


def _label(state: int) -> str:
    from sim.enums import SurfaceState
    return SurfaceState(state).label
