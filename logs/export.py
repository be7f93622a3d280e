"""JSON Lines export of a log (SPEC.md section 4): one object per ship per tick, or per event.

Positions, velocities, angular velocities and energy come from the logged state through the same
``sim`` functions the step uses (sim.measure: the site frame, sim.energy), with the parameters of the
log's own recorded scenario; the columnar export (below, what the command line runs) computes the
same numbers, bit for bit, in numpy (logs.derived), and loads no compiled code for Parquet or CSV.
A field the log does not hold on a tick (a format-1 log's velocities between keyframes) is null.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import IO, Iterator

import numpy as np

from touchdown.logs import LogError, derived
from touchdown.logs.reader import LogReader, TickData
from touchdown.logs.rebuild import fleet_params, log_params, scenario_of
from touchdown.proto import touchdown_pb2 as pb
from touchdown.sim import fields, trig
from touchdown.sim.enums import SurfaceState

_STATE = {int(s): s.label for s in SurfaceState}


#: the log's quantities that export names as they are (sim.fields), the state as its label
EXPORTED = tuple(f for f in fields.FIELDS if f.export)
#: what export derives from the logged state: (key, quantity, component)
DERIVED = (("east", "pos", 0), ("north", "pos", 1), ("up", "pos", 2), ("v_east", "vel", 0),
           ("v_north", "vel", 1), ("v_up", "vel", 2), ("omega_x", "omega", 0),
           ("omega_y", "omega", 1), ("omega_z", "omega", 2))


def _derived(params, td: TickData) -> dict[str, np.ndarray] | None:
    """Site-frame position and velocity, body rates and energy of every ship at one tick
    (``params``: every ship of the log in key order, logs.rebuild.fleet_params), by the compiled
    functions of sim.measure (the reference logs.derived is held to)."""
    from touchdown.sim import measure
    from touchdown.sim.dynamics import Motion
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
        e = measure.energy(params, td.keys, t, Motion(p, v, q, w), a["mass_kg"])
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
            row = {"tick": td.tick, "t": td.t_s, "ship_id": ids[key],
                   "tilt_deg": math.degrees(trig.acos(float(a["cos_tilt"][i])))}
            for f in EXPORTED:
                x = a.get(f.in_log)  # a format-1 log has no energy_guard_j
                row[f.export] = None if x is None else (
                    _STATE[int(x[i])] if f.name == "surface_state" else float(x[i]))
            for name, arr, k in DERIVED:
                row[name] = None if d is None else float(d[arr][i, k])
            row["energy_j"] = None if d is None else float(d["energy"][i])
            yield row


def event_rows(reader: LogReader, read: list[bytes] | None = None) -> Iterator[dict]:
    """One row per event (``read``: the event records already read, LogReader.events)."""
    for ev in reader.events(read):
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



# -- columnar export: blocks of ticks as columns (logs.decode), to Parquet, CSV or JSON Lines ------
# The path above (a dict per row) is the reference the columnar one is tested against; the command
# line uses this one.

#: the tick table's columns, in JSON Lines' key order: (name, unit, what it is)
TICK_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("tick", "", "tick number"),
    ("t", "s", "simulated time of the tick"),
    ("ship_id", "", "the ship"),
    ("tilt_deg", "deg", "long axis from local vertical"),
) + tuple((f.export, f.unit, f.doc) for f in EXPORTED) + (
    ("east", "m", "centre of mass in the landing-site frame (body-fixed)"),
    ("north", "m", "centre of mass in the landing-site frame (body-fixed)"),
    ("up", "m", "centre of mass above the reference sphere under the site"),
    ("v_east", "m/s", "velocity relative to the surface, site frame"),
    ("v_north", "m/s", "velocity relative to the surface, site frame"),
    ("v_up", "m/s", "velocity relative to the surface, site frame"),
    ("omega_x", "rad/s", "angular velocity (inertial rate), body frame"),
    ("omega_y", "rad/s", "angular velocity (inertial rate), body frame"),
    ("omega_z", "rad/s", "angular velocity (inertial rate), body frame"),
    ("energy_j", "J", "mechanical energy in the body's turning frame (MODEL-NOTES 28)"),
)
TICK_NAMES = tuple(name for name, _, _ in TICK_COLUMNS)
#: the event table's columns: (name, unit, what it is)
EVENT_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("event", "", "ship.contact, ship.landed, ship.tipped, ship.righted, ship.crashed, "
                  "ship.liftoff"),
    ("tick", "", "the tick it is reported at"),
    ("t", "s", "the tick's time"),
    ("t_event", "s", "the instant it happened inside the tick"),
    ("ship_id", "", "the ship"), ("player_id", "", "its player"), ("body", "", "the body"),
    ("from_state", "", "state before"), ("to_state", "", "state after"),
    ("v_radial", "m/s", "speed along local up at the transition (+ = up)"),
    ("tilt_deg", "deg", "tilt at the transition"),
    ("surface_contact_state", "", "the seed's string for the new state"),
)
EVENT_NAMES = tuple(name for name, _, _ in EVENT_COLUMNS)
STATE_LABELS = tuple(SurfaceState(i).label for i in range(len(SurfaceState)))
#: the log fields each kind of column is made from
_BASE_FIELDS = ("surface_state", "cos_tilt") + tuple(f.in_log for f in EXPORTED)
_DERIVED_FIELDS = ("pos_m", "vel_mps", "quat", "omega_body_radps", "mass_kg")
#: every log field the tick table is made from
SOURCE_FIELDS = _BASE_FIELDS + _DERIVED_FIELDS
_SITE = ("east", "north", "up", "v_east", "v_north", "v_up")
_OMEGA = ("omega_x", "omega_y", "omega_z")
FORMATS = ("jsonl", "csv", "parquet")


def parse_fields(text: str | None, known: tuple[str, ...] = TICK_NAMES) -> tuple[str, ...]:
    """``--fields a,b,c`` as the table's columns in its order; ValueError naming an unknown one."""
    if not text:
        return known
    asked = [f.strip() for f in text.split(",") if f.strip()]
    bad = [f for f in asked if f not in known]
    if bad:
        raise ValueError(f"--fields: no field {bad[0]!r} (fields: {', '.join(known)})")
    if not asked:
        raise ValueError("--fields: no field named")
    return tuple(n for n in known if n in asked)


