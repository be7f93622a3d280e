"""The MCAP log: one ScenarioRecord, one TickBatch per tick, a TransitionEvent per transition, a
FleetChange per tick at which ships join or leave, a CommandBatch per tick with commands, and a
LogSummary at the end. The ScenarioRecord, the joins and leaves and the commands are the run's whole
input: a replay folds the step over them (replay.verify). Chunked, zstd-compressed, CRCs on, protobuf schemas embedded, so that stock
readers (``mcap-protobuf-support``, Foxglove) decode every message without this project.

Log times are simulation time, ``tick * dt`` in integer nanoseconds, never the wall clock.

Writing goes to ``OUT.mcap.partial`` and is renamed to ``OUT.mcap`` only once the footer is
written: a file under the final name is always a finished MCAP. A writer that is interrupted
(Ctrl-C) finishes what it has and marks the summary ``complete = false``.
"""
from __future__ import annotations

import copy
import dataclasses
import json
import math
import os
import queue
import threading
from pathlib import Path
from typing import Iterator

import numpy as np
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import register_schema

from logs import LogError
from logs.encode import chunk_level, resolved_json
from logs.codec import PACKED, BlockEncoder, decode_tick
from logs.decode import TickBlock, decode_block
from logs.safe_read import ReadLimits, ReadStatus, iter_messages
from logs.structure import Structure
from logs.structure import check as check_structure
from proto import touchdown_pb2 as pb
from sim import __version__ as PROJECT_VERSION
from sim import fields
from sim.enums import EventKind, SurfaceState
from sim.world import Block, TickRecord, World
from sim.scenario import TIMING_KEYS, Scenario, ScenarioError, parse
from sim.params import Params
from sim.state import STATE_ARRAY_FIELDS, Inputs, Outputs, State, concatenate
from sim.timeline import Command, CommandError, Retire, Spawn, Timeline

#: The log formats and their fields: sim.fields (LOG_FORMAT, EVERY_TICK_BY_FORMAT,
#: KEYFRAME_BY_FORMAT), where the rule is written. 2 (touchdown 0.3): per-foot ``sliding`` (4 per
#: ship); velocities and angular velocities on every tick. A format-1 log still reads (``sliding``
#: per ship is given to all four feet). 3 (touchdown 0.5): ships join and leave (FleetChange), each
#: tick names its ships by key (TickBatch.ship_key), commands are recorded as commands
#: (CommandBatch), and a replay folds over those; formats 1 and 2 replay from their scenario's
#: inputs, with a notice. Later in 3, with fields that default to what every earlier log of format
#: 3 is: a log may start at any tick (ScenarioRecord.start_tick: its first tick record is a
#: keyframe of the header's ships, which the replay starts from) and a run may have no set end
#: (ScenarioRecord.open_ended: the summary's last tick is its end). A reader from before refuses
#: such a log (its first tick is not 0). 4 (touchdown 0.6): keyframes hold how long the settle
#: thresholds have held (settle_for_s, settle_margin); events carry their instant (t_event_s).
LOG_FORMAT_VERSION = fields.LOG_FORMAT
#: how far a log may start (ticks): past any run a scenario may ask for, within a double's integers
MAX_START_TICK = 1 << 53
#: the tick, s: what a scenario may set (sim.scenario), and so what a log may hold
MIN_DT_S, MAX_DT_S = 1e-4, 1.0
MAX_SHIPS = 10_000_000
MAX_SCENARIO_CHARS = 64 << 20
_EMPTY = np.zeros(0)
TOPIC_SCENARIO = "/touchdown/scenario"
TOPIC_TICKS = "/touchdown/ticks"
TOPIC_EVENTS = "/touchdown/events"
TOPIC_SUMMARY = "/touchdown/summary"
TOPIC_FLEET = "/touchdown/fleet"
TOPIC_COMMANDS = "/touchdown/commands"
#: state fields written only on keyframe ticks (today's format); the rest (positions, velocities,
#: attitudes, angular velocities, masses, states, telemetry, commands) are on every tick
KEYFRAME_ONLY = fields.KEYFRAME_BY_FORMAT[LOG_FORMAT_VERSION]
#: numbers per ship of each TickBatch array (1 where not listed)
WIDTH = {f.in_log: f.per_ship for f in fields.FIELDS if f.per_ship > 1}


