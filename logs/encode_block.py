"""The recorder's encoding of a whole block of ticks as TickBatch messages, straight from the run's
record arrays, compiled (sim.compiled): no per-field conversions, a few microseconds a tick. The
same bytes as :func:`logs.codec.encode_tick` gives field by field (a test holds them to each other
and to protobuf). Apart from :mod:`logs.codec`, whose wire facts every reader needs: reading a log
loads no compiled code.
"""
from __future__ import annotations

import sys

import numpy as np

from touchdown.logs.codec import PACKED, varint
from touchdown.sim.compiled import kernel
from touchdown.sim.fields import BY_LOG_NAME
from touchdown.sim.state import INPUTS_DTYPE, OUTPUTS_DTYPE, STATE_DTYPE

#: Where each packed field's numbers come from: (record kind, field in that record).
SOURCES = {"state": 0, "outputs": 1, "inputs": 2, "keys": 3}  # _encode_ticks's src


def _field_table(keyframe_only: tuple[str, ...], with_keys: bool = True) -> np.ndarray:
    """One row per packed field, in field-number order: (source, byte offset in its record,
    numbers per ship, bytes per number in the record, bytes per number on the wire, key,
    key length, keyframe-only)."""
    rows = []
    for num, name, dt in PACKED:
        if name == "ship_key":  # the block's keys, one int64 per ship (format 3)
            if with_keys:
                key = varint((num << 3) | 2)
                rows.append((SOURCES["keys"], 0, 1, 8, 8, key[0], key[1] if len(key) > 1 else 0,
                             len(key), False))
            continue
        f = BY_LOG_NAME[name]  # the quantity's record and name there (sim.fields)
        src, fname = SOURCES[f.record], f.name
        dtype = {"state": STATE_DTYPE, "outputs": OUTPUTS_DTYPE, "inputs": INPUTS_DTYPE}[f.record]
        ftype, offset = dtype.fields[fname][:2]
        count = int(np.prod(ftype.shape)) if ftype.shape else 1
        size = ftype.base.itemsize
        wire = 1 if dt == "u1" else 8
        if wire != size or (wire == 8 and offset % 8):  # words are read as words
            raise AssertionError(f"{name}: {size}-byte numbers at byte {offset} for a "
                                 f"{wire}-byte wire type")
        key = varint((num << 3) | 2)
        rows.append((src, offset, count, size, wire, key[0], key[1] if len(key) > 1 else 0,
                     len(key), name in keyframe_only))
    return np.array(rows, dtype=np.int64)


@kernel
def _put_varint(out, o, value):
    while True:
        b = value & 0x7F
        value >>= 7
        if value:
            out[o] = b | 0x80
            o += 1
        else:
            out[o] = b
            return o + 1


#: the machine keeps its words little-endian, the wire's order: a word is stored as it is
LITTLE = sys.byteorder == "little"