@dataclass
class Selection:
    """What of a log to export: ships (ids; None: every ship), ticks first..last (None: to the
    log's end), the columns (in the table's order)."""

    ships: tuple[str, ...] | None = None
    first: int | None = None
    last: int | None = None
    columns: tuple[str, ...] = TICK_NAMES


@dataclass
class ColumnBlock:
    """Rows of the tick table: ``columns`` name -> numpy array; ``ship_id`` and ``state`` as
    int32 indices into ``TableInfo.ship_ids`` and STATE_LABELS; ``missing`` name -> bool mask of
    rows the log does not hold that number on (a format-1 log's velocities between keyframes)."""

    rows: int
    columns: dict[str, np.ndarray]
    missing: dict[str, np.ndarray]
    first_tick: int
    last_tick: int
    #: (rows, 4) each row's attitude as a body -> landing-site quaternion (x, y, z, w), when
    #: asked for (tick_blocks' ``attitude``): what a 3-D view turns a ship's frame by
    quat_site_xyzw: np.ndarray | None = None
    #: the ships' keys, one per row (ship_id holds them as int32)
    keys: np.ndarray | None = None


@dataclass
class TableInfo:
    path: str
    ship_ids: list[str]
    columns: tuple[str, ...]
    metadata: dict[str, str]
    #: the columns that may hold a null (a number the log does not hold on some tick); every
    #: other column is declared without nulls (Parquet's ``required``)
    nullable: tuple[str, ...] = ()


def table_info(reader: LogReader, columns: tuple[str, ...] = TICK_NAMES) -> TableInfo:
    sr = reader.scenario
    return TableInfo(str(reader.path), reader.ship_table().ids, columns, {
        "touchdown.log": str(reader.path), "touchdown.scenario": sr.name,
        "touchdown.project_version": sr.project_version,
        "touchdown.log_format_version": str(sr.log_format_version),
        "touchdown.integrator": sr.integrator, "touchdown.dt_s": repr(sr.dt_s),
        "touchdown.body": sr.body}, nullable_columns(reader.log_format))


