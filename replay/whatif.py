"""``touchdown replay LOG --set KEY=VALUE ... [-o NEW.mcap]``: the same ship inputs under changed
settings, and how far the new run departs from the recording."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import zip_longest

import numpy as np

from logs.mcap_log import LogReader, LogWriter, scenario_of
from sim import __version__ as PROJECT_VERSION
from sim.enums import EventKind, SurfaceState
from sim.run import run


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
    res = WhatIf()
    with LogReader(path) as reader:
        res.log_version = reader.scenario.project_version
        scn, index = scenario_of(reader, ship_id, overrides)
        ids = list(scn.params.ships.ship_id)
        old_dt = reader.scenario.dt_s
        new_dt = scn.params.sim.dt_s
        old_ticks = {}
        for td in reader.ticks():
            old_ticks[td.tick] = td
        old_events = {sid: [] for sid in ids}
        for ev in reader.events():
            if ev.ship_id in old_events:
                old_events[ev.ship_id].append(_fmt(ev.t_s, ev.event, ev.from_state, ev.to_state))
        new_events = {sid: [] for sid in ids}
        writer = LogWriter(out_path, scn, f"{path} (what-if)") if out_path else None
        try:
            for rec in run(scn):
                if writer is not None:
                    writer.write(rec)
                for ev in rec.events:
                    new_events[ids[ev.ship]].append(
                        _fmt(ev.tick * new_dt, EventKind(ev.kind).topic, ev.from_state, ev.to_state))
                t = rec.tick * new_dt
                old_tick = t / old_dt
                k = round(old_tick)
                if abs(old_tick - k) > 1e-6 or k not in old_ticks:
                    continue
                old_pos, old_quat = old_ticks[k].vec("pos_m", 3), old_ticks[k].vec("quat", 4)
                if index is not None:
                    old_pos, old_quat = old_pos[index:index + 1], old_quat[index:index + 1]
                dp = np.linalg.norm(old_pos - rec.state.pos_m, axis=1)
                dots = np.abs(np.sum(old_quat * rec.state.quat, axis=1)).clip(0.0, 1.0)
                dang = np.degrees(2.0 * np.arccos(dots))
                i, j = int(np.argmax(dp)), int(np.argmax(dang))
                if dp[i] > res.max_position_diff_m:
                    res.max_position_diff_m, res.max_position_at = float(dp[i]), (ids[i], t)
                if dang[j] > res.max_attitude_diff_deg:
                    res.max_attitude_diff_deg, res.max_attitude_at = float(dang[j]), (ids[j], t)
                res.samples += 1
        except BaseException:
            if writer is not None:
                writer.abandon()
            raise
        if writer is not None:
            writer.close()
    res.timelines = {sid: (old_events[sid], new_events[sid]) for sid in ids}
    if not math.isfinite(res.max_position_diff_m):
        res.max_position_diff_m = float("inf")
    return res
