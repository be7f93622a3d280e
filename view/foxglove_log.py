"""A Touchdown log as a Foxglove-ready MCAP file (``touchdown export LOG --format foxglove -o
OUT.mcap``): the channels of view.foxglove, every tick of every ship (or those chosen), from any
log of any format, written by the stock MCAP writer (chunked, zstd, every CRC, indexed).

The log is read a block of ticks at a time, as the other exports read it (logs.export's
columns: the same numbers as the Parquet, CSV and JSON Lines tables), and each tick's messages
are written in log-time order: the ground and the landers at the first tick, then per tick its
transforms, its values, its events and, when due, the landers.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import register_schema

from touchdown.logs.export import Selection, table_info, tick_blocks, TICK_NAMES
from touchdown.logs.reader import LogReader
from touchdown.logs.rebuild import fleet_params, scenario_of
from touchdown.sim import __version__ as PROJECT_VERSION
from touchdown.view import foxglove as fx

class FoxgloveWriter:
    """The Foxglove channels (view.foxglove.SCHEMAS) on an mcap Writer: ``put(topic, t_ns,
    bytes)`` adds a message with its log and publish time and the channel's sequence number."""

    def __init__(self, mcap: Writer, topics=tuple(fx.SCHEMAS)):
        self.mcap = mcap
        schema_ids: dict[type, int] = {}
        self.channels: dict[str, int] = {}
        for topic in topics:
            cls = fx.SCHEMAS[topic]
            if cls not in schema_ids:
                schema_ids[cls] = register_schema(mcap, cls)
            self.channels[topic] = mcap.register_channel(topic, "protobuf", schema_ids[cls])
        self._seq = {t: 0 for t in self.channels}
        self.counts = {t: 0 for t in self.channels}

    def put(self, topic: str, t_ns: int, data: bytes) -> None:
        self.mcap.add_message(self.channels[topic], log_time=int(t_ns), data=data,
                              publish_time=int(t_ns), sequence=self._seq[topic])
        self._seq[topic] += 1
        self.counts[topic] += 1


class SceneKeeper:
    """Which ships are present and in which state, and when the landers' SceneUpdate is due
    (view.foxglove: the whole fleet in each message, after a change, at most one per period)."""

    def __init__(self, ids: list[str], leg_radius_m: np.ndarray, com_height_m: np.ndarray,
                 period_s: float, label: bool = True):
        self.ids = ids
        self.landers = fx.LanderCache(ids, leg_radius_m, com_height_m, label)
        self.period_ns = int(round(period_s * 1e9))
        self.state: dict[int, int] = {}  # key -> state, of the ships drawn
        self.last_ns: int | None = None
        self.pending = False
        self._gone: set[int] = set()

    def see(self, keys: np.ndarray, states: np.ndarray) -> None:
        """One tick's ships and states."""
        now = dict(zip(keys.tolist(), states.tolist()))
        if now != self.state:
            self._gone |= set(self.state) - set(now)
            self._gone -= set(now)
            self.state = now
            self.pending = True

    def due(self, t_ns: int, last: bool = False) -> bytes | None:
        """The SceneUpdate of the whole fleet if one is due at ``t_ns`` (``last``: the run's
        last tick: anything pending is written)."""
        if not self.pending:
            return None
        if not last and self.last_ns is not None and t_ns - self.last_ns < self.period_ns:
            return None
        self.pending, self.last_ns = False, t_ns
        gone = [self.ids[k] for k in sorted(self._gone)]
        self._gone = set()
        return self.landers.update(t_ns, sorted(self.state.items()), gone)


@dataclass
class Exported:
    messages: dict[str, int] = field(default_factory=dict)
    ticks: int = 0
    rows: int = 0
    first_tick: int | None = None
    last_tick: int | None = None