def tick_arrays(rec: TickRecord, keys: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Every per-ship array of a TickBatch, by field name (``keys``: the ships' keys)."""
    records = {"state": rec.state, "outputs": rec.outputs, "inputs": rec.inputs}
    arrays = {f.in_log: records[f.record].rows[f.name] for f in fields.FIELDS}
    if keys is not None:
        arrays["ship_key"] = keys
    return arrays


def ship_state_message(ship_id: str, player_id: str, body: str, rec_state, i: int
                       ) -> pb.ShipState:
    st = SurfaceState(int(rec_state.surface_state[i]))
    p, v, q, w = (rec_state.pos_m[i], rec_state.vel_mps[i], rec_state.quat[i],
                  rec_state.omega_body_radps[i])
    r_hat = p / math.sqrt(float(p @ p))
    ez = np.array([2 * (q[1] * q[3] + q[0] * q[2]), 2 * (q[2] * q[3] - q[0] * q[1]),
                   1 - 2 * (q[1] ** 2 + q[2] ** 2)])
    tilt = math.degrees(math.acos(max(-1.0, min(1.0, float(ez @ r_hat)))))
    return pb.ShipState(
        ship_id=ship_id, player_id=player_id,
        landed_body_name="" if st is SurfaceState.FLYING else body,
        position_m=pb.Vec3(x=p[0], y=p[1], z=p[2]), velocity_mps=pb.Vec3(x=v[0], y=v[1], z=v[2]),
        attitude=pb.Quaternion(w=q[0], x=q[1], y=q[2], z=q[3]),
        omega_body_radps=pb.Vec3(x=w[0], y=w[1], z=w[2]),
        mass_kg=float(rec_state.mass_kg[i]), fuel_kg=float(rec_state.fuel_kg[i]), state=int(st),
        tilt_deg=tilt, surface_contact_state=st.seed_string)


def event_message(ships: "ShipTable", body: str, dt_s: float, state: State, ev
                  ) -> pb.TransitionEvent:
    """A transition as the log and the event stream carry it."""
    ship_id = ev.ship_id
    player_id = ships.players[ships.key(ship_id)]
    return pb.TransitionEvent(
        event=EventKind(ev.kind).topic, tick=ev.tick, t_s=ev.tick * dt_s, ship_id=ship_id,
        player_id=player_id, body=body, from_state=ev.from_state, to_state=ev.to_state,
        ship=ship_state_message(ship_id, player_id, body, state, ev.ship),
        v_radial_mps=ev.v_radial_mps, t_event_s=ev.t_event_s)


def scenario_message(scn: Scenario, source: str, keyframe_interval: int = 1
                     ) -> pb.ScenarioRecord:
    """The log's header: the resolved scenario and the ships present at tick 0."""
    return pb.ScenarioRecord(
        log_format_version=LOG_FORMAT_VERSION, project_version=PROJECT_VERSION, name=scn.name,
        description=scn.description, resolved_json=json.dumps(scn.resolved, sort_keys=True),
        integrator=scn.params.sim.integrator, dt_s=scn.params.sim.dt_s,
        ship_ids=list(scn.params.ships.ship_id), player_ids=list(scn.params.ships.player_id),
        body=scn.params.body.name, source=source, n_ticks=scn.params.sim.n_ticks,
        keyframe_interval=keyframe_interval)


def world_header(world: World, name: str, source: str, keyframe_interval: int = 1,
                 open_ended: bool = False, description: str = "", end_tick: int | None = None,
                 tables: dict[str, dict] | None = None) -> pb.ScenarioRecord:
    """The header of a log of ``world`` from its current tick (``start_tick``): the resolved scene
    with ``ships`` the tables of the ships present now (their timing keys removed: when they join,
    leave and what they are commanded is the log's own record; their ``initial`` tables are
    irrelevant, as the state comes from the log's first tick record, a keyframe). The world may
    have no ships. ``open_ended``: the run has no set end (a live service); ``end_tick``: the
    run's last tick when not the scene's ``duration`` (a cut: n_ticks is set to it);
    ``tables``: ship id -> its resolved table, a cache kept across the headers of one world
    (each ship is resolved once: 10,000 ships take about half a second)."""
    doc = copy.deepcopy(world.scene.doc)
    doc.pop("ships", None)
    doc["name"] = name
    if description:
        doc["description"] = description
    sim = world.params.sim
    if end_tick is not None:
        doc["duration"] = end_tick * sim.dt_s
        if dataclasses.replace(sim, duration_s=doc["duration"]).n_ticks != end_tick:
            raise ValueError(f"end_tick {end_tick}: not a whole number of ticks of {sim.dt_s!r} s")
        sim = dataclasses.replace(sim, duration_s=doc["duration"])
    ids = list(world.ship_ids)
    cache = {} if tables is None else tables
    missing = [sid for sid in ids if sid not in cache]
    if missing:  # resolved by the scenario's rules, with its messages
        scn = parse({**doc, "ships": [{k: v for k, v in world.known[sid].items()
                                       if k not in TIMING_KEYS} for sid in missing]},
                    source or name)
        if list(scn.params.ships.ship_id) != missing:
            raise ValueError(f"the world's ships {missing[:5]} resolve to "
                             f"{list(scn.params.ships.ship_id)[:5]}")
        cache.update(zip(missing, scn.resolved["ships"]))
    # no ships (yet): the scene alone, which the log's reader accepts (scenario_of)
    resolved = {**doc, "ships": [cache[sid] for sid in ids]}
    return pb.ScenarioRecord(
        log_format_version=LOG_FORMAT_VERSION, project_version=PROJECT_VERSION, name=name,
        description=resolved.get("description", ""),
        resolved_json=resolved_json(resolved, ids, tables), integrator=sim.integrator,
        dt_s=sim.dt_s, ship_ids=ids, player_ids=list(world.params.ships.player_id),
        body=world.params.body.name, source=source, n_ticks=sim.n_ticks,
        keyframe_interval=keyframe_interval, start_tick=world.tick, open_ended=open_ended)


class ShipTable:
    """Every ship of a log by key: the header's ships (keys 0, 1, ...), then each that joined, in
    the order they joined. ``specs[k]``: the table a joining ship came with (None for the
    header's, whose tables are in the resolved scenario)."""

    def __init__(self, ids=(), players=()):
        self.ids: list[str] = list(ids)
        self.players: list[str] = list(players)
        self.specs: list[dict | None] = [None] * len(self.ids)
        self.joined: list[int] = [0] * len(self.ids)
        self._key = {sid: k for k, sid in enumerate(self.ids)}

    def add(self, tick: int, spec: dict) -> int:
        key = len(self.ids)
        self.ids.append(spec["id"])
        self.players.append(spec.get("player_id") or "player-" + spec["id"])
        self.specs.append(spec)
        self.joined.append(tick)
        self._key[spec["id"]] = key
        return key

    def key(self, ship_id: str) -> int:
        return self._key[ship_id]

    def keys(self, ship_ids) -> np.ndarray:
        return np.fromiter((self._key[s] for s in ship_ids), np.int64, len(ship_ids))

    def __contains__(self, ship_id: str) -> bool:
        return ship_id in self._key

    def __len__(self) -> int:
        return len(self.ids)


#: encoded blocks waiting for the writer's thread, at most (each about a megabyte or one tick)
QUEUE_BLOCKS = 4


class FinishedOrGone:
    """A log writer as a context manager: closed when the block ends, marked incomplete on
    Ctrl-C, abandoned (nothing kept) on any other error. Needs ``close`` and ``abandon``."""

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        elif issubclass(exc_type, KeyboardInterrupt):
            self.close(complete=False, reason="interrupted")
        else:
            self.abandon()


class LogWriter(FinishedOrGone):
    """Write a run to an MCAP file. A context manager; ``close()`` is safe to call twice.

    The caller's thread encodes each block of ticks (compiled, without the GIL); a thread of the
    writer's own adds the messages to the MCAP file and compresses its chunks (zstd releases the
    GIL), so the next block is stepped meanwhile. The queue between them holds at most
    QUEUE_BLOCKS blocks. An error on the writer's thread (a full disk) is raised by the next call
    from the caller (write, close)."""

    def __init__(self, path: str | os.PathLike, header: pb.ScenarioRecord,
                 chunk_size: int = 1 << 20, flush_every_ticks: int = 200,
                 zstd_level: int | None = None):
        self.path = Path(path)
        self.partial = self.path.with_name(self.path.name + ".partial")
        self.header = header
        self.ships = ShipTable(header.ship_ids, header.player_ids)
        self._keys_of: tuple[tuple[str, ...], np.ndarray] = ((), np.zeros(0, np.int64))
        self._dt_ns = int(round(header.dt_s * 1e9))
        keyframe_interval = max(1, header.keyframe_interval)
        self._flush_every = flush_every_ticks
        self._zstd_level = zstd_level  # the chunks' (logs.encode; None: the library's, 3)
        chunk_level(zstd_level)  # (the header's chunk is compressed on this thread)
        self._stream = open(self.partial, "wb")
        try:
            self._mcap = Writer(self._stream, chunk_size=chunk_size, compression=CompressionType.ZSTD,
                                enable_crcs=True)
            self._mcap.start(profile="", library=f"touchdown {PROJECT_VERSION}")
            self._channels = {}
            for topic, cls in ((TOPIC_SCENARIO, pb.ScenarioRecord), (TOPIC_TICKS, pb.TickBatch),
                               (TOPIC_EVENTS, pb.TransitionEvent), (TOPIC_SUMMARY, pb.LogSummary),
                               (TOPIC_FLEET, pb.FleetChange), (TOPIC_COMMANDS, pb.CommandBatch)):
                schema_id = register_schema(self._mcap, cls)
                self._channels[topic] = self._mcap.register_channel(topic, "protobuf", schema_id)
            self._seq = {t: 0 for t in self._channels}
            self._mcap.add_metadata("touchdown", {
                "project_version": PROJECT_VERSION, "log_format_version": str(LOG_FORMAT_VERSION),
                "scenario": header.name, "integrator": header.integrator,
                "dt_s": repr(header.dt_s)})
            self.keyframe_interval = keyframe_interval
            self._encoder = BlockEncoder(header.dt_s, KEYFRAME_ONLY, keyframe_interval)
            self._put(TOPIC_SCENARIO, int(header.start_tick), header.SerializeToString())
            self._size = self._stream.tell()
        except BaseException:  # nothing half-written: no .partial without a writer
            self._discard()
            raise
        self.last_tick = -1
        self.event_count = 0
        self._closed = False
        self._queue: queue.Queue = queue.Queue(maxsize=QUEUE_BLOCKS)
        self._error: BaseException | None = None
        self._abort = False
        self._thread = threading.Thread(target=self._drain, name="touchdown-log", daemon=True)
        self._thread.start()

    def _drain(self) -> None:
        """The writer's thread: add every queued block's messages, until the end marker."""
        chunk_level(self._zstd_level)
        while True:
            item = self._queue.get()
            if item is None:
                return
            if isinstance(item, threading.Event):  # flush(): all before it is written
                try:
                    if self._error is None and not self._abort:
                        self._mcap.flush()  # ends the chunk being filled
                        self._stream.flush()
                except BaseException as exc:  # noqa: BLE001 - handed to the caller's thread
                    self._error = exc
                item.set()
                continue
            if self._error is not None or self._abort:
                continue  # drop the rest; the caller hears of the error
            try:
                block, keys, first_keyframe, events, inputs = item
                data, offsets = self._encoder.encode(block.first_tick, block.states,
                                                     block.outputs, block.inputs, keys,
                                                     first_keyframe=first_keyframe)
                self._write_encoded(block.first_tick, data, offsets, events, inputs)
                self._size = self._stream.tell()
            except BaseException as exc:  # noqa: BLE001 - handed to the caller's thread
                self._error = exc

    def _write_encoded(self, first_tick: int, data: np.ndarray, offsets: np.ndarray,
                       events: dict[int, list[bytes]], inputs: list[tuple[str, int, bytes]]
                       ) -> None:
        for topic, tick, message in inputs:  # joins, leaves and commands: before their ticks
            self._put(topic, tick, message)
        view = memoryview(data)
        for k in range(offsets.shape[0] - 1):
            tick = first_tick + k
            self._put(TOPIC_TICKS, tick, view[offsets[k]:offsets[k + 1]])
            for m in events.get(tick, ()):
                self._put(TOPIC_EVENTS, tick, m)
            if self._flush_every and tick % self._flush_every == 0:
                self._mcap.flush()  # bounds what a killed writer loses

    def _check(self) -> None:
        if self._error is not None:
            exc, self._error = self._error, None
            raise exc

    def _stop_thread(self) -> None:
        if self._thread.is_alive():
            self._queue.put(None)
            self._thread.join()

    def _put(self, topic: str, tick: int, data: bytes) -> None:
        t_ns = tick * self._dt_ns
        self._mcap.add_message(self._channels[topic], log_time=t_ns, data=data,
                               publish_time=t_ns, sequence=self._seq[topic])
        self._seq[topic] += 1

    def write_block(self, block: Block) -> list[pb.TransitionEvent]:
        """Append a block of ticks (sim.world.Block): its joins and leaves, its commands, its
        ticks and its events. Returns the events as messages (for publishing elsewhere too).

        The first block is the record of the header's ``start_tick`` with the header's ships (a
        run's tick 0: ``world.first_block()``; later, a keyframe of the fleet as it is then), and
        is written as a keyframe; each next block follows the last."""
        self._check()
        expected = int(self.header.start_tick) if self.last_tick < 0 else self.last_tick + 1
        if block.first_tick != expected:
            raise ValueError(f"{self.path}: a block of ticks {block.first_tick}.."
                             f"{block.last_tick} where the log's next tick is {expected}")
        if self.last_tick < 0 and (len(block) != 1 or tuple(block.ship_ids) != tuple(
                self.header.ship_ids) or block.spawned or block.retired or block.commands
                                   or block.events):
            raise ValueError(f"{self.path}: the first block must be the one tick {expected} with "
                             f"the header's ships and nothing that led to it (no joins, leaves, "
                             f"commands or events): world.first_block()")
        inputs = self._inputs(block)
        if self._keys_of[0] is not block.ship_ids:  # the same tuple while the fleet is the same
            self._keys_of = (block.ship_ids, self.ships.keys(block.ship_ids))
        msgs = []
        events: dict[int, list[bytes]] = {}
        body = self.header.body
        for ev in block.events:
            state = State(rows=block.states[ev.tick - block.first_tick], tick=ev.tick)
            m = event_message(self.ships, body, self.header.dt_s, state, ev)
            events.setdefault(ev.tick, []).append(m.SerializeToString())
            msgs.append(m)
        # encoded on the writer's thread (compiled, without the GIL): off the caller's tick
        self._queue.put((block, self._keys_of[1], self.last_tick < 0, events, inputs))
        self.event_count += len(msgs)
        self.last_tick = block.last_tick
        return msgs

    def _inputs(self, block: Block) -> list[tuple[str, int, bytes]]:
        """The block's joins, leaves and commands as FleetChange and CommandBatch messages."""
        out = []
        if block.spawned or block.retired:
            change = pb.FleetChange(tick=block.first_tick)
            for r in block.retired:
                change.left_ship_key.append(self.ships.key(r.ship_id))
                change.left_ship_id.append(r.ship_id)
            for sp in block.spawned:
                key = self.ships.add(block.first_tick, sp.spec)
                change.joined.add(ship_key=key, ship_id=sp.ship_id,
                                  player_id=self.ships.players[key],
                                  spec_json=json.dumps(sp.spec, sort_keys=True))
            out.append((TOPIC_FLEET, block.first_tick, change.SerializeToString()))
        batch = None
        for c in block.commands:
            if batch is None or batch.tick != c.tick:
                if batch is not None:
                    out.append((TOPIC_COMMANDS, batch.tick, batch.SerializeToString()))
                batch = pb.CommandBatch(tick=c.tick)
            batch.commands.add(tick=c.tick, ship_id=c.ship_id, throttle=c.throttle,
                               rcs=list(c.rcs), hold=c.hold)
        if batch is not None:
            out.append((TOPIC_COMMANDS, batch.tick, batch.SerializeToString()))
        return out

    def close(self, complete: bool = True, reason: str = "") -> None:
        """Write the summary and the MCAP footer, then move the file to its final name. If that
        fails (a full disk), the partial file is removed and the error raised: a file is either
        finished under its final name or gone."""
        if self._closed:
            return
        self._closed = True
        try:
            self._stop_thread()
            self._check()
            last = max(self.last_tick, int(self.header.start_tick))
            summary = pb.LogSummary(last_tick=last, complete=complete, reason=reason,
                                    event_count=self.event_count)
            self._put(TOPIC_SUMMARY, last, summary.SerializeToString())
            self._mcap.finish()
            self._stream.close()
            os.replace(self.partial, self.path)
        except BaseException:
            self._abort = True
            self._stop_thread()
            self._discard()
            raise

    def flush(self, wait: bool = True) -> threading.Event:
        """Every block written so far into the file (its chunk ended, the file's buffer handed
        to the operating system): a reader of the partial file, or one that recovers it after
        the writer is killed, finds every tick up to the last one written. Waits for it, or
        (``wait=False``) returns at once with an Event set once it is so."""
        self._check()
        done = threading.Event()
        if self._closed:
            done.set()
            return done
        self._queue.put(done)
        if wait:
            done.wait()
            self._check()
        return done

    @property
    def size(self) -> int:
        """Bytes written to the file so far (the blocks still queued for the writer's thread,
        and the chunk it is filling, are not in it yet)."""
        # as the writer's thread last saw it: asking the file here (tell()) would wait for
        # that thread's write to finish (the buffer's lock): 7 ms a tick in a 12,500-ship service
        return self._size

    def abandon(self) -> None:
        """Drop the partial file (an error before anything worth keeping)."""
        if not self._closed:
            self._closed = True
            self._abort = True
            self._stop_thread()
            self._discard()

    def _discard(self) -> None:
        # closing flushes the buffer, which fails again on a full disk: the file goes regardless
        try:
            self._stream.close()
        except OSError:
            pass
        self.partial.unlink(missing_ok=True)



#: the most a writer puts in a chunk before it closes it (LogWriter's chunk_size at most), bytes
CHUNK_BYTES_MAX = 1 << 20


def tick_bytes_bound(ships: int) -> int:
    """The most bytes a tick record of ``ships`` ships holds, with margin: its header, and each
    field's key, length and numbers (every field, a keyframe's too), then a quarter more."""
    per_ship = sum(fields.per_ship(name) * (1 if dt == "u1" else 8) for _, name, dt in PACKED)
    exact = 32 + 16 * len(PACKED) + ships * per_ship
    return exact + exact // 4 + 4096


def _ends_with_magic(s: Structure) -> bool:
    """The file ends with MCAP's magic (finished; a cut file has none: read as a cut)."""
    return not any(p.part == "footer" and "ends without a footer" in p.what for p in s.problems)


class TickData:
    """One TickBatch as read from a log: the raw bytes, decoded only when a field is asked for
    (a verification that finds the bytes identical never decodes them)."""

    def __init__(self, raw: bytes, tick_from_time: int, where: str = "", ships: int = 0,
                 log_format: int = LOG_FORMAT_VERSION, table_size: int = 0):
        self.raw = raw
        self.tick_from_time = tick_from_time
        self._where = where
        self._ships = ships if log_format < 3 else 0  # format 3: the fleet changes
        self._format = log_format
        self._table_size = table_size
        self._decoded: tuple[int, float, int, dict[str, np.ndarray]] | None = None

    def _decode(self) -> tuple[int, float, int, dict[str, np.ndarray]]:
        if self._decoded is None:
            try:
                decoded = decode_tick(self.raw)
            except LogError as exc:
                raise LogError(f"{self._where}: tick {self.tick_from_time}: {exc}") from None
            self._check(*decoded)
            self._decoded = decoded
        return self._decoded

    def _check(self, tick: int, t_s: float, count: int, arrays: dict[str, np.ndarray]) -> None:
        """Every field a tick must hold, each with exactly ship_count x width numbers, the ship
        count the scenario's, the tick its log time's."""
        where = f"{self._where}: tick {self.tick_from_time}"
        if tick != self.tick_from_time:
            raise LogError(f"{where}: the record says tick {tick}")
        if self._ships and count != self._ships:
            raise LogError(f"{where}: {count} ships where the scenario has {self._ships}")
        for name in fields.EVERY_TICK_BY_FORMAT[self._format]:
            if name not in arrays and count:
                raise LogError(f"{where}: field {name} is missing")
        keyframe = [name in arrays for name in fields.KEYFRAME_BY_FORMAT[self._format]]
        if any(keyframe) and not all(keyframe):
            raise LogError(f"{where}: a keyframe with some of its fields missing")
        for name, a in arrays.items():
            width = 1 if (name == "sliding" and self._format < 2) else WIDTH.get(name, 1)
            if a.size != count * width:
                raise LogError(f"{where}: field {name} holds {a.size} numbers for {count} ships")
        if count and (arrays["surface_state"] > 4).any():
            raise LogError(f"{where}: a surface state out of range")
        keys = arrays.get("ship_key")
        if keys is not None and keys.size and (
                keys.min() < 0 or keys.max() >= self._table_size
                or np.unique(keys).size != keys.size):
            raise LogError(f"{where}: ship keys outside the log's {self._table_size} ships, or "
                           f"a ship twice")

    @property
    def tick(self) -> int:
        return self._decode()[0]

    @property
    def t_s(self) -> float:
        return self._decode()[1]

    @property
    def ship_count(self) -> int:
        return self._decode()[2]

    @property
    def arrays(self) -> dict[str, np.ndarray]:
        return self._decode()[3]

    def vec(self, name: str, width: int) -> np.ndarray:
        return self.arrays[name].reshape(self.ship_count, width)

    @property
    def keys(self) -> np.ndarray:
        """The ships of this tick by key (format 3); before it, the header's ships in order."""
        keys = self.arrays.get("ship_key")
        if keys is None:
            return np.arange(self.ship_count, dtype=np.int64)
        return keys

    @property
    def is_keyframe(self) -> bool:
        return all(name in self.arrays for name in fields.KEYFRAME_BY_FORMAT[self._format]) \
            or self.ship_count == 0

    def state(self) -> State:
        """The full state recorded at this tick (a keyframe)."""
        a = self.arrays
        if not self.is_keyframe:
            raise LogError(f"tick {self.tick} is not a keyframe")
        if self.ship_count == 0:
            return State.zeros(0, tick=self.tick)
        try:
            # a field its format does not have (settle_for_s before format 4) starts at zero
            values = {f.name: self.vec(f.in_log, f.per_ship) if f.per_ship > 1 else a[f.in_log]
                      for f in fields.of_record("state")
                      if f.name != "sliding" and (f.in_log in a or f.in_log in
                                                  fields.EVERY_TICK_BY_FORMAT[self._format]
                                                  + fields.KEYFRAME_BY_FORMAT[self._format])}
            values["absorbing"] = values["absorbing"] != 0
            return State.of(self.ship_count, tick=self.tick, sliding=self._sliding(), **values)
        except (KeyError, ValueError) as exc:
            raise LogError(f"tick {self.tick}: incomplete state record ({exc})") from None

    def _sliding(self) -> np.ndarray:
        a = self.arrays["sliding"].astype(bool)
        if a.size == self.ship_count:  # a format-1 log: one regime per ship
            return np.repeat(a[:, None], 4, axis=1)
        return a.reshape(self.ship_count, 4)

    def outputs(self) -> Outputs:
        """What this tick reported (on every tick)."""
        if self.ship_count == 0:
            return Outputs.zeros(0)
        return Outputs.of(self.ship_count, **{
            f.name: self.vec(f.in_log, f.per_ship) if f.per_ship > 1 else self.arrays[f.in_log]
            for f in fields.of_record("outputs")})

    def inputs(self) -> Inputs:
        """The commands applied during the step into this tick."""
        if self.ship_count == 0:
            return Inputs.zeros(0)
        return Inputs.of(self.ship_count, **{
            f.name: self.vec(f.in_log, f.per_ship) if f.per_ship > 1 else self.arrays[f.in_log]
            for f in fields.of_record("inputs")})


class LogReader:
    """Read a Touchdown log. CRCs are checked; any damage raises :class:`LogError`."""

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        try:
            self._file = open(self.path, "rb")
        except OSError as exc:
            raise LogError(f"{self.path}: cannot open: {exc.strerror}") from None
        self.scenario: pb.ScenarioRecord | None = None
        self.summary: pb.LogSummary | None = None
        self.status = ReadStatus()
        # the file's MCAP structure (no decompression): a finished file whose summary or footer
        # is damaged but whose data section is whole is read by walking that section
        self.structure = check_structure(self._file)
        st = self.structure
        self._walk = _ends_with_magic(st) and not st.summary_ok and st.data_end >= 0
        self._largest_record = 0
        for topic, data in self._iter({TOPIC_SCENARIO}):
            self._largest_record = len(data)
            try:
                self.scenario = pb.ScenarioRecord.FromString(data)
            except Exception as exc:
                raise LogError(f"{self.path}: damaged scenario record ({exc})") from None
            break
        if self.scenario is None:
            raise LogError(f"{self.path}: not a Touchdown log (no {TOPIC_SCENARIO} record)")
        self._check_record()

    def _check_record(self) -> None:
        """The scenario record's own numbers, before anything is run on them (the resolved
        scenario itself is checked by scenario_of, by the same rules as a scenario file)."""
        sr, where = self.scenario, f"{self.path}: the scenario record"
        if not 1 <= sr.log_format_version <= LOG_FORMAT_VERSION:
            raise LogError(f"{where}: log format {sr.log_format_version}; this touchdown "
                           f"({PROJECT_VERSION}) reads formats 1 to {LOG_FORMAT_VERSION}")
        if not (math.isfinite(sr.dt_s) and MIN_DT_S <= sr.dt_s <= MAX_DT_S):
            raise LogError(f"{where}: dt_s {sr.dt_s!r} is out of range ({MIN_DT_S:g}..{MAX_DT_S:g} s)")
        least = 1 if sr.log_format_version < 3 else 0  # format 3: ships may all join later
        if not least <= len(sr.ship_ids) <= MAX_SHIPS or len(sr.player_ids) != len(sr.ship_ids):
            raise LogError(f"{where}: {len(sr.ship_ids)} ships, {len(sr.player_ids)} players")
        if sr.keyframe_interval > max(1, sr.n_ticks) and not sr.open_ended:
            raise LogError(f"{where}: keyframe_interval {sr.keyframe_interval} exceeds its "
                           f"{sr.n_ticks} ticks")
        if (sr.start_tick or sr.open_ended) and sr.log_format_version < 3:
            raise LogError(f"{where}: start_tick or open_ended in a log of format "
                           f"{sr.log_format_version} (they are of format 3)")
        if sr.start_tick >= MAX_START_TICK or (sr.start_tick > sr.n_ticks and not sr.open_ended):
            raise LogError(f"{where}: start_tick {sr.start_tick} is past its run's "
                           f"{'limit' if sr.open_ended else f'last tick {sr.n_ticks}'}")
        if len(sr.resolved_json) > MAX_SCENARIO_CHARS:
            raise LogError(f"{where}: its scenario is {len(sr.resolved_json):,} characters "
                           f"(limit {MAX_SCENARIO_CHARS:,})")

    def structure_note(self) -> str:
        """One line if the file's MCAP structure (message indexes, summary, footer) is damaged
        while its content is readable (logs.structure), else "". A cut file (no footer) is not
        said to be damaged here: its readers say what they recovered."""
        return self.structure.line() if _ends_with_magic(self.structure) else ""

    def _iter(self, topics: set[str]) -> Iterator[tuple[str, bytes]]:
        for topic, _t, data in iter_messages(self._file, str(self.path), topics, None, None,
                                             self.status, walk=self._walk):
            yield topic, data

    def messages(self, topics: set[str]) -> Iterator[tuple[str, int, bytes]]:
        """(topic, log time ns, bytes) of the messages on ``topics``, in log order, read as
        every reader of this log reads them (through its index, or by walking its data section
        when its summary or footer is damaged)."""
        yield from iter_messages(self._file, str(self.path), topics, None, None, self.status,
                                 walk=self._walk)

    def raw(self, topic: str, start_ns: int | None = None, end_ns: int | None = None
            ) -> Iterator[tuple[int, bytes]]:
        """(log time ns, message bytes) of one topic's messages, in log order."""
        for _topic, t_ns, data in iter_messages(self._file, str(self.path), {topic}, start_ns,
                                                end_ns, self.status, walk=self._walk):
            yield t_ns, data

    @property
    def keyframe_interval(self) -> int:
        return max(1, int(self.scenario.keyframe_interval))

    @property
    def start_tick(self) -> int:
        """The first tick the log holds (a keyframe): 0, or later for a log that starts with the
        fleet as it is at a later tick (a rotated segment, a worker's takeover, a cut)."""
        return int(self.scenario.start_tick)

    @property
    def open_ended(self) -> bool:
        """The run had no set end (a live service): its end is the summary's last tick."""
        return bool(self.scenario.open_ended)

    def is_keyframe_tick(self, tick: int) -> bool:
        """Whether the writer made ``tick`` a keyframe (its multiples of the interval, and the
        log's first tick)."""
        return tick == self.start_tick or tick % self.keyframe_interval == 0

    def keyframe_at_or_before(self, tick: int) -> int:
        """The keyframe a replay of ``tick`` starts from (never before the log's first tick)."""
        return max(self.start_tick, tick - tick % self.keyframe_interval)

    def tick_time_ns(self, tick: int) -> int:
        return tick * int(round(self.scenario.dt_s * 1e9))

    def ticks(self, first: int | None = None, last: int | None = None) -> Iterator[TickData]:
        """The tick records, optionally only ticks first..last (found through the chunk index,
        without reading the rest of the file)."""
        start = None if first is None else self.tick_time_ns(first)
        end = None if last is None else self.tick_time_ns(last)
        dt_ns = self.tick_time_ns(1)
        ships = len(self.scenario.ship_ids)
        fmt = self.scenario.log_format_version
        table = len(self.ship_table()) if fmt >= 3 else ships
        limit = self.max_tick_bytes()
        for _topic, t_ns, data in iter_messages(self._file, str(self.path), {TOPIC_TICKS}, start,
                                                end, self.status, self._tick_limits(),
                                                walk=self._walk):
            if t_ns % dt_ns:
                raise LogError(f"{self.path}: a tick record at {t_ns} ns, not on the tick")
            if len(data) > limit:
                raise self._oversize(t_ns // dt_ns, len(data))
            yield TickData(data, t_ns // dt_ns, str(self.path), ships, fmt, table)

    def max_tick_bytes(self) -> int:
        """The most bytes a tick record of this log can hold: every ship the log ever held
        (its header's and each that joined), each with every field (sim.fields), with margin."""
        ships = len(self.ship_table()) if self.log_format >= 3 else len(self.scenario.ship_ids)
        return tick_bytes_bound(ships)

    def _oversize(self, tick: int, size: int) -> LogError:
        ships = len(self.ship_table()) if self.log_format >= 3 else len(self.scenario.ship_ids)
        return LogError(f"{self.path}: tick {tick}: a tick record of {size:,} bytes, more than "
                        f"the log's {ships:,} ship(s) can fill ({self.max_tick_bytes():,}); "
                        f"refusing it")

    def _tick_limits(self) -> ReadLimits:
        """The reader's limits for the tick records: a chunk may hold at most what a writer puts
        in one (its target size, then one message more: the largest tick this fleet fills, or
        the log's header), so a chunk claiming more is refused before it is decompressed."""
        base = ReadLimits.from_environment()
        bound = (CHUNK_BYTES_MAX + max(self.max_tick_bytes(), self._largest_record)
                 + (1 << 18))
        if bound >= base.max_chunk_bytes:
            return base
        ships = len(self.ship_table()) if self.log_format >= 3 else len(self.scenario.ship_ids)
        return dataclasses.replace(base, max_chunk_bytes=bound, chunk_bound=(
            f"what a chunk of ticks of this log's {ships:,} ship(s) can hold"))

    def blocks(self, first: int | None = None, last: int | None = None,
               wanted: tuple[str, ...] | None = None, block_bytes: int = 32 << 20,
               reuse: bool = False) -> Iterator[TickBlock]:
        """The tick records (optionally ticks first..last) as columns, about ``block_bytes`` of
        records at a time, each block decoded and checked in one compiled pass
        (logs.decode.decode_block); ``wanted``: the fields to gather (default all). ``reuse``:
        every block's columns in one buffer, valid until the next block is asked for (a reader
        that converts or copies each block at once saves the fresh pages' faults)."""
        start = None if first is None else self.tick_time_ns(first)
        end = None if last is None else self.tick_time_ns(last)
        dt_ns = self.tick_time_ns(1)
        fmt = self.log_format
        table = len(self.ship_table()) if fmt >= 3 else len(self.scenario.ship_ids)
        limit = self.max_tick_bytes()
        # the records are decoded where they lie, in their decompressed chunks: one segment
        # (buffer, begins, ends) per chunk
        segments: list = []
        times: list[int] = []
        size = 0
        columns = [None] if reuse else None
        base = base_arr = None
        begins: list[int] = []
        ends: list[int] = []

        def flush() -> TickBlock:
            ticks = np.asarray(times, np.int64) // dt_ns
            return decode_block(segments, None, ticks, fmt, table, len(self.scenario.ship_ids),
                                wanted, str(self.path), columns)

        for _topic, t_ns, data in iter_messages(self._file, str(self.path), {TOPIC_TICKS}, start,
                                                end, self.status, self._tick_limits(),
                                                views=True, walk=self._walk):
            if t_ns % dt_ns:
                raise LogError(f"{self.path}: a tick record at {t_ns} ns, not on the tick")
            n = len(data)
            if n > limit:
                raise self._oversize(t_ns // dt_ns, n)
            owner = data.obj if isinstance(data, memoryview) else data
            if owner is not base:
                base = owner
                base_arr = np.frombuffer(owner, np.uint8)
                begins, ends = [], []
                segments.append((base_arr, begins, ends))
            at = np.frombuffer(data, np.uint8).ctypes.data - base_arr.ctypes.data if n else 0
            begins.append(at)
            ends.append(at + n)
            times.append(t_ns)
            size += n
            if size >= block_bytes:
                yield flush()
                segments, times, size, base = [], [], 0, None
        if times:
            yield flush()

    @property
    def log_format(self) -> int:
        return int(self.scenario.log_format_version)

    def ship_table(self) -> ShipTable:
        """Every ship of the log by key: the header's, then each that joined (format 3)."""
        if getattr(self, "_table", None) is None:
            table = ShipTable(self.scenario.ship_ids, self.scenario.player_ids)
            self._fleet: list[pb.FleetChange] = []
            if self.log_format >= 3:
                for _topic, data in self._iter({TOPIC_FLEET}):
                    self._largest_record = max(self._largest_record, len(data))
                    change = _parse(pb.FleetChange, data, f"{self.path}: damaged fleet record")
                    for j in change.joined:
                        try:
                            spec = json.loads(j.spec_json)
                        except (ValueError, RecursionError):
                            spec = None
                        if (not isinstance(spec, dict) or spec.get("id") != j.ship_id
                                or j.ship_id in table or j.ship_key != len(table)):
                            raise LogError(f"{self.path}: tick {change.tick}: a joining ship's "
                                           f"record is damaged (ship {j.ship_id!r})")
                        table.add(int(change.tick), spec)
                    self._fleet.append(change)
            self._table = table
        return self._table

    def timeline(self) -> Timeline:
        """The run's recorded input: the ships that joined and left, and every command
        (format 3). Read once (a later call, e.g. while the ticks are being read, reads nothing:
        a file whose footer is missing is read in one pass at a time)."""
        if getattr(self, "_timeline", None) is None:
            self._timeline = self._read_timeline()
        return self._timeline

    def _read_timeline(self) -> Timeline:
        table = self.ship_table()
        spawns, retires = [], []
        for change in self._fleet:
            for j in change.joined:
                spawns.append(Spawn(int(change.tick), table.specs[j.ship_key]))
            for sid in change.left_ship_id:
                retires.append(Retire(int(change.tick), sid))
        commands = []
        for _topic, data in self._iter({TOPIC_COMMANDS}):
            batch = _parse(pb.CommandBatch, data, f"{self.path}: damaged command record")
            for c in batch.commands:
                try:
                    commands.append(Command(int(c.tick), c.ship_id, c.throttle, tuple(c.rcs),
                                            int(c.hold)).check())
                except CommandError as exc:
                    raise LogError(f"{self.path}: {exc}") from None
        return Timeline.of(spawns, retires, commands)

    def events(self) -> Iterator[pb.TransitionEvent]:
        for _topic, data in self._iter({TOPIC_EVENTS}):
            try:
                yield pb.TransitionEvent.FromString(data)
            except Exception as exc:
                raise LogError(f"{self.path}: damaged event record ({exc})") from None

    def read_summary(self) -> pb.LogSummary | None:
        for _topic, data in self._iter({TOPIC_SUMMARY}):
            try:
                self.summary = pb.LogSummary.FromString(data)
            except Exception as exc:
                raise LogError(f"{self.path}: damaged summary record ({exc})") from None
        return self.summary

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> "LogReader":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def fleet_params(reader: LogReader, scn: Scenario) -> Params:
    """The log's scene with every ship it ever held, in key order (row k: ship key k): the
    header's from its scenario, each joined one from the table it joined with."""
    table = reader.ship_table()
    ships = [scn.params.ships]
    for k in range(len(scn.params.ships.ship_id), len(table)):
        try:
            ships.append(scn.scene.ship(table.specs[k])[0])
        except ScenarioError as exc:
            raise LogError(f"{reader.path}: ship {table.ids[k]!r}: {exc}") from None
    return scn.params.with_ships(concatenate(ships))


def keyframe_world(reader: LogReader, scn: Scenario, keyframe: "TickData") -> World:
    """The world a replay folds over from ``keyframe``'s tick (a log that starts later than tick
    0, or a window): its ships in the state recorded there (their parameters from ``scn``, the
    log's scenario, perhaps changed by a what-if, and the tables ships joined with), the commands
    in force then, and the log's joins, leaves and commands after it."""
    world = recorded_world(reader, scn)
    world.params = fleet_params(reader, scn).take(keyframe.keys)
    world.state, world.inputs = keyframe.state(), keyframe.inputs()
    world.timeline = world.timeline.from_tick(keyframe.tick)
    return world


def recorded_world(reader: LogReader, scn: Scenario) -> World:
    """The world a replay folds over: ``scn``'s ships at tick 0 (the log's scenario, perhaps
    changed by a what-if), with the log's recorded joins, leaves and commands (format 3; before
    it, the scenario's own inputs)."""
    world = World.of(scn)
    if reader.log_format >= 3:
        world.timeline = reader.timeline()
        table = reader.ship_table()
        for sid, spec in zip(table.ids, table.specs):
            if spec is not None:
                world.known[sid] = spec
    return world


def _parse(cls, data: bytes, what: str):
    try:
        return cls.FromString(data)
    except Exception as exc:  # protobuf's DecodeError and friends
        raise LogError(f"{what} ({type(exc).__name__})") from None


def scenario_of(reader: LogReader, ship_id: str | None = None,
                overrides: dict | None = None) -> tuple[Scenario, int | None]:
    """The log's scenario (optionally one ship of it, or with ``overrides``); returns it and that
    ship's index. The resolved scenario is checked by the same rules as a scenario file, with the
    same messages, and must agree with its record (tick, tick count, method, ships)."""
    rec = reader.scenario
    try:
        doc = json.loads(rec.resolved_json)
    except RecursionError:
        raise LogError(f"{reader.path}: the recorded scenario is not valid JSON (arrays or "
                       f"objects nested too deeply)") from None
    except ValueError as exc:  # JSONDecodeError, or an integer past Python's digit limit
        raise LogError(f"{reader.path}: the recorded scenario is not valid JSON "
                       f"({str(exc).split(';')[0][:100]})") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("ships"), list):
        raise LogError(f"{reader.path}: the recorded scenario is not a scenario")
    try:
        if not doc["ships"] and reader.log_format >= 3:  # no ships at its first tick
            whole = _without_ships(doc, str(reader.path))
        else:
            whole = parse(doc, str(reader.path))
    except ScenarioError as exc:
        raise LogError(str(exc)) from None
    sim = whole.params.sim
    if (sim.dt_s, sim.n_ticks, sim.integrator, list(whole.params.ships.ship_id)) != (
            rec.dt_s, rec.n_ticks, rec.integrator, list(rec.ship_ids)):
        raise LogError(f"{reader.path}: the scenario record disagrees with its own scenario "
                       f"(tick, tick count, method or ships)")
    index = None
    if ship_id is not None:
        ids = [s.get("id") for s in doc["ships"]]
        if ship_id not in ids:
            raise LogError(f"{reader.path}: no ship {ship_id!r} in this log (ships: "
                           f"{', '.join(map(str, ids))})")
        index = ids.index(ship_id)
        doc["ships"] = [doc["ships"][index]]
    if index is None and not overrides:
        return whole, None
    try:
        if not doc["ships"]:
            return _without_ships(doc, str(reader.path), overrides), index
        return parse(doc, str(reader.path), overrides), index
    except ScenarioError as exc:
        raise LogError(str(exc)) from None


_ON_UNSTABLE = ("substep", "error", "allow")


def _without_ships(doc: dict, source: str, overrides: dict | None = None) -> Scenario:
    """A scenario with no ships (a log whose fleet is empty at its first tick: a live service
    before anything is spawned), which sim.scenario.parse refuses: the scene is checked and
    resolved by the same rules, with a stand-in ship that is then dropped (its own stability is
    allowed, as it never runs); ``resolved`` is the scene with ``ships = []``."""
    from sim.timeline import Timeline
    if overrides:
        from sim.scenario import apply_overrides
        doc = apply_overrides(doc, overrides, source)
    sim = doc.get("sim", {})
    own = sim.get("on_unstable", "substep") if isinstance(sim, dict) else None
    stand_in = {**doc, "ships": [{"id": "(none)"}]}
    if own in _ON_UNSTABLE:
        stand_in["sim"] = {**sim, "on_unstable": "allow"}
    scn = parse(stand_in, source)
    if scn.params.ships.n != 1:  # the stand-in joins later (a spawn time of its own): impossible
        raise ScenarioError(source, "ships", "no ships, and a scene that places none")
    resolved = {**scn.resolved, "sim": {**scn.resolved["sim"], "on_unstable": own}, "ships": []}
    none = np.zeros(1, dtype=bool)
    return Scenario(scn.name, scn.description, resolved, scn.params.take(none),
                    State(rows=scn.initial.select(none).rows, tick=0), Timeline())


__all__ = ["LogWriter", "LogReader", "TickData", "ShipTable", "STATE_ARRAY_FIELDS", "tick_arrays",
           "scenario_of", "scenario_message", "world_header", "fleet_params", "recorded_world",
           "keyframe_world"]