def nullable_columns(log_format: int) -> tuple[str, ...]:
    """The tick table's columns made from a field the log need not hold on every tick (a
    format-1 log's velocities, between keyframes; its energy_guard_j, never): the ones a tick
    table of a log of ``log_format`` may hold a null in."""
    every = fields.EVERY_TICK_BY_FORMAT[log_format]
    out = [f.export for f in EXPORTED if f.in_log not in every]
    if "vel_mps" not in every or "omega_body_radps" not in every:
        out += [*_SITE[3:], *_OMEGA, "energy_j"]
    return tuple(n for n in TICK_NAMES if n in out)


def tick_blocks(reader: LogReader, sel: Selection = Selection(),
                block_bytes: int = 64 << 20, attitude: bool = False,
                events: list | None = None) -> Iterator[ColumnBlock]:
    """The tick table of ``reader`` as blocks of columns (module comment above), each block
    decoded as its chunks are read (LogReader.blocks). A number that is not finite (only a
    damaged log holds one) is a LogError naming the tick, ship and field. ``attitude``: each
    block also holds each row's attitude in the landing-site frame (ColumnBlock.quat_site_xyzw).
    ``events``: a list the event records of the same ticks are appended to, read in the same
    pass (LogReader.blocks). Every block's columns lie in the same buffers: a block is valid
    until the next one is asked for (fresh arrays for each block cost a page fault per 4 kB
    of them: a tenth of a Parquet export, measured)."""
    ids = reader.ship_table().ids
    cols = sel.columns
    need = attitude or any(c in _SITE or c in _OMEGA or c == "energy_j" for c in cols)
    params = log_params(reader) if need else None
    wanted = _BASE_FIELDS + (_DERIVED_FIELDS if need else ())
    keep_keys = None
    scratch: dict[str, np.ndarray] = {}  # the blocks' columns, one buffer each
    if sel.ships is not None:
        table = reader.ship_table()
        for sid in sel.ships:
            if sid not in table:
                raise LogError(f"{reader.path}: no ship {sid!r} in this log (ships: "
                               f"{', '.join(ids[:10])}{', ...' if len(ids) > 10 else ''})")
        keep_keys = np.array(sorted(table.key(s) for s in sel.ships), np.int64)
    for b in reader.blocks(sel.first, sel.last, wanted=wanted, block_bytes=block_bytes,
                           reuse=True, events=events):
        if keep_keys is not None:
            b = b.take(np.flatnonzero(np.isin(b.keys, keep_keys)))
        if b.rows == 0:
            continue
        blk = _columns(reader, b, cols, params, ids, scratch)
        blk.keys = b.keys
        if attitude:
            from touchdown.sim import measure  # compiled: a 3-D view's attitudes
            t = np.repeat(b.t_s, b.counts)
            c, s_ = measure.body_angles(params, t, b.rows)
            blk.quat_site_xyzw = measure.site_quats_xyzw(b.columns["quat"], c, s_)
        yield blk