@kernel
def _put_fields(src, recs, words, table, start, i0, i1, out, out64, little):
    """The numbers of ships ``i0 .. i1 - 1`` of every field whose numbers come from record kind
    ``src`` (``table``'s column 0: SOURCES), each field's where its ships' numbers begin
    (``start[f]``; -1: not in this tick). ``recs``: that kind's records as bytes (N, itemsize),
    ``words``: the same as eight-byte words. Returns -1 if a one-byte number is past 127 (a
    two-byte varint: never written here), else 0.

    An eight-byte number is read as a word and, on a little-endian machine (``little``: byte b of
    word q is the buffer's byte 8 q + b), stored as one: a field's numbers begin anywhere (after
    its key and length), so each word of the wire straddles two of the buffer's words at a shift
    of ``o % 8`` bytes: word q takes the last number's high bytes and the next one's low bytes (a
    funnel shift), and the bytes before the field and after its last number are kept as they
    were (so the fields may be written in any order). The same bytes as storing each number
    byte by byte, which a big-endian machine does. Fields of one, three or four numbers a ship
    (all but the keyframe's 12-number one) have loops of their own, unrolled: the general loop's
    inner loop over ``count`` cost about a fifth of the encoder's time (176-180 -> 129-143 ns a
    ship-tick at 15,000 ships, loaded).

    One call a record kind, its fields' loop inside: numba counts references to the arrays a
    function is given at each call, two atomic calls an array, and a call a field (an array
    chosen a field) was ~70 ns of each of a tick's 32 fields, two thirds of a one-ship tick's
    encoding (2.2 us)."""
    for f in range(table.shape[0]):
        o = start[f]
        if table[f, 0] != src or o < 0:
            continue
        off, count, size, wire = table[f, 1], table[f, 2], table[f, 3], table[f, 4]
        o += i0 * count * wire
        if wire != 8:
            for i in range(i0, i1):
                for j in range(count):
                    v = recs[i, off + j * size]
                    if v > 127:
                        return -1
                    out[o] = v
                    o += 1
            continue
        w0 = off // 8
        if not little:
            for i in range(i0, i1):
                for j in range(count):
                    w = words[i, w0 + j]
                    for b in range(8):
                        out[o + b] = (w >> np.uint64(8 * b)) & np.uint64(0xFF)
                    o += 8
            continue
        q = o >> 3
        r = o & 7
        if r == 0:
            if count == 1:
                for i in range(i0, i1):
                    out64[q] = words[i, w0]
                    q += 1
            else:
                for i in range(i0, i1):
                    for j in range(count):
                        out64[q] = words[i, w0 + j]
                        q += 1
            continue
        up = np.uint64(8 * r)
        down = np.uint64(64 - 8 * r)
        below = (np.uint64(1) << up) - np.uint64(1)  # the bytes of word q before byte o
        carry = out64[q] & below
        if count == 1:
            for i in range(i0, i1):
                w = words[i, w0]
                out64[q] = carry | (w << up)
                carry = w >> down
                q += 1
        elif count == 3:
            for i in range(i0, i1):
                a = words[i, w0]
                b = words[i, w0 + 1]
                c = words[i, w0 + 2]
                out64[q] = carry | (a << up)
                out64[q + 1] = (a >> down) | (b << up)
                out64[q + 2] = (b >> down) | (c << up)
                carry = c >> down
                q += 3
        elif count == 4:
            for i in range(i0, i1):
                a = words[i, w0]
                b = words[i, w0 + 1]
                c = words[i, w0 + 2]
                d = words[i, w0 + 3]
                out64[q] = carry | (a << up)
                out64[q + 1] = (a >> down) | (b << up)
                out64[q + 2] = (b >> down) | (c << up)
                out64[q + 3] = (c >> down) | (d << up)
                carry = d >> down
                q += 4
        else:
            for i in range(i0, i1):
                for j in range(count):
                    w = words[i, w0 + j]
                    out64[q] = carry | (w << up)
                    carry = w >> down
                    q += 1
        out64[q] = (out64[q] & ~below) | carry
    return 0


#: ships gathered at a time: their records stay in cache while every field takes its numbers
GATHER_SHIPS = 256


@kernel
def _gather(states, outputs, inputs, keys8, states64, outputs64, inputs64, keys64, table, start,
            out, out64, little):
    """One tick's numbers of every field, written to ``out`` where each field's numbers begin
    (``start[f]``; -1: not in this tick), a record kind at a time (:func:`_put_fields`). Ships
    are taken GATHER_SHIPS at a time, so each record is read from memory once. Returns -1 if a
    one-byte number is past 127, else 0."""
    n = states.shape[0]
    for i0 in range(0, n, GATHER_SHIPS):
        i1 = min(i0 + GATHER_SHIPS, n)
        if (_put_fields(0, states, states64, table, start, i0, i1, out, out64, little) < 0
                or _put_fields(1, outputs, outputs64, table, start, i0, i1, out, out64,
                               little) < 0
                or _put_fields(2, inputs, inputs64, table, start, i0, i1, out, out64, little) < 0
                or _put_fields(3, keys8, keys64, table, start, i0, i1, out, out64, little) < 0):
            return -1
    return 0


