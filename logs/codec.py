"""Fast, exact encoding of the per-tick batch message (``touchdown.v1.TickBatch``).

A 10,000-ship tick holds ~400,000 numbers; going through protobuf's Python objects costs ~100 ms.
Packed repeated fields of doubles and fixed64s are, on the wire, just a tag, a length and the
little-endian bytes, so this module writes and reads them straight from numpy buffers. The result
is byte-for-byte what ``TickBatch.SerializeToString()`` gives (a test checks it), so any protobuf
reader decodes these messages.

Two encoders write the same bytes: :func:`encode_tick` takes any arrays by field name (what tools
and tests re-encode, damaged or not), and :class:`logs.encode_block.BlockEncoder` writes a whole
block of ticks straight from the run's record arrays, compiled (the recorder's path: no
per-field conversions, a few microseconds a tick). A test holds them to each other and to
protobuf. This module holds the wire's facts and loads no compiled code (a reader needs none).
"""
from __future__ import annotations

import struct

import numpy as np

from touchdown.logs import LogError
from touchdown.proto import touchdown_pb2 as pb
from google.protobuf.descriptor import FieldDescriptor as FD

_DESC = pb.TickBatch.DESCRIPTOR
_SINGULAR = {"tick", "t_s", "ship_count"}
#: (field number, name, numpy dtype on the wire) for every packed per-ship field, in number order
PACKED: tuple[tuple[int, str, str], ...] = tuple(
    (f.number, f.name, {FD.TYPE_DOUBLE: "<f8", FD.TYPE_SFIXED64: "<i8", FD.TYPE_ENUM: "u1",
                        FD.TYPE_BOOL: "u1"}[f.type])
    for f in sorted(_DESC.fields, key=lambda f: f.number) if f.name not in _SINGULAR)
_BY_NUMBER = {num: (name, dt) for num, name, dt in PACKED}


def varint(n: int) -> bytes:
    """A protobuf base-128 varint."""
    out = bytearray()
    while True:
        b = n & 0x7F
        n >>= 7
        if n:
            out.append(b | 0x80)
        else:
            out.append(b)
            return bytes(out)


_TAG = {name: bytes([((num << 3) | 2)]) if num < 16 else None for num, name, _ in PACKED}


def encode_tick(tick: int, t_s: float, ship_count: int, arrays: dict[str, np.ndarray]) -> bytes:
    """Serialise one TickBatch. ``arrays`` maps packed field names to per-ship arrays; a missing
    or empty one is left out, as protobuf leaves out an empty repeated field."""
    parts = []
    if tick:
        parts.append(b"\x08" + varint(tick))
    if t_s != 0.0:
        parts.append(b"\x11" + struct.pack("<d", t_s))
    if ship_count:
        parts.append(b"\x18" + varint(ship_count))
    for num, name, dt in PACKED:
        arr = arrays.get(name)
        if arr is None or arr.size == 0:  # absent, like an empty repeated field
            continue
        if dt == "u1":
            a = np.ascontiguousarray(arr, dtype=np.int64).ravel()
            if a.min() < 0 or a.max() > 127:
                raise ValueError(f"{name}: value outside 0..127 cannot use the one-byte varint path")
            payload = a.astype(np.uint8).tobytes()
        else:
            payload = np.ascontiguousarray(arr, dtype=dt).tobytes()
        tag = _TAG[name] or varint((num << 3) | 2)
        parts.append(tag + varint(len(payload)) + payload)
    return b"".join(parts)


def _read_varint(buf: bytes, i: int, end: int) -> tuple[int, int]:
    result = shift = 0
    for _ in range(10):  # a varint has at most 10 bytes
        if i >= end:
            raise LogError("truncated varint in a tick record")
        b = buf[i]
        i += 1
        result |= (b & 0x7F) << shift
        if not b & 0x80:
            return result, i
        shift += 7
    raise LogError("malformed varint in a tick record")


def decode_tick_python(data: bytes) -> tuple[int, float, int, dict[str, np.ndarray]]:
    """One TickBatch decoded as :func:`logs.decode.decode_tick` decodes it, in Python, field by
    field (the reference the compiled decoder is tested against)."""
    tick, t_s, count = 0, 0.0, 0
    arrays: dict[str, np.ndarray] = {}
    i, end = 0, len(data)
    while i < end:
        key, i = _read_varint(data, i, end)
        num, wt = key >> 3, key & 7
        if wt == 0:
            val, i = _read_varint(data, i, end)
            if num == 1:
                tick = val
            elif num == 3:
                count = val
            elif num in _BY_NUMBER:  # unpacked elements: legal protobuf, never written here
                raise LogError(f"unpacked field {_BY_NUMBER[num][0]} in a tick record")
        elif wt == 1:
            if i + 8 > end:
                raise LogError("truncated fixed64 in a tick record")
            if num == 2:
                t_s = struct.unpack_from("<d", data, i)[0]
            i += 8
        elif wt == 2:
            length, i = _read_varint(data, i, end)
            if i + length > end:
                raise LogError("a packed field runs past the end of its tick record")
            if num in _BY_NUMBER:
                name, dt = _BY_NUMBER[num]
                chunk = data[i:i + length]
                if dt == "u1":
                    raw = np.frombuffer(chunk, dtype=np.uint8)
                    if (raw & 0x80).any():  # a state or flag past 127: never written here
                        raise LogError(f"packed field {name} holds a value out of range")
                    a = raw.astype(np.int64)
                else:
                    if length % 8:
                        raise LogError(f"packed field {name} has a length that is not whole numbers")
                    a = np.frombuffer(chunk, dtype=dt).astype(np.float64 if dt == "<f8" else np.int64)
                if name in arrays:
                    raise LogError(f"packed field {name} appears twice in a tick record")
                arrays[name] = a
            i += length
        elif wt == 5:
            i += 4
        else:
            raise LogError(f"unsupported wire type {wt} in a tick record")
    if i != end:
        raise LogError("tick record ends inside a field")
    return tick, t_s, count, arrays