def _columns(reader: LogReader, b, cols: tuple[str, ...], params, ids,
             scratch: dict[str, np.ndarray] | None = None) -> ColumnBlock:
    R = b.rows
    out: dict[str, np.ndarray] = {}
    missing: dict[str, np.ndarray] = {}
    c = b.columns
    scratch = {} if scratch is None else scratch

    def column(name: str, dtype=np.float64) -> np.ndarray:
        """The block's column ``name``: R numbers in the buffer kept for it."""
        buf = scratch.get(name)
        if buf is None or buf.shape[0] < R or buf.dtype != dtype:
            buf = scratch[name] = np.empty(R + R // 8, dtype)
        return buf[:R]

    def per_row(name: str, per_tick: np.ndarray) -> np.ndarray:
        """Each tick's number on each of its rows (np.repeat, into its buffer)."""
        a = column(name, per_tick.dtype)
        for k, (lo, hi) in enumerate(zip(b.row_off[:-1].tolist(), b.row_off[1:].tolist())):
            a[lo:hi] = per_tick[k]
        return a

    tick = per_row("tick", b.ticks)
    t = per_row("t", b.t_s)
    whole = np.ones(R, bool)
    # (a field on every tick: no per-row mask to make, the common case)
    present_rows = {name: whole if p.all() else np.repeat(p, b.counts)
                    for name, p in b.present.items()}
    for name in cols:
        if name == "tick":
            out[name] = tick
        elif name == "t":
            out[name] = t
        elif name == "ship_id":
            out[name] = column(name, np.int32)
            out[name][:] = b.keys
        elif name == "tilt_deg":
            out[name] = derived.tilt_deg(c["cos_tilt"].reshape(R), column(name))
    for f in EXPORTED:
        if f.export not in cols:
            continue
        if f.name == "surface_state":
            out[f.export] = column(f.export, np.int32)
            out[f.export][:] = c[f.in_log].reshape(R)
            continue
        a = c.get(f.in_log)
        if a is None or not b.present[f.in_log].all():  # a format-1 log has no energy_guard_j
            has = present_rows.get(f.in_log, np.zeros(R, bool))
            missing[f.export] = ~has
            a = np.zeros((R, 1)) if a is None else a
        out[f.export] = a.reshape(R)
    if any(n in cols for n in _SITE + _OMEGA + ("energy_j",)):
        p, v = c["pos_m"], c["vel_mps"]
        q, w = c["quat"], c["omega_body_radps"]
        has_v = present_rows["vel_mps"] & present_rows["omega_body_radps"]
        with np.errstate(all="ignore"):  # a damaged log's overflow is named below, in one line
            cos_t, sin_t = derived.body_angles(params, t)
            if any(n in cols for n in _SITE):
                out.update(zip(_SITE, derived.site_frame(params, p, v, cos_t, sin_t,
                                                         tuple(column(n) for n in _SITE))))
            for k, name in enumerate(_OMEGA):
                out[name] = column(name)
                out[name][:] = w[:, k]
            if "energy_j" in cols:
                out["energy_j"] = derived.energy(params, b.keys, p, v, q, w,
                                                 c["mass_kg"].reshape(R), cos_t, sin_t,
                                                 column("energy_j"))
        if not has_v.all():
            for name in _SITE[3:] + _OMEGA + ("energy_j",):
                missing[name] = ~has_v
    out = {name: out[name] for name in cols}
    for name, a in out.items():
        if a.dtype.kind != "f":
            continue
        with np.errstate(all="ignore"):
            if np.isfinite(np.add.reduce(a)):  # every number finite (a sum that overflows
                continue  # or meets a NaN or an infinity is looked at number by number)
        bad = ~np.isfinite(a)
        if name in missing:
            bad &= ~missing[name]
        if bad.any():
            r = int(np.argmax(bad))
            raise LogError(f"{reader.path}: tick {int(tick[r])}, ship {ids[int(b.keys[r])]}: "
                           f"{name} is {float(a[r])} (the log is damaged)")
    return ColumnBlock(R, out, {k: v for k, v in missing.items() if k in out},
                       int(b.ticks[0]), int(b.ticks[-1]))


# -- writers ---------------------------------------------------------------------------------------

def arrow_schema(info: TableInfo, events: bool = False):
    """The table's Arrow schema: every field with its unit (and what it is) in its metadata; the
    log, its scenario, project version and format in the schema's."""
    import pyarrow as pa
    spec = EVENT_COLUMNS if events else TICK_COLUMNS
    types = {"tick": pa.int64(), "ship_id": pa.dictionary(pa.int32(), pa.string()),
             "state": pa.dictionary(pa.int32(), pa.string())}
    if events:
        types = {"tick": pa.int64()}
    out = []
    for name, unit, doc in spec:
        if name not in info.columns:
            continue
        typ = types.get(name, pa.string() if events and name not in (
            "t", "t_event", "v_radial", "tilt_deg") else pa.float64())
        out.append(pa.field(name, typ, nullable=events or name in info.nullable,
                            metadata={"unit": unit, "description": doc}))
    return pa.schema(out, metadata=info.metadata)


class _ArrowBlocks:
    """Blocks of the tick table as Arrow record batches."""

    def __init__(self, info: TableInfo, dictionary: bool = True):
        import pyarrow as pa
        self.pa = pa
        self.ids = pa.array(info.ship_ids, pa.string())
        self.states = pa.array(list(STATE_LABELS), pa.string())
        self.schema = arrow_schema(info)
        if not dictionary:
            self.schema = pa.schema([f.with_type(pa.string()) if pa.types.is_dictionary(f.type)
                                     else f for f in self.schema], metadata=self.schema.metadata)
        self.dictionary = dictionary

    def batch(self, blk: ColumnBlock):
        pa = self.pa
        arrays = []
        for f in self.schema:
            a = blk.columns[f.name]
            if f.name in ("ship_id", "state"):
                values = self.ids if f.name == "ship_id" else self.states
                idx = pa.array(a, pa.int32())
                arrays.append(pa.DictionaryArray.from_arrays(idx, values) if self.dictionary
                              else values.take(idx))
            else:
                mask = blk.missing.get(f.name)
                if mask is not None and not f.nullable:  # pragma: no cover - nullable_columns
                    raise AssertionError(f"{f.name}: a null in a column declared without")
                arrays.append(pa.array(a, f.type, mask=mask))
        return pa.RecordBatch.from_arrays(arrays, schema=self.schema)


#: the tick table's zstd level: one of zstd's fast levels. The fleet's 2,001,000 rows of 26
#: columns: 77.7 MB (level 1: 67.6 MB, level -1: 72.3 MB; snappy, pyarrow's and DuckDB's own
#: default, 105.5 MB; the log itself 123 MB), written in 0.22 CPU s (level 1: 0.34 s), and read
#: back twice as fast as level 1's (pyarrow's read_table 0.11 s against 0.21 s; DuckDB the same
#: way): the same codec, which every Parquet reader reads (docs/SPEED.md, "Replay and the logs' commands")
PARQUET_LEVEL = -4


def write_parquet(blocks: Iterator[ColumnBlock], info: TableInfo, path: str) -> int:
    """The tick table to a Parquet file, block by block (a row group each), zstd at
    PARQUET_LEVEL; dictionaries for ship_id and state only (a float column gains nothing by
    one), statistics for tick and t only (what a reader selects row groups by)."""
    import pyarrow.parquet as pq
    conv = _ArrowBlocks(info)
    n = 0
    with pq.ParquetWriter(path, conv.schema, compression="zstd",
                          compression_level=PARQUET_LEVEL, use_dictionary=["ship_id", "state"],
                          write_statistics=["tick", "t"], store_schema=True) as w:
        for blk in blocks:
            w.write_batch(conv.batch(blk), row_group_size=blk.rows)
            n += blk.rows
    return n


def write_csv(blocks: Iterator[ColumnBlock], info: TableInfo, out) -> int:
    """The tick table as CSV (a header line, then a line per row), block by block; ``out`` a
    binary file."""
    import pyarrow.csv as pcsv
    conv = _ArrowBlocks(info, dictionary=False)
    n = 0
    with pcsv.CSVWriter(out, conv.schema) as w:
        for blk in blocks:
            w.write_batch(conv.batch(blk))
            n += blk.rows
    return n


def write_jsonl_blocks(blocks: Iterator[ColumnBlock], info: TableInfo, out) -> int:
    """The tick table as JSON Lines, the same objects (keys, order, values) as :func:`tick_rows`
    with :func:`write_jsonl` gives; each block's columns formatted at once (Arrow's shortest
    round-trip text of doubles) and interleaved into lines by a compiled pass, then written at
    once. ``out``: a binary file."""
    import pyarrow as pa
    import pyarrow.compute as pc

    from touchdown.logs.json_lines import json_lines
    ids = pa.array([json.dumps(s) for s in info.ship_ids], pa.string())
    states = pa.array([json.dumps(s) for s in STATE_LABELS], pa.string())
    keys = [("{" if k == 0 else ",") + json.dumps(name) + ":" for k, name in
            enumerate(info.columns)]
    key_bytes = np.frombuffer("".join(keys).encode(), np.uint8)
    key_off = np.zeros(len(keys) + 1, np.int64)
    np.cumsum([len(k.encode()) for k in keys], out=key_off[1:])
    n = 0
    buf = np.empty(0, np.uint8)
    for blk in blocks:
        R = blk.rows
        texts, kinds = [], []
        missing = np.zeros((len(info.columns), R), bool)
        for k, name in enumerate(info.columns):
            a = blk.columns[name]
            if name == "ship_id":
                texts.append(ids.take(pa.array(a, pa.int32())))
            elif name == "state":
                texts.append(states.take(pa.array(a, pa.int32())))
            else:
                texts.append(pc.cast(pa.array(a), pa.string()))
            kinds.append(1 if a.dtype.kind == "f" else 0)
            if name in blk.missing:
                missing[k] = blk.missing[name]
        offsets = np.empty((len(texts), R + 1), np.int64)
        bases = np.zeros(len(texts) + 1, np.int64)
        datas = []
        for k, t in enumerate(texts):
            t = t.combine_chunks() if isinstance(t, pa.ChunkedArray) else t
            off = np.frombuffer(t.buffers()[1], np.int32)[t.offset:t.offset + R + 1]
            offsets[k] = off
            data = np.frombuffer(t.buffers()[2], np.uint8) if t.buffers()[2] is not None \
                else np.zeros(0, np.uint8)
            datas.append(data)
            bases[k + 1] = bases[k] + data.shape[0]
        data = np.concatenate(datas) if datas else np.zeros(0, np.uint8)
        kinds_a = np.asarray(kinds, np.int64)
        size = json_lines(offsets, data, bases, kinds_a, missing, key_bytes, key_off, None)
        if buf.shape[0] < size:  # one buffer for every block: fresh pages fault as they fill
            buf = np.empty(size + size // 4, np.uint8)
        json_lines(offsets, data, bases, kinds_a, missing, key_bytes, key_off, buf[:size])
        out.write(memoryview(buf[:size]))
        n += R
    return n


def event_table(reader: LogReader, ships: tuple[str, ...] | None = None,
                first: int | None = None, last: int | None = None,
                read: list[bytes] | None = None) -> dict[str, list]:
    """The events (optionally of some ships, in ticks first..last) as columns (``read``: the
    event records already read with the ticks, tick_blocks' ``events``)."""
    cols: dict[str, list] = {name: [] for name in EVENT_NAMES}
    for row in event_rows(reader, read):
        if ships is not None and row["ship_id"] not in ships:
            continue
        if (first is not None and row["tick"] < first) or (last is not None and
                                                           row["tick"] > last):
            continue
        for name in EVENT_NAMES:
            cols[name].append(row[name])
    return cols


def write_events(cols: dict[str, list], info: TableInfo, fmt: str, out) -> int:
    """The event table in ``fmt``; ``out`` a path (parquet) or a binary file."""
    n = len(cols["event"])
    if fmt == "jsonl":
        for k in range(n):
            row = {name: cols[name][k] for name in info.columns}
            try:
                line = json.dumps(row, separators=(",", ":"), allow_nan=False)
            except ValueError:
                bad = next(c for c in info.columns if isinstance(row[c], float)
                           and not math.isfinite(row[c]))
                raise LogError(f"{info.path}: tick {cols['tick'][k]}, ship "
                               f"{cols['ship_id'][k]}: event {bad} is {row[bad]} (the log is "
                               f"damaged)") from None
            out.write((line + "\n").encode())
        return n
    import pyarrow as pa
    schema = arrow_schema(info, events=True)
    table = pa.Table.from_arrays([pa.array(cols[f.name], f.type) for f in schema], schema=schema)
    if fmt == "parquet":
        import pyarrow.parquet as pq
        pq.write_table(table, out, compression="zstd")
    else:
        import pyarrow.csv as pcsv
        pcsv.write_csv(table, out)
    return n


__all__ = ["tick_rows", "event_rows", "write_jsonl", "what_was_read", "pb", "Selection",
           "tick_blocks", "table_info", "write_parquet", "write_csv", "write_jsonl_blocks",
           "event_table", "write_events", "parse_fields", "TICK_COLUMNS", "EVENT_COLUMNS",
           "FORMATS"]