#: an MCAP Message record's head: opcode, record length, channel, sequence, log and publish time
#: (u8, u64, u16, u32, u64, u64, little-endian)
MESSAGE_HEAD_BYTES = 31


@kernel
def _put_le(out, o, value, n_bytes):
    for b in range(n_bytes):
        out[o + b] = (value >> (8 * b)) & 0xFF


@kernel
def _put_head(out, o, body_bytes, channel, sequence, t_ns):
    """A Message record's head at ``out[o:o + 31]``, for a message of ``body_bytes`` whose log
    and publish time are both ``t_ns`` (MCAP specification, "Message": opcode 0x05, the record's
    length after its opcode and length fields, channel id, sequence, log time, publish time)."""
    out[o] = 0x05
    _put_le(out, o + 1, body_bytes + 22, 8)
    _put_le(out, o + 9, channel, 2)
    _put_le(out, o + 11, sequence, 4)
    _put_le(out, o + 15, t_ns, 8)
    _put_le(out, o + 23, t_ns, 8)


@kernel
def _encode_ticks(states, outputs, inputs, keys64, table, ticks, t_s, t_bytes, keyframe_interval,
                  keyframe_phase, first_keyframe, out, offsets, little, head):
    """Each tick of a block as a TickBatch, one after another into ``out``; ``offsets[k]`` is
    where tick k starts. ``states``, ``outputs``, ``inputs``: the block's records as bytes
    (K, N, itemsize; 8-byte aligned, so also read as words). Each tick's keys and lengths are
    written first, then every field's numbers (:func:`_gather`). ``head`` (channel, first
    sequence, nanoseconds a tick; channel < 0: none): each tick is preceded by its MCAP Message
    record's head (:func:`_put_head`), and ``offsets[k]`` is where that head starts. Returns
    -1 if a one-byte field holds a value past 127, else the bytes written."""
    n = states.shape[1]
    nf = table.shape[0]
    start = np.empty(nf, np.int64)
    out64 = out.view(np.uint64)  # (its length a multiple of 8: BlockEncoder.encode)
    keys8 = keys64.view(np.uint8)  # (the keys' kind as bytes, as every record kind is given)
    gap = MESSAGE_HEAD_BYTES if head[0] >= 0 else 0
    o = 0
    for k in range(ticks.shape[0]):
        offsets[k] = o
        o += gap
        tick = ticks[k]
        if tick:
            out[o] = 0x08
            o = _put_varint(out, o + 1, tick)
        if t_s[k] != 0.0:
            out[o] = 0x11
            for b in range(8):
                out[o + 1 + b] = t_bytes[k, b]
            o += 9
        if n:
            out[o] = 0x18
            o = _put_varint(out, o + 1, n)
        # logs.header.keyframe_due (ticks are never negative)
        keyframe = tick % keyframe_interval == keyframe_phase or (k == 0 and first_keyframe)
        for f in range(nf):
            count, wire, key_len, kf_only = table[f, 2], table[f, 4], table[f, 7], table[f, 8]
            length = n * count * wire
            start[f] = -1
            if (kf_only and not keyframe) or length == 0:
                continue
            out[o] = table[f, 5]
            if key_len > 1:
                out[o + 1] = table[f, 6]
            o = _put_varint(out, o + key_len, length)
            start[f] = o
            o += length
        if gap:  # (before the numbers: _put_fields keeps the bytes around them as they were)
            _put_head(out, offsets[k], o - offsets[k] - gap, head[0], head[1] + k, tick * head[2])
        s8, o8, i8 = states[k], outputs[k], inputs[k]
        if _gather(s8, o8, i8, keys8, s8.view(np.uint64), o8.view(np.uint64), i8.view(np.uint64),
                   keys64,
                   table, start, out, out64, little) < 0:
            return -1
    offsets[ticks.shape[0]] = o
    return o


