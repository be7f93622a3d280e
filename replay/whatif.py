"""``touchdown replay LOG --set KEY=VALUE ... [-o NEW.mcap]``: the same ship inputs under changed
settings, and how far the new run departs from the recording."""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from itertools import zip_longest

import numpy as np

from touchdown.logs import LogError
from touchdown.logs.header import scenario_message, world_header
from touchdown.logs.reader import LogReader
from touchdown.logs.rebuild import keyframe_world, recorded_world, scenario_of
from touchdown.logs.writer import LogWriter
from touchdown.service.driver import drive
from touchdown.sim import __version__ as PROJECT_VERSION
from touchdown.sim.enums import EventKind, SurfaceState
from touchdown.sim.scenario import Scenario
from touchdown.sim.timeline import Timeline


@dataclass
class WhatIf:
    max_position_diff_m: float = 0.0
    max_position_at: tuple[str, float] = ("", 0.0)
    max_attitude_diff_deg: float = 0.0
    max_attitude_at: tuple[str, float] = ("", 0.0)
    samples: int = 0
    timelines: dict[str, tuple[list[str], list[str]]] = field(default_factory=dict)
    log_version: str = PROJECT_VERSION

    def report(self) -> str:
        lines = []
        if self.log_version != PROJECT_VERSION:
            lines.append(f"note: this log was written by touchdown {self.log_version}; the replay runs "
                         f"its scenario and inputs under {PROJECT_VERSION}'s physics "
                         f"(docs/MODEL-NOTES.md)")
        lines += [f"compared at {self.samples} common instants",
                 f"largest position difference: {self.max_position_diff_m:.6g} m "
                 f"(ship {self.max_position_at[0]}, t = {self.max_position_at[1]:.3f} s)",
                 f"largest attitude difference: {self.max_attitude_diff_deg:.6g} deg "
                 f"(ship {self.max_attitude_at[0]}, t = {self.max_attitude_at[1]:.3f} s)",
                 "state timelines (recorded | what-if):"]
        for ship, (old, new) in self.timelines.items():
            lines.append(f"  {ship}")
            for a, b in zip_longest(old, new, fillvalue=""):
                lines.append(f"    {a:<38} | {b}")
        return "\n".join(lines)


def _fmt(t: float, event: str, a: int, b: int) -> str:
    return f"{t:8.3f} s {event:<13} {SurfaceState(a).label}->{SurfaceState(b).label}"


