"""The zstd level of a log writer's chunks (and the CRC-32 of them, from zlib-ng: _Zlib).

The MCAP library compresses each chunk with ``zstandard.compress(data)``: zstd's level 3, about
600 MB/s here. A live service at tens of thousands of ships writes over 100 MB of tick records a
second, and level 3 was the largest single cost of its flight log; zstd's fast levels (negative)
compress the same records about five times faster for a few percent more bytes. The chunk is the
same kind of chunk either way (``compression = "zstd"``, read by every reader, the bounded one
included): only the writer's speed and the file's size change.

The library takes no level, so its ``zstandard`` is replaced (once, on import) by this module's
stand-in, which compresses at the level the calling thread asked for (``chunk_level``) and at
:data:`DEFAULT_ZSTD_LEVEL` otherwise.
"""
from __future__ import annotations

import json
import threading
import time
import zlib

import mcap.writer
import orjson
import zstandard

_local = threading.local()

#: the chunks' zstd level when a writer asks for none (``touchdown record``, ``incident``,
#: ``sweep --record``, what-if logs): -3, zstd's fast mode (a live service's flight logs: -8,
#: service.serve). Measured on 10,000 landers arriving (bench/mujoco_side.py's fleet, 1 s; every
#: tick a keyframe, 552 bytes of records a ship-tick; bench/fleet_log_parts.py, session 32, AMD
#: EPYC, load 5-6, two rounds): zstd's CPU a ship-tick 1.49-1.54 us at 1, 1.05-1.13 at -1,
#: 0.93 at -3, 0.76-0.82 at -5; the file 154.1, 163.9 (+6%), 179.2 (+16%), 194.3 (+26%) bytes a
#: ship-tick. Session 29 (5 s of the same fleet): 752,000 ship-ticks a second of CPU at 1 against
#: 563,000 at 3 (1.33x) for 4.3% more bytes. Until touchdown 0.8 logs were written at 3, then at
#: 1; a log reads the same at any level: the same messages, only the compressed bytes differ.
DEFAULT_ZSTD_LEVEL = -3


class _Zstandard:
    """Stands in for the ``zstandard`` module inside ``mcap.writer``."""

    def __getattr__(self, name: str):
        return getattr(zstandard, name)

    @staticmethod
    def compress(data, level: int = DEFAULT_ZSTD_LEVEL) -> bytes:
        c = getattr(_local, "compressor", None)
        return (c if c is not None else _compressor(level)).compress(data)


def _compressor(level: int) -> zstandard.ZstdCompressor:
    """This thread's compressor at ``level``, made once: ``zstandard.compress(data, level)`` is
    ``ZstdCompressor(level=level).compress(data)``, the same bytes, but makes a compression
    context each call (15 us of the 25 a small log's 7 kB chunk takes to compress)."""
    made = getattr(_local, "by_level", None)
    if made is None:
        made = _local.by_level = {}
    c = made.get(level)
    if c is None:
        c = made[level] = zstandard.ZstdCompressor(level=level)
    return c


def chunk_level(level: int | None) -> None:
    """The chunks the calling thread compresses from now on are compressed at ``level`` (None:
    :data:`DEFAULT_ZSTD_LEVEL`)."""
    _local.compressor = _compressor(DEFAULT_ZSTD_LEVEL if level is None else level)


if not isinstance(mcap.writer.zstandard, _Zstandard):
    mcap.writer.zstandard = _Zstandard()

try:
    from zlib_ng.zlib_ng import crc32 as _crc32
except ImportError:  # pragma: no cover
    from zlib import crc32 as _crc32


class _Zlib:
    """Stands in for the ``zlib`` module inside ``mcap.writer``: the same CRC-32 of each chunk
    (and of the summary), from zlib-ng (SIMD, about three times faster here than the stock
    zlib's, a live service's flight log's third largest cost after zstd and the encoding: over
    100 MB of records a second at tens of thousands of ships). The same numbers, so the same
    bytes."""

    def __getattr__(self, name: str):
        return getattr(zlib, name)

    crc32 = staticmethod(_crc32)


if not isinstance(mcap.writer.zlib, _Zlib):
    mcap.writer.zlib = _Zlib()


class ShipTables(dict):
    """Ship id -> its resolved table (``world_header``'s cache across the headers of one
    world), and each table's JSON kept beside it: a rotating log's header lists the tables of
    every ship present (7.6 MB of JSON at 12,500 ships, 140 ms to encode), and with each
    ship's JSON kept the next header is a join (a few milliseconds)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.json: dict[str, bytes] = {}


_SHIPS = "\x00touchdown-ships\x00"


def canonical_json(doc) -> bytes:
    """``doc`` as JSON, UTF-8, its keys sorted and no spaces: a log header's scenario. orjson
    writes it (17 ms for a 10,000-ship scenario, 5.4 MB, against the standard library's 150 ms);
    where orjson cannot (an integer past 64 bits, a key not a string) the standard library does,
    the same JSON with its own spelling of some floats (1e-05 for orjson's 0.00001), so that a
    document always takes one of the two, whole."""
    try:
        return orjson.dumps(doc, option=orjson.OPT_SORT_KEYS)
    except TypeError:  # (orjson.JSONEncodeError is one)
        return json.dumps(doc, sort_keys=True, separators=(",", ":"), allow_nan=False).encode()


def resolved_json_bytes(resolved: dict, ids: list[str], tables: dict | None) -> bytes:
    """:func:`canonical_json` of ``resolved``, the same bytes, with the ships' tables
    (``resolved["ships"]``, those of ``ids`` in order) encoded once each when ``tables`` is a
    ShipTables, and joined from pieces (each copy of megabytes a call of its own, the GIL let go
    between them: this runs on a log writer's thread beside the tick)."""
    if not isinstance(tables, ShipTables) or not ids:
        return canonical_json(resolved)
    try:
        head = orjson.dumps({**resolved, "ships": _SHIPS}, option=orjson.OPT_SORT_KEYS)
        parts = _ship_json(resolved, ids, tables)
    except TypeError:  # (one the standard library writes: the whole document, as it would)
        return canonical_json(resolved)
    before, after = head.split(orjson.dumps(_SHIPS), 1)
    time.sleep(0)
    ships = b",".join(parts)
    time.sleep(0)
    return b"".join((before, b"[", ships, b"]", after))


def _ship_json(resolved: dict, ids: list[str], tables: "ShipTables") -> list[bytes]:
    cache = tables.json
    parts = []
    for sid, table in zip(ids, resolved["ships"]):
        s = cache.get(sid)
        if s is None:
            s = cache[sid] = orjson.dumps(table, option=orjson.OPT_SORT_KEYS)
        parts.append(s)
    return parts
