"""JSON Lines export of a log (SPEC.md section 4): one object per ship per tick, or per event.

Positions, velocities, angular velocities and energy come from the logged state through the same
``sim`` functions the step uses (sim.measure: the site frame, sim.energy), with the parameters of the
log's own recorded scenario. A field the log does not hold on a tick (a format-1 log's velocities
between keyframes) is null.
"""
from __future__ import annotations

import json
import math
from typing import IO, Iterator

import numpy as np

from logs import LogError
from logs.mcap_log import LogReader, TickData, fleet_params, scenario_of
from proto import touchdown_pb2 as pb
from sim import fields, measure
from sim.enums import SurfaceState

_STATE = {int(s): s.label for s in SurfaceState}


#: the log's quantities that export names as they are (sim.fields), the state as its label
EXPORTED = tuple(f for f in fields.FIELDS if f.export)
#: what export derives from the logged state: (key, quantity, component)
DERIVED = (("east", "pos", 0), ("north", "pos", 1), ("up", "pos", 2), ("v_east", "vel", 0),
           ("v_north", "vel", 1), ("v_up", "vel", 2), ("omega_x", "omega", 0),
           ("omega_y", "omega", 1), ("omega_z", "omega", 2))


def _derived(params, td: TickData) -> dict[str, np.ndarray] | None:
    """Site-frame position and velocity, body rates and energy of every ship at one tick
    (``params``: every ship of the log in key order, logs.mcap_log.fleet_params)."""
    a = td.arrays
    if "vel_mps" not in a or "omega_body_radps" not in a:
        return None
    p, v = td.vec("pos_m", 3), td.vec("vel_mps", 3)
    q, w = td.vec("quat", 4), td.vec("omega_body_radps", 3)
    t = td.tick * params.sim.dt_s
    # a damaged log's numbers may overflow here: write_jsonl names the field that came out
    # non-finite, in one line, where numpy's warnings would add lines of their own
    with np.errstate(all="ignore"):
        pos, vel = measure.site_frame(params, p, v, t)
        e = measure.energy(params, td.keys, t, p, v, q, w, a["mass_kg"])
    return {"pos": pos, "vel": vel, "omega": w, "energy": e["total_j"]}


def tick_rows(reader: LogReader) -> Iterator[dict]:
    """One row per ship per tick, the ships of each tick named by their ids (across joins and
    leaves)."""
    ids = reader.ship_table().ids
    params = fleet_params(reader, scenario_of(reader)[0])
    for td in reader.ticks():
        a = td.arrays
        d = _derived(params, td)
        for i, key in enumerate(td.keys.tolist()):
            c = max(-1.0, min(1.0, float(a["cos_tilt"][i])))
            row = {"tick": td.tick, "t": td.t_s, "ship_id": ids[key],
                   "tilt_deg": math.degrees(math.acos(c))}
            for f in EXPORTED:
                x = a.get(f.in_log)  # a format-1 log has no energy_guard_j
                row[f.export] = None if x is None else (
                    _STATE[int(x[i])] if f.name == "surface_state" else float(x[i]))
            for name, arr, k in DERIVED:
                row[name] = None if d is None else float(d[arr][i, k])
            row["energy_j"] = None if d is None else float(d["energy"][i])
            yield row


def event_rows(reader: LogReader) -> Iterator[dict]:
    for ev in reader.events():
        yield {
            "event": ev.event, "tick": ev.tick, "t": ev.t_s,
            # the instant it happened inside the tick (a log before 0.6: the tick's end)
            "t_event": ev.t_event_s if ev.HasField("t_event_s") else ev.t_s,
            "ship_id": ev.ship_id,
            "player_id": ev.player_id, "body": ev.body,
            "from_state": _STATE[ev.from_state], "to_state": _STATE[ev.to_state],
            "v_radial": ev.v_radial_mps, "tilt_deg": ev.ship.tilt_deg, "surface_contact_state": ev.ship.surface_contact_state,
        }


def write_jsonl(rows: Iterator[dict], out: IO[str], where: str = "") -> int:
    """One JSON object per line; a number that is not finite (only a damaged log holds one) is a
    LogError naming the tick, ship and field, never ``NaN`` in the output (not JSON)."""
    n = 0
    for row in rows:
        try:
            line = json.dumps(row, separators=(",", ":"), allow_nan=False)
        except ValueError:
            bad = next(k for k, v in row.items() if isinstance(v, float) and not math.isfinite(v))
            raise LogError(f"{where}: tick {row.get('tick')}, ship {row.get('ship_id')}: {bad} is "
                           f"{row[bad]} (the log is damaged)") from None
        out.write(line)
        out.write("\n")
        n += 1
    return n


def what_was_read(reader: LogReader, last_tick: int | None, events: bool = False) -> str:
    """"" when the export holds the whole run; otherwise one line saying which part it holds
    (``last_tick``: the last tick exported, of a tick export)."""
    if not reader.status.complete:
        held = ("the events recorded before the cut" if events else
                "no tick" if last_tick is None else
                f"ticks {reader.start_tick}..{last_tick}{_of(reader)}")
        damage = f"; {reader.status.damage}" if reader.status.damage else ""
        return (f"{reader.path}: read only part of the log: it ends without a footer (cut, or its "
                f"writer was killed{damage}); exported {held}")
    summary = reader.read_summary()
    if summary is not None and not summary.complete:
        return (f"{reader.path}: the run was stopped ({summary.reason or 'no reason given'}): "
                f"the log holds ticks {reader.start_tick}..{summary.last_tick}{_of(reader)}")
    return ""


def _of(reader: LogReader) -> str:
    """" of N" (the run's last tick), or nothing for a run without a set end (a live service)."""
    return "" if reader.open_ended else f" of {reader.scenario.n_ticks}"


__all__ = ["tick_rows", "event_rows", "write_jsonl", "what_was_read", "pb"]