def what_if(path: str, overrides: dict, out_path: str | None = None,
            ship_id: str | None = None) -> WhatIf:
    """Re-run the log's recorded input (its ships, joins, leaves and commands; format 1 and 2: its
    scenario's inputs) under ``overrides``, and compare with the recording at their common
    instants. A recorded tick is moved to the new tick's grid by its time when ``sim.dt``
    changes. A log that starts later than tick 0 (ScenarioRecord.start_tick) is re-run from its
    first tick record, a keyframe, on the same tick (``sim.dt`` cannot change)."""
    res = WhatIf()
    with LogReader(path) as reader:
        res.log_version = reader.scenario.project_version
        start = reader.start_tick
        # from a keyframe, the whole fleet's scenario (ship keys are its rows); then one ship
        scn = _scenario(reader, overrides, None if start else ship_id)
        old_dt = reader.scenario.dt_s
        new_dt = scn.params.sim.dt_s
        if start and new_dt != old_dt:
            raise LogError(f"{reader.path}: starts at tick {start} (its state there is a "
                           f"keyframe on its own tick): a what-if of it cannot change sim.dt")
        old_ticks = _recorded_positions(reader)
        if start:
            first = next(reader.ticks(start, start), None)
            if start not in old_ticks or first is None:
                raise LogError(f"{reader.path}: no tick record at its first tick {start}")
            world = keyframe_world(reader, scn, first)
            if ship_id is not None and ship_id not in reader.ship_table():
                raise LogError(f"{reader.path}: no ship {ship_id!r} in this log")
            if ship_id is not None:
                keep = np.array([sid == ship_id for sid in world.ship_ids], dtype=bool)
                world = world.select(keep)
        else:
            world = recorded_world(reader, scn)
        table = reader.ship_table()
        if reader.log_format >= 3:
            recorded = world.timeline
            if ship_id is not None:
                recorded = recorded.for_ship(ship_id)
            world.timeline = _regrid(recorded, old_dt, new_dt)
        ids = [ship_id] if ship_id is not None else list(table.ids)
        old_events = {sid: [] for sid in ids}
        for ev in reader.events():
            if ev.ship_id in old_events:
                old_events[ev.ship_id].append(_fmt(ev.t_s, ev.event, ev.from_state, ev.to_state))
        new_events = {sid: [] for sid in ids}

        def compare(block, _msgs) -> None:
            for rec in block.records():
                for ev in rec.events:
                    new_events.setdefault(ev.ship_id, []).append(
                        _fmt(ev.tick * new_dt, EventKind(ev.kind).topic, ev.from_state,
                             ev.to_state))
                t = rec.tick * new_dt
                old_tick = t / old_dt
                k = round(old_tick)
                if abs(old_tick - k) > 1e-6 or k not in old_ticks or rec.state.n == 0:
                    continue
                old = old_ticks[k]
                where = {table.ids[int(key)]: j for j, key in enumerate(old.keys)}
                mine = [j for j, sid in enumerate(rec.ship_ids) if sid in where]
                if not mine:
                    continue
                theirs = [where[rec.ship_ids[j]] for j in mine]
                old_pos, old_quat = old.vec("pos_m", 3)[theirs], old.vec("quat", 4)[theirs]
                dp = np.linalg.norm(old_pos - rec.state.pos_m[mine], axis=1)
                dots = np.abs(np.sum(old_quat * rec.state.quat[mine], axis=1)).clip(0.0, 1.0)
                dang = np.degrees(2.0 * np.arccos(dots))
                i, j = int(np.argmax(dp)), int(np.argmax(dang))
                if dp[i] > res.max_position_diff_m:
                    res.max_position_diff_m = float(dp[i])
                    res.max_position_at = (rec.ship_ids[mine[i]], t)
                if dang[j] > res.max_attitude_diff_deg:
                    res.max_attitude_diff_deg = float(dang[j])
                    res.max_attitude_at = (rec.ship_ids[mine[j]], t)
                res.samples += 1

        end = scn.params.sim.n_ticks
        if reader.open_ended:  # no set end: as far as the recording goes
            end = max(old_ticks) if old_ticks else start
        header = None
        if out_path:
            header = scenario_message(scn, f"{path} (what-if)") if not (
                start or reader.open_ended) else world_header(
                world, scn.name, f"{path} (what-if)", reader.keyframe_interval,
                reader.open_ended, scn.description, keyframe_phase=reader.keyframe_phase)
        writer = LogWriter(out_path, header) if out_path else None
        outcome = drive(world, end, writer, [compare])
        if outcome.how != "done":
            raise KeyboardInterrupt
    res.timelines = {sid: (old_events.get(sid, []), new_events.get(sid, [])) for sid in ids}
    if not math.isfinite(res.max_position_diff_m):
        res.max_position_diff_m = float("inf")
    return res


class _Recorded:
    """One recorded tick's ships (keys), positions and attitudes: what a what-if compares."""

    __slots__ = ("keys", "pos", "quat")

    def __init__(self, keys: np.ndarray, pos: np.ndarray, quat: np.ndarray):
        self.keys, self.pos, self.quat = keys, pos, quat

    def vec(self, name: str, width: int) -> np.ndarray:
        return self.pos if name == "pos_m" else self.quat


def _recorded_positions(reader: LogReader) -> dict[int, _Recorded]:
    """Every recorded tick's positions and attitudes, decoded a block at a time (compiled:
    LogReader.blocks), holding those two fields only."""
    out = {}
    for b in reader.blocks(wanted=("pos_m", "quat")):
        pos, quat = b.columns["pos_m"], b.columns["quat"]
        for k in range(b.ticks.shape[0]):
            lo, hi = b.row_off[k], b.row_off[k + 1]
            out[int(b.ticks[k])] = _Recorded(b.keys[lo:hi], pos[lo:hi], quat[lo:hi])
    return out


def _scenario(reader: LogReader, overrides: dict, ship_id: str | None) -> Scenario:
    """The log's scenario under ``overrides`` (with ``ship_id``: that ship alone)."""
    if ship_id is None:
        return scenario_of(reader, overrides=overrides)[0]
    table = reader.ship_table()
    if ship_id not in table:
        raise LogError(f"{reader.path}: no ship {ship_id!r} in this log")
    if table.specs[table.key(ship_id)] is not None:
        raise LogError(f"{reader.path}: ship {ship_id!r} joined by command; a what-if of it "
                       f"alone is not supported: replay the whole log with --set")
    return scenario_of(reader, ship_id, overrides)[0]


def _regrid(timeline: Timeline, old_dt: float, new_dt: float) -> Timeline:
    """The same joins, leaves and commands at the same times on another tick's grid."""
    if old_dt == new_dt:
        return timeline
    at = lambda tick: int(math.ceil(tick * old_dt / new_dt - 1e-9))  # noqa: E731
    return Timeline.of([replace(s, tick=max(1, at(s.tick))) for s in timeline.spawns],
                       [replace(r, tick=max(1, at(r.tick))) for r in timeline.retires],
                       [replace(c, tick=at(c.tick)) for c in timeline.commands])