class BlockEncoder:
    """Encodes blocks of ticks (sim.world.Block) as TickBatch messages; the keyframe-only fields
    (``keyframe_only``) go only into ticks = ``keyframe_phase`` (mod ``keyframe_interval``), and
    into the first tick a writer writes (a log that starts later, or one cut from another,
    starts with a keyframe). ``with_keys``: the ships' keys go into each tick (log format 3)."""

    def __init__(self, dt_s: float, keyframe_only: tuple[str, ...], keyframe_interval: int = 1,
                 with_keys: bool = True, keyframe_phase: int = 0):
        self.dt_s = dt_s
        self.keyframe_interval = max(1, keyframe_interval)
        self.keyframe_phase = keyframe_phase % self.keyframe_interval
        self.table = _field_table(keyframe_only, with_keys)

    def _bytes_per_tick(self, n: int) -> int:
        """At most: a message head, the tick's header, and each field's key, length and
        numbers."""
        return MESSAGE_HEAD_BYTES + 31 + sum(12 + n * count * wire for _, _, count, _, wire, *_
                                             in self.table.tolist())

    def encode(self, first_tick: int, states: np.ndarray, outputs: np.ndarray,
               inputs: np.ndarray, keys: np.ndarray | None = None, first_keyframe: bool = False,
               room: int = 0, heads: tuple[int, int, int] | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
        """(bytes, offsets): tick ``first_tick + k`` is ``bytes[offsets[k]:offsets[k + 1]]``.
        ``keys``: the ships' keys (N,), for a table with them; ``first_keyframe``: the block's
        first tick is a keyframe whatever its number. ``room``: bytes left free before the
        first tick (a multiple of 8), so offsets[0] is ``room``; the ticks' bytes are the same.
        ``heads`` = (channel, first sequence, nanoseconds a tick): each tick as an MCAP Message
        record, its head (MESSAGE_HEAD_BYTES) and then its TickBatch, tick ``first_tick + k``
        on ``channel`` with sequence ``first sequence + k`` at log time ``tick * ns``: what
        logs.writer adds to a chunk as it is (the block's records, one run of bytes)."""
        if room % 8:
            raise ValueError(f"room {room}: a multiple of 8")
        k, n = states.shape
        keys64 = np.zeros((n, 1), np.uint64) if keys is None else \
            np.ascontiguousarray(keys, dtype=np.int64).view(np.uint64).reshape(n, 1)
        views = [np.ascontiguousarray(a).view(np.uint8).reshape(k, n, a.dtype.itemsize)
                 for a in (states, outputs, inputs)]
        ticks = np.arange(first_tick, first_tick + k, dtype=np.int64)
        t_s = ticks * self.dt_s
        t_bytes = t_s.astype("<f8").view(np.uint8).reshape(k, 8)
        # whole words, and one spare: _put_fields reads and writes the word a field's numbers end in
        buf = np.empty(room + (k * self._bytes_per_tick(n) // 8 + 2) * 8, np.uint8)
        out = buf[room:]  # (8-byte aligned, as buf: the kernel reads and writes it as words)
        offsets = np.empty(k + 1, np.int64)
        if _encode_ticks(*views, keys64, self.table, ticks, t_s, t_bytes, self.keyframe_interval,
                         self.keyframe_phase, first_keyframe, out, offsets, LITTLE,
                         np.array((-1, 0, 0) if heads is None else heads, np.int64)) < 0:
            raise ValueError("a one-byte field holds a value outside 0..127")
        if room:
            offsets += room
        return buf, offsets


__all__ = ["BlockEncoder", "MESSAGE_HEAD_BYTES", "SOURCES"]
