"""JSON Lines export of a log (SPEC.md section 4): one object per ship per tick, or per event."""
from __future__ import annotations

import json
import math
from typing import IO, Iterator

from logs.mcap_log import LogReader
from proto import touchdown_pb2 as pb
from sim.enums import SurfaceState

_STATE = {int(s): s.label for s in SurfaceState}


def tick_rows(reader: LogReader) -> Iterator[dict]:
    ids = list(reader.scenario.ship_ids)
    for td in reader.ticks():
        a = td.arrays
        for i, ship_id in enumerate(ids):
            c = max(-1.0, min(1.0, float(a["cos_tilt"][i])))
            yield {
                "tick": td.tick, "t": td.t_s, "ship_id": ship_id,
                "state": _STATE[int(a["surface_state"][i])],
                "altitude": float(a["altitude_m"][i]), "penetration": float(a["penetration_m"][i]),
                "peak_penetration": float(a["peak_penetration_m"][i]),
                "tilt_deg": math.degrees(math.acos(c)),
                "v_radial": float(a["v_radial_mps"][i]),
                "v_tangential": float(a["v_tangential_mps"][i]),
                "normal_force": float(a["normal_force_n"][i]),
                "friction_force": float(a["friction_force_n"][i]),
                "fuel_mass": float(a["fuel_kg"][i]), "mass": float(a["mass_kg"][i]),
                "throttle": float(a["throttle"][i]),
            }


def event_rows(reader: LogReader) -> Iterator[dict]:
    for ev in reader.events():
        yield {
            "event": ev.event, "tick": ev.tick, "t": ev.t_s, "ship_id": ev.ship_id,
            "player_id": ev.player_id, "body": ev.body,
            "from_state": _STATE[ev.from_state], "to_state": _STATE[ev.to_state],
            "v_radial": ev.v_radial_mps, "tilt_deg": ev.ship.tilt_deg, "surface_contact_state": ev.ship.surface_contact_state,
        }


def write_jsonl(rows: Iterator[dict], out: IO[str]) -> int:
    n = 0
    for row in rows:
        out.write(json.dumps(row, separators=(",", ":")))
        out.write("\n")
        n += 1
    return n


__all__ = ["tick_rows", "event_rows", "write_jsonl", "pb"]