def write(reader: LogReader, out: str | os.PathLike, sel: Selection = Selection(),
          scene_period_s: float | None = None, block_bytes: int = 32 << 20) -> Exported:
    """``reader``'s log (the ships and ticks ``sel`` picks; its columns are ignored: every
    value is written) as a Foxglove-ready MCAP file at ``out`` (the caller renames a partial
    file into place)."""
    sel = Selection(sel.ships, sel.first, sel.last, TICK_NAMES)
    info = table_info(reader, TICK_NAMES)
    params = fleet_params(reader, scenario_of(reader)[0])
    ids = reader.ship_table().ids
    sh = params.ships
    period = scene_period_s if scene_period_s is not None else fx.scene_period(len(ids))
    scene = SceneKeeper(ids, sh.leg_radius_m, sh.com_height_m, period,
                        label=len(ids) <= fx.LARGE_FLEET)
    events: dict[int, list[bytes]] = {}
    for ev in reader.events():
        if sel.ships is not None and ev.ship_id not in sel.ships:
            continue
        if (sel.first is not None and ev.tick < sel.first) or (
                sel.last is not None and ev.tick > sel.last):
            continue
        t_event = ev.t_event_s if ev.HasField("t_event_s") else ev.t_s
        events.setdefault(int(ev.tick), []).append(fx.event_log(
            ev.event, ev.ship_id, ev.from_state, ev.to_state, t_event, ev.v_radial_mps,
            ev.ship.tilt_deg, ev.player_id))
    dt_ns = reader.tick_time_ns(1)
    enc = fx.FleetEncoder()
    enc.ids(ids)
    res = Exported()
    with open(out, "wb") as f:
        mcap = Writer(f, chunk_size=1 << 20, compression=CompressionType.ZSTD,
                      enable_crcs=True, enable_data_crcs=True)
        mcap.start(profile="", library=f"touchdown {PROJECT_VERSION}")
        fw = FoxgloveWriter(mcap)
        mcap.add_metadata("touchdown", {**info.metadata, "foxglove.frame": fx.SITE_FRAME,
                                        "foxglove.layout": "docs/foxglove-layout.json"})
        pending_last = None
        for blk in tick_blocks(reader, sel, block_bytes, attitude=True):
            tick = blk.columns["tick"]
            starts = np.flatnonzero(np.r_[True, tick[1:] != tick[:-1]])
            counts = np.diff(np.r_[starts, blk.rows])
            ticks = tick[starts].tolist()
            t_ns = [tk * dt_ns for tk in ticks]
            t_s = blk.columns["t"][starts].tolist()
            keys = blk.keys
            states = blk.columns["state"].astype(np.int64)
            pos = np.stack([blk.columns["east"], blk.columns["north"], blk.columns["up"]], 1)
            values = {}
            for name in fx.VALUE_FIELDS:
                a = np.asarray(blk.columns[name], float)
                miss = blk.missing.get(name)
                if miss is not None and miss.any():
                    a = np.where(miss, np.nan, a)
                values[name] = a
            transforms = enc.transforms(t_ns, counts, keys, pos, blk.quat_site_xyzw)
            ship_values = enc.values(ticks, t_s, counts, keys, states, values)
            for k, (tk, t) in enumerate(zip(ticks, t_ns)):
                rows = slice(starts[k], starts[k] + counts[k])
                if res.first_tick is None:
                    res.first_tick = tk
                    fw.put(fx.TOPIC_GROUND, t, fx.ground_around(params, pos[rows], float(
                        (sh.leg_radius_m + sh.com_height_m).max())))
                fw.put(fx.TOPIC_TRANSFORMS, t, transforms[k])
                fw.put(fx.TOPIC_SHIPS, t, ship_values[k])
                scene.see(keys[rows], states[rows])
                landers = scene.due(t)
                if landers is not None:
                    fw.put(fx.TOPIC_LANDERS, t, landers)
                for m in events.get(tk, ()):
                    fw.put(fx.TOPIC_EVENTS, t, m)
                pending_last = t
                res.last_tick = tk
            res.ticks += len(ticks)
            res.rows += blk.rows
        if pending_last is not None:
            landers = scene.due(pending_last, last=True)
            if landers is not None:
                fw.put(fx.TOPIC_LANDERS, pending_last, landers)
        mcap.finish()
    res.messages = dict(fw.counts)
    return res


__all__ = ["write", "Exported", "FoxgloveWriter", "SceneKeeper"]
