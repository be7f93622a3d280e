"""The log's format: its topics, its header (the ScenarioRecord: the resolved scenario and the
ships present at its first tick), the messages the writer and the event stream share (a
transition, a ship's state) and the table of every ship a log held by key.

The MCAP log: one ScenarioRecord, one TickBatch per tick, a TransitionEvent per transition, a
FleetChange per tick at which ships join or leave, a CommandBatch per tick with commands, and a
LogSummary at the end. The ScenarioRecord, the joins and leaves and the commands are the run's whole
input: a replay folds the step over them (replay.verify). Chunked, zstd-compressed, CRCs on, protobuf schemas embedded, so that stock
readers (``mcap-protobuf-support``, Foxglove) decode every message without this project.
Written by logs.writer, read by logs.reader; a run is rebuilt from a log by logs.rebuild.

Log times are simulation time, ``tick * dt`` in integer nanoseconds, never the wall clock.
"""
from __future__ import annotations

import copy
import dataclasses
import functools
import itertools
import math
import time
from typing import TYPE_CHECKING, Callable

import numpy as np

from touchdown.logs.codec import PACKED, varint
from touchdown.proto import touchdown_pb2 as pb
from touchdown.sim import __version__ as PROJECT_VERSION
from touchdown.sim import fields
from touchdown.sim.enums import EventKind, SurfaceState
from touchdown.sim.scenario import SHIP, TIMING_KEYS, Scenario, resolve
from touchdown.sim.state import State

if TYPE_CHECKING:  # (sim.world is compiled: a reader of logs loads none of it)
    from touchdown.sim.world import TickRecord, World

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
#: 5 (touchdown 0.7): the keyframes may have a phase (ScenarioRecord.keyframe_phase: keyframes
#: at ticks = phase mod interval), so that a live service's shards encode theirs on different
#: ticks; the fields are 4's. A reader of format 4 would look for keyframes at the multiples of
#: the interval, so such a reader refuses the log by its format number. 6 (touchdown 0.8): an
#: event's tilt_deg is the same bits on every machine (:func:`tilt_deg`); the fields are 5's. A
#: replay rebuilds a format-5 log's events as 0.7 made them, which can differ in the last bits
#: on a machine whose BLAS or libm differs from the recording's.
LOG_FORMAT_VERSION = fields.LOG_FORMAT
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


def keyframe_due(tick: int, interval: int, phase: int = 0) -> bool:
    """Whether ``tick`` is on a log's keyframe grid: tick = phase (mod interval). A log's first
    tick is a keyframe as well, wherever it falls (LogReader.is_keyframe_tick)."""
    return tick % max(1, interval) == phase


