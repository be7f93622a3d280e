"""Reading of tick records: a block of ``TickBatch`` messages decoded into numpy columns, as
:mod:`logs.codec` writes them, in plain Python and numpy (no compiled code: a reader of a log's
numbers starts in a tenth of a second, not half a second).

1. :class:`_Scanner` finds every message's fields: the header (tick, time, ship count), and for
   each packed field where its numbers start and how many bytes they take. A message is walked
   field by field once (:func:`_scan_one`); the messages of a log share a handful of layouts (a
   fleet's ticks differ in their numbers, not in where their fields lie), so a walked message's
   layout is then checked against the others in one numpy comparison of the bytes that decide
   the walk (every key and length; the tick's varint by its continuation bits) and taken for
   those that agree. Anything the writer never produces (an unknown wire type, an unpacked
   element, a field twice, a length past the message, a one-byte enum past 127, a varint of
   more than ten bytes) is an error code and the message's index. A message of more fields than
   a writer writes (only a hostile one), or more layouts than a log has, goes to the compiled
   scan (logs.scan_compiled): no input costs more than a pass over its bytes.
2. :class:`BlockDecoder` copies each wanted field's numbers of each message into its column,
   one row per ship-tick, as the messages arrive (a chunk's messages are copied while the chunk
   is in cache, and its buffer is then free: logs.safe_read.ChunkBuffers): the wire's
   little-endian words are the column's own bytes.

The checks :class:`logs.reader.TickData` makes of one tick (every field a tick must hold, each
with ship count x width numbers, a known surface state, ship keys in the log's table and no ship
twice) are made over the whole block at once (:meth:`BlockDecoder.finish`), in the same order,
with the same messages, as the compiled decoder made them (a test holds the two to each other).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from touchdown.logs import LogError
from touchdown.logs.codec import PACKED
from touchdown.sim import fields

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

#: what an error code of a scan means (_scan_one; logs.scan_compiled.scan_messages)
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


#: most fields a message is walked for in Python (a TickBatch holds at most 36)
PY_FIELDS = 64
#: most messages of a block walked in Python (a log's records have a few layouts each block)
PY_MESSAGES = 64
_U64 = (1 << 64) - 1
_LONG = -1  # _scan_one: more than PY_FIELDS fields
_NUM_LIST = _NUM_INDEX.tolist()
_WIRE_LIST = WIRE.tolist()
_NF = len(PACKED)


class _Layout(NamedTuple):
    """Where a walked message's fields lie, relative to its start, and the bytes that decided
    the walk: a message of the same length holding the same bytes there (and continuation bits
    in its tick's varint) is walked the same way."""

    length: int
    count: int
    tick_at: np.ndarray  # the bytes of the (last) tick varint (none: no tick, 0) ...
    tick_shift: np.ndarray  # ... and their shifts
    t_at: int  # the time's 8 bytes (-1: absent)
    starts: np.ndarray  # (NF,) -1: absent
    lengths: np.ndarray  # (NF,)
    at: np.ndarray  # the bytes that decided the walk ...
    mask: np.ndarray  # ... the bits of each that did (0xFF; a tick's byte: its continuation) ...
    want: np.ndarray  # ... and those bits
    u1: list  # (start, length) of each one-byte field: its values checked per message


def varint(data, i: int, end: int) -> tuple[int, int, int]:
    """(value, next index, error): a varint of at most ten bytes starting at ``i`` (as a uint64:
    the bits past 64 dropped)."""
    result = shift = 0
    for _ in range(10):
        if i >= end:
            return result & _U64, i, 1
        b = data[i]
        i += 1
        result |= (b & 0x7F) << shift
        if b < 0x80:
            return result & _U64, i, 0
        shift += 7
    return result & _U64, i, 2


def _int64(v: int) -> int:
    return v - (1 << 64) if v >= 1 << 63 else v


def _scan_one(mv, data: np.ndarray, i: int, end: int) -> tuple[int, _Layout | None]:
    """(error code, layout) of the message ``data[i:end]`` (``mv``: a memoryview of ``data``);
    error ``_LONG`` for more than PY_FIELDS fields. The walk of
    logs.scan_compiled.scan_messages, field by field."""
    begin = i
    count = 0
    tick_at, tick_bytes, t_at = -1, 0, -1
    starts, lengths = [-1] * _NF, [0] * _NF
    fixed, flags, u1 = [], [], []
    for _ in range(PY_FIELDS):
        if i >= end:
            break
        k0 = i
        key, i, err = varint(mv, i, end)
        if err:
            return err, None
        fixed.extend(range(k0, i))
        num, wt = key >> 3, key & 7
        f = _NUM_LIST[num] if num < 64 else -1
        if wt == 0:
            v0 = i
            val, i, err = varint(mv, i, end)
            if err:
                return err, None
            if num == 1:
                tick_at, tick_bytes = v0, i - v0  # (its value: read with the layout)
                flags.extend(range(v0, i))
            else:
                fixed.extend(range(v0, i))
                if num == 3:
                    count = val
                elif f >= 0:
                    return 3, None
        elif wt == 1:
            if i + 8 > end:
                return 4, None
            if num == 2:
                t_at = i
            i += 8
        elif wt == 2:
            l0 = i
            n, i, err = varint(mv, i, end)
            if err:
                return err, None
            fixed.extend(range(l0, i))
            if n > end - i:
                return 5, None
            if f >= 0:
                if starts[f] >= 0:
                    return 8, None
                if _WIRE_LIST[f] == 1:
                    if n and data[i:i + n].max() > 127:
                        return 6, None
                    if n:
                        u1.append((i - begin, n))
                elif n % 8:
                    return 7, None
                starts[f] = i - begin
                lengths[f] = n
            i += n
        elif wt == 5:
            i += 4
        else:
            return 9, None
    else:
        if i < end:
            return _LONG, None
    if i != end:
        return 10, None
    at = np.array(fixed + flags, np.int64) - begin
    mask = np.array([0xFF] * len(fixed) + [0x80] * len(flags), np.uint8)
    tick_at = np.arange(tick_bytes, dtype=np.int64) + (tick_at - begin)
    return 0, _Layout(end - begin, _int64(count), tick_at,
                      np.arange(tick_bytes, dtype=np.uint64) * np.uint64(7),
                      t_at - begin if t_at >= 0 else -1, np.array(starts, np.int64),
                      np.array(lengths, np.int64), at, mask, data[begin + at] & mask, u1)


class _Scan(NamedTuple):
    ticks: np.ndarray
    t_s: np.ndarray
    counts: np.ndarray
    starts: np.ndarray  # (K, NF), absolute; -1: absent
    lengths: np.ndarray  # (K, NF)
    error: tuple[int, int] | None  # (message index, error code): the first
    layout: _Layout | None = None  # the one layout of every message, if they share one


class _Scanner:
    """Scans messages a segment at a time (module docstring, 1), keeping the layouts found for
    the next segments (a block's records share them); at most PY_MESSAGES walked in Python."""

    def __init__(self):
        self.layouts: list[_Layout] = []
        self.walked = 0

    def scan(self, data: np.ndarray, begins: np.ndarray, ends: np.ndarray) -> _Scan:
        if self.layouts:  # the common case: every message as the last one walked
            same = self._same(self.layouts[0], data, begins, ends)
            if same is not None:
                return same
        k = begins.shape[0]
        header = np.zeros((k, 2), np.int64)
        t_at = np.full(k, -1, np.int64)
        starts = np.full((k, _NF), -1, np.int64)
        lengths = np.zeros((k, _NF), np.int64)
        todo = np.ones(k, bool)
        size = ends - begins
        error = None
        u1_bad = k  # the first message whose one-byte numbers are past 127

        def take(lay: _Layout, idx: np.ndarray) -> None:
            """The messages ``idx`` that agree with ``lay``: their fields, from it."""
            nonlocal u1_bad
            if not idx.size:
                return
            b = begins[idx]
            if lay.at.size:
                ok = ((data[b[:, None] + lay.at] & lay.mask) == lay.want).all(axis=1)
                if not ok.all():
                    idx, b = idx[ok], b[ok]
                    if not idx.size:
                        return
            todo[idx] = False
            if lay.tick_at.size:
                raw = (data[b[:, None] + lay.tick_at] & 0x7F).astype(np.uint64)
                header[idx, 0] = np.bitwise_or.reduce(raw << lay.tick_shift, axis=1).view(
                    np.int64)
            header[idx, 1] = lay.count
            if lay.t_at >= 0:
                t_at[idx] = b + lay.t_at
            starts[idx] = np.where(lay.starts >= 0, b[:, None] + lay.starts, -1)
            lengths[idx] = lay.lengths
            if lay.u1:
                parts = [data[x + s:x + s + n] for x in b.tolist() for s, n in lay.u1]
                if np.concatenate(parts).max() > 127:
                    bad = next(j for j, p in enumerate(parts) if p.max() > 127)
                    u1_bad = min(u1_bad, int(idx[bad // len(lay.u1)]))

        for lay in self.layouts:
            take(lay, np.flatnonzero(todo & (size == lay.length)))
        compiled = []
        mv = memoryview(data)
        first = 0
        while True:
            rest = np.flatnonzero(todo[first:])
            if not rest.size:
                break
            first += int(rest[0])
            if self.walked >= PY_MESSAGES:  # more layouts than a log has: the rest compiled
                compiled.extend(np.flatnonzero(todo).tolist())
                break
            self.walked += 1
            todo[first] = False
            err, lay = _scan_one(mv, data, int(begins[first]), int(ends[first]))
            if err == _LONG:
                compiled.append(first)
                continue
            if err:
                error = (first, err)
                break
            todo[first] = True
            self.layouts.insert(0, lay)
            take(lay, np.flatnonzero(todo & (size == lay.length)))
        if compiled:
            idx = np.array(compiled, np.int64)
            if error is not None:
                idx = idx[idx < error[0]]
            err, at = _compiled(data, begins[idx], ends[idx], header, t_at, starts, lengths, idx)
            if err and (error is None or at < error[0]):
                error = (at, err)
        if u1_bad < k and (error is None or u1_bad < error[0]):
            error = (u1_bad, 6)
        t_s = np.zeros(k)
        has_t = t_at >= 0
        if has_t.any():
            t_s[has_t] = data[t_at[has_t, None] + np.arange(8)].view("<f8").ravel()
        return _Scan(header[:, 0], t_s, header[:, 1], starts, lengths, error)


    @staticmethod
    def _same(lay: _Layout, data: np.ndarray, begins: np.ndarray, ends: np.ndarray
              ) -> _Scan | None:
        """The messages' fields if every one of them agrees with ``lay``, else None."""
        k = begins.shape[0]
        if not k or not (ends - begins == lay.length).all():
            return None
        if lay.at.size and not ((data[begins[:, None] + lay.at] & lay.mask) == lay.want).all():
            return None
        if lay.u1 and np.concatenate([data[x + s:x + s + n] for x in begins.tolist()
                                      for s, n in lay.u1]).max() > 127:
            return None  # (the general path names the message)
        if lay.tick_at.size:
            raw = (data[begins[:, None] + lay.tick_at] & 0x7F).astype(np.uint64)
            ticks = np.bitwise_or.reduce(raw << lay.tick_shift, axis=1).view(np.int64)
        else:
            ticks = np.zeros(k, np.int64)
        if lay.t_at >= 0:
            t_s = data[(begins + lay.t_at)[:, None] + np.arange(8)].view("<f8").ravel()
        else:
            t_s = np.zeros(k)
        starts = np.where(lay.starts >= 0, begins[:, None] + lay.starts, -1)
        return _Scan(ticks, t_s, np.full(k, lay.count, np.int64), starts,
                     np.broadcast_to(lay.lengths, (k, _NF)), None, lay)


def _compiled(data, begins, ends, header, t_at, starts, lengths, idx) -> tuple[int, int]:
    """The messages ``idx`` scanned by the compiled scan (logs.scan_compiled), into the rows
    ``idx`` of the outputs; (error code, message index) of the first error, (0, -1) if none."""
    from touchdown.logs.scan_compiled import scan_messages
    k = idx.shape[0]
    h, t, s, n = (np.empty((k, 2), np.int64), np.empty(k, np.int64),
                  np.empty((k, _NF), np.int64), np.empty((k, _NF), np.int64))
    err, at = scan_messages(data, np.ascontiguousarray(begins), np.ascontiguousarray(ends),
                            _NUM_INDEX, WIRE, h, t, s, n)
    done = idx if not err else idx[:at]
    m = done.shape[0]
    header[done], t_at[done], starts[done], lengths[done] = h[:m], t[:m], s[:m], n[:m]
    return int(err), (int(idx[at]) if err else -1)


def scan(data: np.ndarray, begins: np.ndarray, ends: np.ndarray
         ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(ticks, t_s, counts, starts, lengths) of the messages ``data[begins[k]:ends[k]]``
    (``data`` uint8). LogError (``"message k: what"``) on anything the writer never writes."""
    res = _Scanner().scan(data, np.asarray(begins, np.int64), np.asarray(ends, np.int64))
    if res.error is not None:
        raise _ScanError(*res.error)
    return res.ticks, res.t_s, res.counts, res.starts, res.lengths


class _ScanError(LogError):
    def __init__(self, message: int, code: int):
        super().__init__(ERRORS[code])
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
    fields past 127 (none of which the writer produces) raise LogError. Any message costs at
    most a pass over its bytes at compiled speed (module docstring)."""
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
                 out: dict | None = None) -> TickBlock:
    """Decode and check the messages ``data[offsets[k]:offsets[k + 1]]`` (or, ``offsets``
    None, ``data`` a list of segments ``(buffer, begins, ends)``: messages
    ``buffer[begins[k]:ends[k]]``, e.g. where they lie in their decompressed chunks), whose log
    times say they are ticks ``tick_from_time``; ``wanted``: the columns to gather (default every
    field the format has). Checks as TickData does, each failure a LogError naming the tick.
    ``out``: a dict of buffers to reuse for the columns (BlockDecoder)."""
    segments = [(data, offsets[:-1], offsets[1:])] if offsets is not None else data
    dec = BlockDecoder(log_format, table_size, header_ships, wanted, where, out)
    first = 0
    for seg, begins, ends in segments:
        dec.add(seg, begins, ends, tick_from_time[first:first + len(begins)])
        first += len(begins)
    return dec.finish()


class BlockDecoder:
    """A block of tick records decoded as they arrive (:meth:`add`, a segment of messages at a
    time: their fields found, their wanted numbers copied into the columns, so that the
    segment's buffer may be reused at once), then checked as a whole (:meth:`finish`), in the
    order and with the messages of TickData's checks. ``out``: a dict of column buffers kept
    from block to block (the block's columns are then valid only until the next block is
    decoded into them); ``wanted``: the fields to gather (default every field of the format);
    ``expect_bytes``: about how many bytes of records the block will hold (its columns' buffers
    are sized for them when first made, rather than grown)."""

    def __init__(self, log_format: int, table_size: int, header_ships: int = 0,
                 wanted: tuple[str, ...] | None = None, where: str = "",
                 out: dict | None = None, expect_bytes: int = 0):
        self.expect_bytes = expect_bytes  # of records the block will hold, about
        self.format, self.table_size, self.header_ships = log_format, table_size, header_ships
        self.where = where
        self.every = fields.EVERY_TICK_BY_FORMAT[log_format]
        self.kf = fields.KEYFRAME_BY_FORMAT[log_format]
        names = list(dict.fromkeys(wanted)) if wanted is not None else [
            n for n in NAMES if n in self.every or n in self.kf]
        for must in ("surface_state", "ship_key"):
            if must not in names and must in self.every:
                names.append(must)
        self.names = names
        self.idx = np.array([INDEX[n] for n in names], np.int64)
        self.widths = np.array([width_of(n, log_format) for n in NAMES], np.int64)
        self.row_bytes = self.widths * WIRE  # bytes per ship of each field
        self.buffers = out if out is not None else {}
        self.views: dict[str, memoryview] = {}
        self.used = dict.fromkeys(names, 0)  # bytes written to each column
        self.scanner = _Scanner()
        self.parts: list[_Scan] = []
        self.times: list[np.ndarray] = []
        self.error: tuple[int, int] | None = None  # (message in the block, code): the first
        self.messages = 0
        self.doomed = False  # a message finish() refuses: its numbers are not gathered
        self.sane: dict[int, tuple[_Layout, bool]] = {}  # a layout's fields as a tick's must be

    def add(self, data: np.ndarray, begins, ends, tick_from_time: np.ndarray) -> None:
        """The messages ``data[begins[k]:ends[k]]`` (``data`` uint8), whose log times say they
        are ticks ``tick_from_time``. A scan error is kept for :meth:`finish` (a read that
        fails later, on a damaged chunk, says so first, as it always has)."""
        begins = np.asarray(begins, np.int64)
        ends = np.asarray(ends, np.int64)
        res = self.scanner.scan(data, begins, ends)
        self.parts.append(res)
        self.times.append(np.asarray(tick_from_time, np.int64))
        k = begins.shape[0]
        if res.error is not None and self.error is None:
            self.error = (self.messages + res.error[0], res.error[1])
        self.messages += k
        if self.error is not None or self.doomed or not k:
            return
        # what finish() checks before any column is sized: every field a tick must hold, each
        # of ship count x width numbers (else the block is refused; nothing more is gathered)
        lay = res.layout
        if lay is not None:  # every message as ``lay``: checked once
            sane = self.sane.get(id(lay))
            if sane is None:
                sane = self.sane[id(lay)] = (lay, self._sane(lay.starts[None] >= 0,
                                                             np.array([lay.count]),
                                                             lay.lengths[None]))
            if not sane[1]:
                self.doomed = True
                return
            rel = np.where(lay.starts[self.idx] >= 0, lay.starts[self.idx], -1)
            sizes = (lay.count * self.row_bytes[self.idx]).tolist()
            b = begins.tolist()
            all_starts = [[x + r for x in b] if r >= 0 else [-1] * k for r in rel.tolist()]
            all_sizes = [[n] * k for n in sizes]
        else:
            if not self._sane(res.starts >= 0, res.counts, res.lengths):
                self.doomed = True
                return
            expect = res.counts[:, None] * self.row_bytes[None, :]
            all_starts = res.starts[:, self.idx].T.tolist()
            all_sizes = expect[:, self.idx].T.tolist()
        mv = memoryview(data)
        # the block's share of each column in these messages' bytes: a column's buffer, when it
        # grows, grows to what ``expect_bytes`` of records fill (else by half)
        share = self.expect_bytes / max(1, int((ends - begins).sum()))
        for name, at, sizes in zip(self.names, all_starts, all_sizes):
            o = self.used[name]
            need = sum(sizes)
            buf = self._room(name, o + need, int(need * share * 1.05))
            dst = self.views[name]
            for s, n in zip(at, sizes):
                if s >= 0:
                    dst[o:o + n] = mv[s:s + n]
                else:  # a keyframe-only field on another tick: zeros
                    buf[o:o + n] = 0
                o += n
            self.used[name] = o

    def _sane(self, has: np.ndarray, counts: np.ndarray, lengths: np.ndarray) -> bool:
        """Every field a tick must hold there, each of ship count x width numbers."""
        every = [INDEX[n] for n in self.every]
        expect = counts[:, None] * self.row_bytes[None, :]
        return not (((~has[:, every]).any(axis=1) & (counts > 0)).any()
                    or (has & (lengths != expect)).any() or (counts < 0).any())

    def _room(self, name: str, size: int, likely: int = 0) -> np.ndarray:
        buf = self.buffers.get(name)
        if buf is None or buf.shape[0] < size:
            grown = np.empty(max(size + size // 2, likely, 1 << 16), np.uint8)
            if buf is not None:
                grown[:self.used[name]] = buf[:self.used[name]]
            buf = self.buffers[name] = grown
        if self.views.get(name) is None or self.views[name].obj is not buf:
            self.views[name] = memoryview(buf)
        return buf

    def finish(self) -> TickBlock:
        """The block, checked (each failure a LogError naming the tick)."""
        tick_from_time = (np.concatenate(self.times) if self.times
                          else np.zeros(0, np.int64))
        if self.error is not None:
            at, code = self.error
            raise LogError(f"{self.where}: tick {int(tick_from_time[at])}: {ERRORS[code]}")
        if self.parts:
            ticks, t_s, counts, starts, lengths = (np.concatenate([p[i] for p in self.parts])
                                                   for i in range(5))
        else:
            ticks, t_s, counts = np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.int64)
            starts = np.zeros((0, _NF), np.int64)
            lengths = np.zeros((0, _NF), np.int64)
        k = ticks.shape[0]
        where = self.where

        def fail(i: int, what: str):
            raise LogError(f"{where}: tick {int(tick_from_time[i])}: {what}")

        bad = np.flatnonzero(ticks != tick_from_time)
        if bad.size:
            fail(bad[0], f"the record says tick {int(ticks[bad[0]])}")
        if self.format < 3 and self.header_ships:
            bad = np.flatnonzero(counts != self.header_ships)
            if bad.size:
                fail(bad[0], f"{int(counts[bad[0]])} ships where the scenario has "
                             f"{self.header_ships}")
        has = starts >= 0
        for name in self.every:
            bad = np.flatnonzero(~has[:, INDEX[name]] & (counts > 0))
            if bad.size:
                fail(bad[0], f"field {name} is missing")
        kf_has = has[:, [INDEX[n] for n in self.kf]]
        bad = np.flatnonzero(kf_has.any(axis=1) & ~kf_has.all(axis=1))
        if bad.size:
            fail(bad[0], "a keyframe with some of its fields missing")
        expect = counts[:, None] * self.row_bytes[None, :]
        bad_k, bad_f = np.nonzero(has & (lengths != expect))
        if bad_k.size:
            f = int(bad_f[0])
            fail(bad_k[0], f"field {NAMES[f]} holds {int(lengths[bad_k[0], f] // WIRE[f])} "
                           f"numbers for {int(counts[bad_k[0]])} ships")
        bad = np.flatnonzero(counts < 0)
        if bad.size:  # a ship count past 2^63 (no field to hold it)
            fail(bad[0], f"a ship count of {int(counts[bad[0]]) + (1 << 64)}")
        if self.doomed:  # pragma: no cover - every reason to be is a check above
            raise AssertionError(f"{where}: a block refused by no check")
        row_off = np.zeros(k + 1, np.int64)
        np.cumsum(counts, out=row_off[1:])
        rows = int(row_off[-1])
        columns, present = {}, {}
        for name in self.names:
            f = INDEX[name]
            raw = self._room(name, 0)[:self.used[name]]
            columns[name] = raw.view(DTYPE[f]).reshape(rows, int(self.widths[f]))
            present[name] = has[:, f]
        states = columns["surface_state"]
        if rows and states.max(initial=0) > 4:
            r = int(np.argmax(states.ravel() > 4))
            fail(int(np.searchsorted(row_off, r, side="right") - 1),
                 "a surface state out of range")
        if "ship_key" in self.every:
            keys = columns["ship_key"].reshape(rows)
            at = _keys_at_fault(keys, row_off, self.table_size)
            if at >= 0:
                fail(at, f"ship keys outside the log's {self.table_size} ships, or a ship twice")
        else:
            keys = (np.arange(rows, dtype=np.int64) - np.repeat(row_off[:-1], counts))
        return TickBlock(ticks, t_s, counts, row_off, keys, columns, present)


def _keys_at_fault(keys: np.ndarray, row_off: np.ndarray, table_size: int) -> int:
    """-1 if every message's keys are in 0..table_size-1 with no key twice, else the first
    message at fault (messages ``keys[row_off[k]:row_off[k + 1]]``)."""
    k = row_off.shape[0] - 1
    if not keys.shape[0]:
        return -1
    msg = np.repeat(np.arange(k), np.diff(row_off))
    first = k
    out = (keys < 0) | (keys >= table_size)
    if out.any():
        first = int(msg[np.argmax(out)])
    # a message whose keys rise strictly holds none twice (a writer writes them so)
    same = msg[1:] == msg[:-1]
    unsorted = same & (keys[1:] <= keys[:-1])
    if unsorted.any():
        rows = np.isin(msg, np.unique(msg[1:][unsorted]))
        both = np.stack([msg[rows], keys[rows]], axis=1)
        order = np.lexsort((both[:, 1], both[:, 0]))
        s = both[order]
        twice = (s[1:] == s[:-1]).all(axis=1)
        if twice.any():
            first = min(first, int(s[1:][twice][:, 0].min()))
    return first if first < k else -1


__all__ = ["TickBlock", "BlockDecoder", "decode_block", "decode_one", "decode_tick", "scan",
           "width_of", "NAMES", "INDEX"]
