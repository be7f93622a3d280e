"""Compiled reading of tick records: a block of ``TickBatch`` messages decoded in one pass into
numpy columns, as :mod:`logs.codec` writes them.

Two compiled passes over the block's bytes, each linear in them (no input makes either loop
longer than its bytes):

1. :func:`_scan` walks every message's fields once: the header (tick, time, ship count), and for
   each packed field where its numbers start and how many bytes they take. Anything the writer
   never produces (an unknown wire type, an unpacked element, a field twice, a length past the
   message, a one-byte enum past 127, a varint of more than ten bytes) stops it with an error code
   and the message's index.
2. :func:`_gather` copies each wanted field's numbers into its column, one row per ship-tick
   (ticks one after another): the wire's little-endian words are the column's own bytes.

The checks :class:`logs.reader.TickData` makes of one tick (every field a tick must hold, each
with ship count x width numbers, a known surface state, ship keys in the log's table and no ship
twice) are made over the whole block at once (:func:`check_block`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from touchdown.logs import LogError
from touchdown.logs.codec import PACKED
from touchdown.sim import fields
from touchdown.sim.compiled import separate

#: packed fields by their index in PACKED
NAMES: tuple[str, ...] = tuple(name for _, name, _ in PACKED)
INDEX: dict[str, int] = {name: f for f, name in enumerate(NAMES)}
#: bytes per number on the wire (1: an enum or a bool as a one-byte varint; 8: a double or int64)
WIRE = np.array([1 if dt == "u1" else 8 for _, _, dt in PACKED], np.int64)
#: numpy dtype of each column as the wire holds it
DTYPE = tuple(np.dtype({"u1": np.uint8, "<f8": np.float64, "<i8": np.int64}[dt])
              for _, _, dt in PACKED)
_NUM_INDEX = np.full(64, -1, np.int64)
for _f, (_num, _name, _dt) in enumerate(PACKED):
    _NUM_INDEX[_num] = _f

#: what an error code from :func:`_scan` means
ERRORS = {
    1: "truncated varint in a tick record",
    2: "malformed varint in a tick record",
    3: "unpacked field in a tick record",
    4: "truncated fixed64 in a tick record",
    5: "a packed field runs past the end of its tick record",
    6: "a packed field holds a value out of range",
    7: "a packed field has a length that is not whole numbers",
    8: "a packed field appears twice in a tick record",
    9: "unsupported wire type in a tick record",
    10: "tick record ends inside a field",
}


@separate
def _varint(data, i, end):
    """(value, next index, error): a varint of at most ten bytes starting at ``i``."""
    result = np.uint64(0)
    shift = np.uint64(0)
    for _ in range(10):
        if i >= end:
            return result, i, 1
        b = np.uint64(data[i])
        i += 1
        result |= (b & np.uint64(0x7F)) << shift
        if not (b & np.uint64(0x80)):
            return result, i, 0
        shift += np.uint64(7)
    return result, i, 2


@separate
def _scan(data, begins, ends, num_index, wire, header, t_at, starts, lengths):
    """Fields of every message ``data[begins[k]:ends[k]]``: ``header[k]`` = (tick, ship
    count), ``t_at[k]`` where its time's 8 bytes are (-1: absent, 0.0), ``starts[k, f]`` and
    ``lengths[k, f]`` where field f's numbers are (start -1: absent). Returns (error code, the
    message it is in); (0, -1) when all is well."""
    nf = starts.shape[1]
    for k in range(begins.shape[0]):
        i, end = begins[k], ends[k]
        header[k, 0] = 0
        header[k, 1] = 0
        t_at[k] = -1
        for f in range(nf):
            starts[k, f] = -1
            lengths[k, f] = 0
        while i < end:
            key, i, err = _varint(data, i, end)
            if err:
                return err, k
            num = key >> np.uint64(3)
            wt = key & np.uint64(7)
            f = num_index[num] if num < np.uint64(64) else -1
            if wt == 0:
                val, i, err = _varint(data, i, end)
                if err:
                    return err, k
                if num == 1:
                    header[k, 0] = np.int64(val)
                elif num == 3:
                    header[k, 1] = np.int64(val)
                elif f >= 0:
                    return 3, k
            elif wt == 1:
                if i + 8 > end:
                    return 4, k
                if num == 2:
                    t_at[k] = i
                i += 8
            elif wt == 2:
                length, i, err = _varint(data, i, end)
                if err:
                    return err, k
                if length > np.uint64(end - i):
                    return 5, k
                n = np.int64(length)
                if f >= 0:
                    if starts[k, f] >= 0:
                        return 8, k
                    if wire[f] == 1:
                        for j in range(i, i + n):
                            if data[j] > 127:
                                return 6, k
                    elif n % 8:
                        return 7, k
                    starts[k, f] = i
                    lengths[k, f] = n
                i += n
            elif wt == 5:
                i += 4
            else:
                return 9, k
        if i != end:
            return 10, k
    return 0, -1


@separate
def _gather(data, starts, lengths, row_bytes, fields_, bases, out):
    """Copy field ``fields_[j]``'s numbers of every message to ``out[bases[j] + row_bytes[k, j]:]``
    (its column, at the message's first row)."""
    for j in range(fields_.shape[0]):
        f = fields_[j]
        for k in range(starts.shape[0]):
            s = starts[k, f]
            if s < 0:
                continue
            n = lengths[k, f]
            o = bases[j] + row_bytes[k, j]
            out[o:o + n] = data[s:s + n]


@separate
def _keys_unique(keys, row_off, table_size, seen):
    """-1 if every message's keys are in 0..table_size-1 with no key twice, else the first
    message at fault. ``seen``: table_size int64, any contents."""
    for j in range(seen.shape[0]):
        seen[j] = -1
    for k in range(row_off.shape[0] - 1):
        for r in range(row_off[k], row_off[k + 1]):
            key = keys[r]
            if key < 0 or key >= table_size or seen[key] == k:
                return k
            seen[key] = k
    return -1


def scan(data: np.ndarray, begins: np.ndarray, ends: np.ndarray
         ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(ticks, t_s, counts, starts, lengths) of the messages ``data[begins[k]:ends[k]]``
    (``data`` uint8). LogError (``"message k: what"``) on anything the writer never writes."""
    k = begins.shape[0]
    header = np.empty((k, 2), np.int64)
    t_at = np.empty(k, np.int64)
    starts = np.empty((k, len(PACKED)), np.int64)
    lengths = np.empty((k, len(PACKED)), np.int64)
    err, at = _scan(data, begins, ends, _NUM_INDEX, WIRE, header, t_at, starts, lengths)
    if err:
        raise _ScanError(int(at), ERRORS[int(err)])
    t_s = np.zeros(k)
    has_t = t_at >= 0
    if has_t.any():
        t_s[has_t] = data[t_at[has_t, None] + np.arange(8)].view("<f8").ravel()
    return header[:, 0], t_s, header[:, 1], starts, lengths


class _ScanError(LogError):
    def __init__(self, message: int, what: str):
        super().__init__(what)
        self.message = message


def decode_one(data: bytes) -> tuple[int, float, int, dict[str, np.ndarray]]:
    """One TickBatch as (tick, t_s, ship_count, arrays by field name): float64 or int64 arrays,
    as :func:`decode_tick` has always given them. LogError on malformed bytes."""
    buf = np.frombuffer(data, np.uint8)
    ticks, t_s, counts, starts, lengths = scan(buf, np.zeros(1, np.int64),
                                               np.array([buf.size], np.int64))
    arrays = {}
    for f, name in enumerate(NAMES):
        s = starts[0, f]
        if s < 0:
            continue
        raw = buf[s:s + lengths[0, f]]
        if WIRE[f] == 1:
            arrays[name] = raw.astype(np.int64)
        else:
            a = raw.view(DTYPE[f])
            arrays[name] = a.astype(np.float64) if DTYPE[f].kind == "f" else a.astype(np.int64)
    return int(ticks[0]), float(t_s[0]), int(counts[0]), arrays


def decode_tick(data: bytes) -> tuple[int, float, int, dict[str, np.ndarray]]:
    """Parse one TickBatch into (tick, t_s, ship_count, arrays); arrays are float64 or int64.

    Strict: unknown wire types, out-of-range lengths, a field twice, unpacked elements and one-byte
    fields past 127 (none of which the writer produces) raise LogError. Compiled
    (decode_one): any message costs a pass over its bytes at compiled speed."""
    return decode_one(bytes(data))


@dataclass
class TickBlock:
    """Consecutive tick records as columns: ship-tick rows, tick after tick.

    ``ticks``, ``t_s``, ``counts`` (K,); rows ``row_off[k]:row_off[k + 1]`` are tick k's ships;
    ``keys`` (R,) the ships by key; ``columns[name]`` (R, width) as on the wire (float64, int64
    or uint8); ``present[name]`` (K,) bool: the tick holds the field (keyframe-only fields hold
    zeros where absent)."""

    ticks: np.ndarray
    t_s: np.ndarray
    counts: np.ndarray
    row_off: np.ndarray
    keys: np.ndarray
    columns: dict[str, np.ndarray]
    present: dict[str, np.ndarray]

    @property
    def rows(self) -> int:
        return int(self.row_off[-1])

    def tick(self, k: int) -> "BlockTick":
        """The block's k-th tick, as a TickData-like view (tick, keys, arrays by field)."""
        return BlockTick(self, k)

    def tick_of_row(self) -> np.ndarray:
        return np.repeat(self.ticks, self.counts)

    def take(self, rows: np.ndarray) -> "TickBlock":
        """The block's rows ``rows`` (sorted): a block whose ticks are those holding them (the
        ticks with none dropped, except that an empty block keeps nothing)."""
        tick_of = np.repeat(np.arange(self.ticks.shape[0]), self.counts)[rows]
        counts_all = np.bincount(tick_of, minlength=self.ticks.shape[0])
        keep = counts_all > 0
        counts = counts_all[keep]
        row_off = np.zeros(counts.shape[0] + 1, np.int64)
        np.cumsum(counts, out=row_off[1:])
        return TickBlock(self.ticks[keep], self.t_s[keep], counts, row_off, self.keys[rows],
                         {n: c[rows] for n, c in self.columns.items()},
                         {n: p[keep] for n, p in self.present.items()})


class BlockTick:
    """One tick of a TickBlock: ``tick`` (= ``tick_from_time``, checked when decoded),
    ``ship_count``, ``keys`` and ``arrays`` (the fields it holds, flat, as TickData has them)."""

    def __init__(self, block: TickBlock, k: int):
        self.tick = self.tick_from_time = int(block.ticks[k])
        self.t_s = float(block.t_s[k])
        self.ship_count = int(block.counts[k])
        lo, hi = block.row_off[k], block.row_off[k + 1]
        self.keys = block.keys[lo:hi]
        self.arrays = {name: col[lo:hi].ravel() for name, col in block.columns.items()
                       if block.present[name][k]}

    def vec(self, name: str, width: int) -> np.ndarray:
        return self.arrays[name].reshape(self.ship_count, width)


def width_of(name: str, log_format: int) -> int:
    """Numbers per ship of a packed field in a log of ``log_format`` (``sliding``: one per ship
    before format 2)."""
    return 1 if (name == "sliding" and log_format < 2) else fields.per_ship(name)


def decode_block(data, offsets: np.ndarray | None, tick_from_time: np.ndarray,
                 log_format: int, table_size: int, header_ships: int = 0,
                 wanted: tuple[str, ...] | None = None, where: str = "",
                 out: list | None = None) -> TickBlock:
    """Decode and check the messages ``data[offsets[k]:offsets[k + 1]]`` (or, ``offsets``
    None, ``data`` a list of segments ``(buffer, begins, ends)``: messages
    ``buffer[begins[k]:ends[k]]``, e.g. where they lie in their decompressed chunks), whose log
    times say they are ticks ``tick_from_time``; ``wanted``: the columns to gather (default every
    field the format has). Checks as TickData does, each failure a LogError naming the tick.
    ``out``: a one-item list holding a buffer to reuse for the columns (grown as needed; the
    block's columns are then valid only until the next block decoded into it)."""
    segments = [(data, offsets[:-1], offsets[1:])] if offsets is not None else data
    parts, first = [], 0
    for seg, begins, ends in segments:
        try:
            parts.append(scan(seg, np.ascontiguousarray(begins, np.int64),
                              np.ascontiguousarray(ends, np.int64)))
        except _ScanError as exc:
            raise LogError(f"{where}: tick {int(tick_from_time[first + exc.message])}: "
                           f"{exc}") from None
        first += len(begins)
    ticks, t_s, counts, starts, lengths = (np.concatenate([p[i] for p in parts])
                                           for i in range(5))
    k = ticks.shape[0]

    def fail(i: int, what: str):
        raise LogError(f"{where}: tick {int(tick_from_time[i])}: {what}")

    bad = np.flatnonzero(ticks != tick_from_time)
    if bad.size:
        fail(bad[0], f"the record says tick {int(ticks[bad[0]])}")
    if log_format < 3 and header_ships:
        bad = np.flatnonzero(counts != header_ships)
        if bad.size:
            fail(bad[0], f"{int(counts[bad[0]])} ships where the scenario has {header_ships}")
    every = fields.EVERY_TICK_BY_FORMAT[log_format]
    kf = fields.KEYFRAME_BY_FORMAT[log_format]
    has = starts >= 0
    for name in every:
        bad = np.flatnonzero(~has[:, INDEX[name]] & (counts > 0))
        if bad.size:
            fail(bad[0], f"field {name} is missing")
    kf_has = has[:, [INDEX[n] for n in kf]]
    bad = np.flatnonzero(kf_has.any(axis=1) & ~kf_has.all(axis=1))
    if bad.size:
        fail(bad[0], "a keyframe with some of its fields missing")
    widths = np.array([width_of(n, log_format) for n in NAMES], np.int64)
    expect = counts[:, None] * widths[None, :] * WIRE[None, :]
    bad_k, bad_f = np.nonzero(has & (lengths != expect))
    if bad_k.size:
        f = int(bad_f[0])
        fail(bad_k[0], f"field {NAMES[f]} holds {int(lengths[bad_k[0], f] // WIRE[f])} numbers "
                       f"for {int(counts[bad_k[0]])} ships")
    row_off = np.zeros(k + 1, np.int64)
    np.cumsum(counts, out=row_off[1:])
    rows = int(row_off[-1])
    names = list(wanted) if wanted is not None else [n for n in NAMES if n in every or n in kf]
    for must in ("surface_state", "ship_key"):
        if must not in names and (must in every):
            names.append(must)
    idx = np.array([INDEX[n] for n in names], np.int64)
    col_bytes = rows * widths[idx] * WIRE[idx]
    bases = np.zeros(idx.shape[0], np.int64)
    padded = (col_bytes + 7) // 8 * 8
    np.cumsum(padded[:-1], out=bases[1:])
    row_bytes = row_off[:-1, None] * (widths[idx] * WIRE[idx])[None, :]
    need = int(padded.sum()) + 8
    if out is not None:
        if out[0] is None or out[0].shape[0] < need:
            out[0] = np.empty(need + need // 4, np.uint8)
        buf = out[0]
        missing = has[:, idx].all(axis=0) if k else np.ones(idx.shape[0], bool)
        for j in np.flatnonzero(~missing):  # a field absent on some ticks: zeros there
            buf[bases[j]:bases[j] + col_bytes[j]] = 0
    else:
        buf = np.zeros(need, np.uint8)
    row_bytes = np.ascontiguousarray(row_bytes)
    m = 0
    for seg, begins, _ in segments:
        n = len(begins)
        _gather(seg, starts[m:m + n], lengths[m:m + n], row_bytes[m:m + n], idx, bases, buf)
        m += n
    columns, present = {}, {}
    for j, name in enumerate(names):
        f = INDEX[name]
        w = int(widths[f])
        raw = buf[bases[j]:bases[j] + col_bytes[j]]
        columns[name] = raw.view(DTYPE[f]).reshape(rows, w)
        present[name] = has[:, f]
    states = columns["surface_state"]
    if rows and states.max(initial=0) > 4:
        r = int(np.argmax(states.ravel() > 4))
        fail(int(np.searchsorted(row_off, r, side="right") - 1), "a surface state out of range")
    if "ship_key" in every:
        keys = columns["ship_key"].reshape(rows)
        at = _keys_unique(keys, row_off, table_size, np.empty(max(table_size, 1), np.int64))
        if at >= 0:
            fail(at, f"ship keys outside the log's {table_size} ships, or a ship twice")
    else:
        keys = (np.arange(rows, dtype=np.int64) - np.repeat(row_off[:-1], counts))
    return TickBlock(ticks, t_s, counts, row_off, keys, columns, present)


__all__ = ["TickBlock", "decode_block", "decode_one", "decode_tick", "scan", "width_of", "NAMES",
           "INDEX"]