def tick_arrays(rec: TickRecord, keys: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Every per-ship array of a TickBatch, by field name (``keys``: the ships' keys)."""
    records = {"state": rec.state, "outputs": rec.outputs, "inputs": rec.inputs}
    arrays = {f.in_log: records[f.record].rows[f.name] for f in fields.FIELDS}
    if keys is not None:
        arrays["ship_key"] = keys
    return arrays


#: the surface states and event topics by number (an enum's call costs a microsecond or two,
#: a ship's event message a few of them: thousands a second when a fleet touches down)
_SURFACE = {int(x): x for x in SurfaceState}
_TOPIC = {int(x): x.topic for x in EventKind}
#: each state's seed string (``SurfaceState.seed_string``, a property of a property)
SEED_STRINGS = {x: x.seed_string for x in SurfaceState}
#: each state's label (``SurfaceState.label``)
LABELS = {x: x.label for x in SurfaceState}
_FLYING = SurfaceState.FLYING


def surface_state(value) -> SurfaceState:
    """``SurfaceState(int(value))``, by a look-up (the same ValueError for a value outside)."""
    got = _SURFACE.get(int(value))
    return got if got is not None else SurfaceState(int(value))


def ship_state_message(ship_id: str, player_id: str, body: str, rec_state, i: int, *,
                       log_format: int = LOG_FORMAT_VERSION) -> pb.ShipState:
    """Ship ``i`` of ``rec_state`` (a State) as a ShipState: its state, position, velocity,
    attitude and rates, and its tilt from local vertical (:func:`tilt_deg`, as a log of
    ``log_format`` has it).

    The ship's record is read once (its row), its numbers taken as Python floats: the same
    IEEE operations, one by one, as on numpy's scalars, so the same bits, at half the cost (a
    test compares them with the field-by-field way)."""
    rows = getattr(rec_state, "rows", None)
    if rows is None:
        return _ship_state_message_fields(ship_id, player_id, body, rec_state, i, log_format)
    return pb.ShipState(**_ship_state_fields(ship_id, player_id, body, rows[i], log_format))


#: the first log format whose events carry a tilt with the same bits on every machine
#: (:func:`tilt_deg`); an older log's events are rebuilt as their version made them
PORTABLE_TILT_FORMAT = 6


def tilt_deg(pos_m: tuple[float, float, float], quat: tuple[float, float, float, float]) -> float:
    """The long axis's tilt from local vertical, degrees: the angle between the body z axis of
    ``quat`` (w, x, y, z) and pos_m / |pos_m|, as atan2(|ez x r_hat|, ez . r_hat) from IEEE
    +, *, / and sqrt only (sim.measure.tilt_from_vertical_rad, compiled).

    Logs of format 5 and before took acos(ez . r_hat) with numpy's dot products, which OpenBLAS
    computes with the kernel it picks for the CPU (fused multiply-adds on AVX2 and AVX-512, a
    plain sum or another order on older ones) and libm's pow and acos: an event's last bits, and
    so ``replay --verify``, depended on the machine. (The compiled module is imported here, at
    the first event: a reader of logs loads none of it.)"""
    from touchdown.sim.measure import tilt_from_vertical_rad
    return math.degrees(float(tilt_from_vertical_rad(np.array([pos_m]), np.array([quat]))[0]))


def _ship_state_fields(ship_id: str, player_id: str, body: str, row, log_format: int) -> dict:
    """ship_state_message's fields (the sub-messages as dicts) from the ship's record row: a
    TransitionEvent given them makes its ``ship`` at once, where a ShipState made first is
    copied into it (1.3 us of an event's 16)."""
    st = surface_state(row["surface_state"])
    p = row["pos_m"]
    q0, q1, q2, q3 = row["quat"].tolist()
    px, py, pz = p.tolist()
    if log_format >= PORTABLE_TILT_FORMAT:
        tilt = tilt_deg((px, py, pz), (q0, q1, q2, q3))
    else:
        # r_hat divided element by element in Python (IEEE division, correctly rounded: the bits
        # of numpy's p / norm), then an array: numpy's division of the record's unaligned view
        # took 6 us of the message's 22 (the dot products stay numpy's, on the same kinds of
        # arrays)
        norm = math.sqrt(float(p @ p))
        r_hat = np.array((px / norm, py / norm, pz / norm))
        ez = np.array([2 * (q1 * q3 + q0 * q2), 2 * (q2 * q3 - q0 * q1),
                       1 - 2 * (q1 ** 2 + q2 ** 2)])
        tilt = math.degrees(math.acos(max(-1.0, min(1.0, float(ez @ r_hat)))))
    vx, vy, vz = row["vel_mps"].tolist()
    wx, wy, wz = row["omega_body_radps"].tolist()
    return dict(
        ship_id=ship_id, player_id=player_id,
        landed_body_name="" if st is _FLYING else body,
        position_m={"x": px, "y": py, "z": pz}, velocity_mps={"x": vx, "y": vy, "z": vz},
        attitude={"w": q0, "x": q1, "y": q2, "z": q3},
        omega_body_radps={"x": wx, "y": wy, "z": wz},
        mass_kg=float(row["mass_kg"]), fuel_kg=float(row["fuel_kg"]), state=int(st),
        tilt_deg=tilt, surface_contact_state=SEED_STRINGS[st])


def _ship_state_message_fields(ship_id: str, player_id: str, body: str, rec_state, i: int,
                               log_format: int = LOG_FORMAT_VERSION) -> pb.ShipState:
    """ship_state_message field by field, on numpy's scalars (any object with the State's
    fields as arrays)."""
    st = SurfaceState(int(rec_state.surface_state[i]))
    p, v, q, w = (rec_state.pos_m[i], rec_state.vel_mps[i], rec_state.quat[i],
                  rec_state.omega_body_radps[i])
    if log_format >= PORTABLE_TILT_FORMAT:
        tilt = tilt_deg(tuple(p.tolist()), tuple(q.tolist()))
    else:
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


def event_message(ships: "ShipTable", body: str, dt_s: float, state: State, ev, *,
                  log_format: int = LOG_FORMAT_VERSION) -> pb.TransitionEvent:
    """A transition as the log and the event stream carry it (as a log of ``log_format`` has
    it: a replay rebuilds an older log's events as that log's version made them)."""
    ship_id = ev.ship_id
    player_id = ships.players[ships.key(ship_id)]
    topic = _TOPIC.get(int(ev.kind))
    rows = getattr(state, "rows", None)
    ship = (ship_state_message(ship_id, player_id, body, state, ev.ship, log_format=log_format)
            if rows is None else
            _ship_state_fields(ship_id, player_id, body, rows[ev.ship], log_format))
    return pb.TransitionEvent(
        event=EventKind(ev.kind).topic if topic is None else topic, tick=ev.tick,
        t_s=ev.tick * dt_s, ship_id=ship_id,
        player_id=player_id, body=body, from_state=ev.from_state, to_state=ev.to_state,
        ship=ship,
        v_radial_mps=ev.v_radial_mps, t_event_s=ev.t_event_s)


def scenario_message(scn: Scenario, source: str, keyframe_interval: int = 1,
                     keyframe_phase: int = 0) -> pb.ScenarioRecord:
    """The log's header: the resolved scenario and the ships present at tick 0."""
    from touchdown.logs.encode import canonical_json  # (a writer's: mcap's writer, 18 ms)
    return pb.ScenarioRecord(
        log_format_version=LOG_FORMAT_VERSION, project_version=PROJECT_VERSION, name=scn.name,
        description=scn.description, resolved_json=canonical_json(scn.resolved).decode(),
        integrator=scn.params.sim.integrator, dt_s=scn.params.sim.dt_s,
        ship_ids=list(scn.params.ships.ship_id), player_ids=list(scn.params.ships.player_id),
        body=scn.params.body.name, source=source, n_ticks=scn.params.sim.n_ticks,
        keyframe_interval=keyframe_interval, keyframe_phase=_phase(keyframe_interval,
                                                                   keyframe_phase))


def _phase(interval: int, phase: int) -> int:
    if not 0 <= phase < max(1, interval):
        raise ValueError(f"keyframe phase {phase}: not in 0..{max(1, interval) - 1}")
    return phase


def world_header(*args, **kwargs) -> pb.ScenarioRecord:
    """The header of a log of a world from its current tick (world_header_later's arguments)."""
    header, json_of = world_header_later(*args, **kwargs)
    header.resolved_json = json_of().decode()
    return header


def world_header_later(world: World, name: str, source: str, keyframe_interval: int = 1,
                       open_ended: bool = False, description: str = "",
                       end_tick: int | None = None, tables: dict[str, dict] | None = None,
                       keyframe_phase: int = 0) -> tuple[pb.ScenarioRecord, Callable[[], bytes]]:
    """(the header without its ``resolved_json``, the function that makes that JSON as UTF-8:
    every ship's table joined, 13 MB at 20,000 ships; :func:`record_bytes` splices it in; a
    rotating log's writer makes all of it, ships included: :func:`world_record_later`). The header of a log of ``world`` from its current tick
    (``start_tick``): the resolved scene
    with ``ships`` the tables of the ships present now (their timing keys removed: when they join,
    leave and what they are commanded is the log's own record; their ``initial`` tables are
    irrelevant, as the state comes from the log's first tick record, a keyframe). The world may
    have no ships. ``open_ended``: the run has no set end (a live service); ``end_tick``: the
    run's last tick when not the scene's ``duration`` (a cut: n_ticks is set to it);
    ``tables``: ship id -> its resolved table, a cache kept across the headers of one world
    (each ship is resolved once: 10,000 ships take about half a second); ``keyframe_phase``:
    the keyframes after the first fall on ticks = phase (mod keyframe_interval)."""
    doc, sim = _header_doc(world, name, description, end_tick)
    ids = list(world.ship_ids)
    resolved = _with_ships(doc, ids, world.known, tables, source or name)
    header = _header_message(world, name, source, doc, sim, keyframe_interval, open_ended,
                             keyframe_phase)
    header.ship_ids.extend(ids)
    header.player_ids.extend(world.params.ships.player_id)
    from touchdown.logs.encode import resolved_json_bytes  # (a writer's: mcap's writer, 18 ms)
    return header, functools.partial(resolved_json_bytes, resolved, ids, tables)


def world_record_later(world: World, name: str, source: str, keyframe_interval: int = 1,
                       open_ended: bool = False, description: str = "",
                       end_tick: int | None = None, tables: dict[str, dict] | None = None,
                       keyframe_phase: int = 0) -> tuple[pb.ScenarioRecord, Callable[[], bytes]]:
    """(the header without its ships, the function that makes the whole header's bytes: the
    ``world_header(...).SerializeToString()`` of the same arguments; LogWriter's ``record``).

    Everything a header does once per ship is left to that function, for a writer's thread:
    the check that each ship's table is in ``tables`` (and the resolving of those that are
    not, ``world.known``'s tables of them), the list of tables, the ids in the record and the
    JSON. A rotation of a 20,000-ship shard's log spent ~5 ms of the service's tick on them
    (session 36). The header returned has everything else (its ``ship_ids``, ``player_ids``
    and ``resolved_json`` empty): fields set on it before the function runs (a shard's take)
    are in the bytes. ``tables`` is then the writer's thread's (a RotatingLog's headers are
    made one after the other on its Runner); an error in resolving is raised by the function."""
    doc, sim = _header_doc(world, name, description, end_tick)
    header = _header_message(world, name, source, doc, sim, keyframe_interval, open_ended,
                             keyframe_phase)
    # (the world's own tuples and table dict: the fleet is a new tuple when it changes, and
    # ``known`` only grows; a world replaced later leaves these as they are)
    return header, functools.partial(_record_of, header, doc, world.ship_ids,
                                     world.params.ships.player_id, world.known, tables,
                                     source or name)


#: ships a call over them takes at a time on a writer's thread (each such call holds the GIL
#: throughout: 2-5 ms at 50,000 ships, which the service's tick would wait for)
_PIECE = 8192


def _record_of(header: pb.ScenarioRecord, doc: dict, ids: tuple[str, ...],
               players: tuple[str, ...], known: dict[str, dict], tables: dict | None,
               source: str) -> bytes:
    """world_record_later's bytes, on a writer's thread (a piece of the ships at a time, the
    GIL let go between pieces)."""
    ids = list(ids)
    cache = {} if tables is None else tables
    pieces = range(0, len(ids), _PIECE)
    if all([_let_go(all(map(cache.__contains__, ids[a:a + _PIECE]))) for a in pieces]):
        resolved = {**doc, "ships": list(itertools.chain.from_iterable(
            [_let_go(list(map(cache.__getitem__, ids[a:a + _PIECE]))) for a in pieces]))}
    else:  # (some to resolve: a ship joined since; world_header_later's way)
        resolved = _with_ships(doc, ids, known, cache, source)
    whole = pb.ScenarioRecord()
    whole.CopyFrom(header)
    for a in pieces:
        whole.ship_ids.extend(ids[a:a + _PIECE])
        whole.player_ids.extend(_let_go(players[a:a + _PIECE]))
    from touchdown.logs.encode import resolved_json_bytes
    return record_bytes(whole, resolved_json_bytes(resolved, ids, tables))


def _let_go(value):
    """``value``, once the GIL has been let go (to a thread waiting for it: the tick)."""
    time.sleep(0)
    return value


def _header_doc(world: World, name: str, description: str, end_tick: int | None):
    """The header's scene (no ships) and its sim parameters (cut at ``end_tick``)."""
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
    return doc, sim


def _with_ships(doc: dict, ids: list[str], known: dict[str, dict], tables: dict | None,
                source: str) -> dict:
    """``doc`` with ``ships`` the tables of ``ids`` from ``tables`` (a cache: those missing
    resolved by the scenario's rules from ``known``'s tables, and kept in it)."""
    cache = {} if tables is None else tables
    missing = [] if all(map(cache.__contains__, ids)) else [sid for sid in ids if sid not in cache]
    if missing:  # resolved by the scenario's rules, with its messages (not built: resolve)
        found = resolve({**doc, "ships": [{k: v for k, v in known[sid].items()
                                           if k not in TIMING_KEYS} for sid in missing]},
                        source)["ships"]
        got = [t["id"] for t in found]
        if got != missing:
            raise ValueError(f"the world's ships {missing[:5]} resolve to {got[:5]}")
        cache.update(zip(missing, found))
    # no ships (yet): the scene alone, which the log's reader accepts (scenario_of)
    return {**doc, "ships": list(map(cache.__getitem__, ids))}


def _header_message(world: World, name: str, source: str, doc: dict, sim,
                    keyframe_interval: int, open_ended: bool,
                    keyframe_phase: int) -> pb.ScenarioRecord:
    """The header's fields but its ships and its JSON."""
    return pb.ScenarioRecord(
        log_format_version=LOG_FORMAT_VERSION, project_version=PROJECT_VERSION, name=name,
        description=doc.get("description", ""), integrator=sim.integrator,
        dt_s=sim.dt_s, body=world.params.body.name, source=source, n_ticks=sim.n_ticks,
        keyframe_interval=keyframe_interval, start_tick=world.tick, open_ended=open_ended,
        keyframe_phase=_phase(keyframe_interval, keyframe_phase))


#: what a ship's timing keys resolve to when a table is resolved without them (the defaults)
_TIMING_DEFAULTS = {key: SHIP[key][1] for key in TIMING_KEYS}


def header_table(resolved_table: dict) -> dict:
    """A ship's table as world_header_later resolves it (its table resolved again without its
    timing keys, which then take their defaults), from its resolved table (a scenario's
    ``resolved["ships"]``, as World.of keeps them in ``known``): the same table, made without
    resolving it again (a service's first headers resolved every ship: 0.3 s a 12,500-ship
    shard). tests/test_log_header_tables.py holds it to world_header_later's own."""
    return {**resolved_table, **{key: copy.copy(value) for key, value in _TIMING_DEFAULTS.items()}}


def record_bytes(header: pb.ScenarioRecord, resolved_json: bytes) -> bytes:
    """``header`` serialized with its ``resolved_json`` set to these UTF-8 bytes, byte for byte
    what the protobuf library writes (its fields in number order: 1-4, the JSON as field 5,
    then 6 on), without making a protobuf string of the JSON's megabytes (a copy, a UTF-8
    check and another copy, each holding the GIL)."""
    if header.resolved_json:
        raise ValueError("the header already holds its resolved_json")
    head = pb.ScenarioRecord(log_format_version=header.log_format_version,
                             project_version=header.project_version, name=header.name,
                             description=header.description).SerializeToString()
    whole = header.SerializeToString()
    if not whole.startswith(head):
        raise ValueError("the header's first fields are not where field 5 goes")
    field = b"\x2a" + varint(len(resolved_json)) if resolved_json else b""
    return b"".join((head, field, resolved_json, whole[len(head):]))


class ShipTable:
    """Every ship of a log by key: the header's ships (keys 0, 1, ...), then each that joined, in
    the order they joined. ``specs[k]``: the table a joining ship came with (None for the
    header's, whose tables are in the resolved scenario)."""

    def __init__(self, ids=(), players=()):
        self.ids: list[str] = list(ids)
        self.players: list[str] = list(players)
        self.specs: list[dict | None] = [None] * len(self.ids)
        self.joined: list[int] = [0] * len(self.ids)
        self._key = dict(zip(self.ids, range(len(self.ids))))
        # the tuple of ids the table was made of (a World's ship_ids), whose keys are 0, 1, ...
        # for good (joins come after): :meth:`keys` of it is a range, not a look-up an id
        self._made_of = (ids if isinstance(ids, tuple) and len(self._key) == len(ids)
                         else None)

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
        if ship_ids is self._made_of and ship_ids:  # (a new file's first block: 2.6 ms at
            return np.arange(len(ship_ids), dtype=np.int64)  # 20,000 ships, looked up)
        return np.fromiter((self._key[s] for s in ship_ids), np.int64, len(ship_ids))

    def __contains__(self, ship_id: str) -> bool:
        return ship_id in self._key

    def __len__(self) -> int:
        return len(self.ids)


#: the most a writer puts in a chunk before it closes it (LogWriter's chunk_size at most), bytes
CHUNK_BYTES_MAX = 1 << 20


def tick_bytes_bound(ships: int) -> int:
    """The most bytes a tick record of ``ships`` ships holds, with margin: its header, and each
    field's key, length and numbers (every field, a keyframe's too), then a quarter more."""
    per_ship = sum(fields.per_ship(name) * (1 if dt == "u1" else 8) for _, name, dt in PACKED)
    exact = 32 + 16 * len(PACKED) + ships * per_ship
    return exact + exact // 4 + 4096


__all__ = ["LOG_FORMAT_VERSION", "TOPIC_SCENARIO", "TOPIC_TICKS", "TOPIC_EVENTS", "TOPIC_SUMMARY",
           "TOPIC_FLEET", "TOPIC_COMMANDS", "KEYFRAME_ONLY", "WIDTH", "keyframe_due",
           "tick_arrays", "ship_state_message", "surface_state", "event_message",
           "scenario_message", "world_header", "world_header_later", "world_record_later",
           "header_table", "record_bytes", "ShipTable", "CHUNK_BYTES_MAX", "tick_bytes_bound"]
