"""Reading MCAP files that may be damaged or hostile, with bounded memory, bounded work and no hangs.

The stock reader trusts a chunk's declared uncompressed size, and zstd allocates what a frame's
header claims (a 33 KB file made it allocate 1 GiB); it parses a chunk's records in a Python loop
with no limit (119 million empty records took 83 s); and it cannot read a file whose writer was
killed before the footer. This reader:

* checks the magic, then reads the summary (chunk indexes, channels) when the footer is intact;
  every chunk index must point at a chunk inside the data section;
* otherwise (no footer: a killed writer, a truncated copy) walks the records from the start and
  keeps everything up to the first damaged byte, reporting that it recovered a prefix;
* decompresses a chunk itself: zstd through a streaming decoder with a capped window that may
  produce no more than the chunk declares, which must be at most ``max_chunk_bytes``, and must
  produce exactly that; an uncompressed chunk must hold what it declares; any other compression
  (lz4 among them) is refused before anything is allocated;
* parses at most ``max_records_per_chunk`` records a chunk, each within its chunk's bounds;
* reads a log's header (``iter_messages``' ``header``) from its chunk as a stream, stopping
  after it: at most ``HEADER_PREAMBLE_BYTES`` inflated before it and the header's own bound for
  it, whatever the chunk declares (a chunk may hold a large fleet's first tick after the header:
  what bounds a chunk is known only once the header is read); that chunk's size and CRC are
  left to a full read by the caller (``ReadStatus.unchecked``, :func:`chunk_at`);
* reads a chunk over what a read knows bounds it (``iter_messages``' ``grow``: a log's fleet
  read, whose joins bound the ticks after them) as a stream too: every record but its last must
  end within the part a writer fills before it closes a chunk, and its last is inflated only if
  it is a message the read wants (within a bound of its own), else that chunk is left to a full
  read by the caller once the read is done and its bound known (``GrowingBound.deferred``);
* refuses a channel declared again with another topic; checks every CRC.

The limits are :class:`ReadLimits` (environment variables ``TOUCHDOWN_MAX_CHUNK_MIB``,
``TOUCHDOWN_MAX_RECORDS_PER_CHUNK``, ``TOUCHDOWN_MAX_WINDOW_MIB``, ``TOUCHDOWN_MAX_COMMANDS`` change
them). Every failure is a
:class:`logs.LogError` with one line naming the file.
"""
from __future__ import annotations

import io
import os
import struct
import weakref
import zlib
from dataclasses import dataclass, field
from typing import IO, Callable, Iterator

import zstandard

try:  # zlib-ng's CRC-32 is the same function, several times faster (SIMD)
    from zlib_ng.zlib_ng import crc32
except ImportError:  # pragma: no cover - zlib-ng is a dependency; zlib's is the same numbers
    from zlib import crc32
from mcap.data_stream import ReadDataStream
from mcap.records import Channel, Chunk, Footer, Message
from mcap.stream_reader import StreamReader

from touchdown.logs import LogError

MAGIC = b"\x89MCAP0\r\n"
_FOOTER_RECORD = 1 + 8 + 8 + 8 + 4  # opcode, length, summary_start, summary_offset_start, crc
_MIB = 1 << 20
#: what a header read inflates of a chunk before the message it looks for (the schemas and
#: channels a writer puts first: about 17 kB in a Touchdown log); a chunk declaring no more than
#: this is read whole, as any other read reads it (and checked at once: a writer's first chunk,
#: the header and its first tick, is a few tens of kB for a small fleet)
HEADER_PREAMBLE_BYTES = 1 << 20
#: the piece a header read inflates at a time
_PIECE = 64 << 10


@dataclass(frozen=True)
class ReadLimits:
    """What a log may ask of the reader. A Touchdown chunk is about 1 MiB and holds a few
    thousand records; one tick of 50,000 ships is about 25 MiB."""

    max_chunk_bytes: int = 256 * _MIB  # a chunk's uncompressed size
    max_records_per_chunk: int = 1_000_000
    max_window_bytes: int = 64 * _MIB  # the zstd decoder's window (the writer's is ~1 MiB)
    #: where max_chunk_bytes comes from, for the message refusing a chunk
    chunk_bound: str = "TOUCHDOWN_MAX_CHUNK_MIB"
    #: the commands a log's timeline holds (LogReader.timeline: at its peak ~140 bytes each in
    #: memory when they repeat their values, ~390 when all differ: 4 M commands of one tick
    #: +525 MiB RSS; a scenario's resolved inputs fit in about a million, a service shard at its
    #: cap of 2,000 a tick fills a 64 MiB file with about 3 million)
    max_commands: int = 4_000_000

    @staticmethod
    def from_environment() -> "ReadLimits":
        def env(name: str, default: int, scale: int = 1) -> int:
            raw = os.environ.get(name)
            if raw is None:
                return default
            try:
                value = float(raw)
                if not 0 < value < 1e12:
                    raise ValueError
                return max(1, int(value * scale))
            except ValueError:
                raise LogError(f"{name}={raw!r}: must be a positive number") from None
        d = ReadLimits()
        return ReadLimits(env("TOUCHDOWN_MAX_CHUNK_MIB", d.max_chunk_bytes, _MIB),
                          env("TOUCHDOWN_MAX_RECORDS_PER_CHUNK", d.max_records_per_chunk),
                          env("TOUCHDOWN_MAX_WINDOW_MIB", d.max_window_bytes, _MIB),
                          max_commands=env("TOUCHDOWN_MAX_COMMANDS", d.max_commands))



@dataclass
class ReadStatus:
    """What a read found: ``complete`` False means the file ended early (no footer) and only a
    prefix was read; ``damage`` says what stopped the read."""

    complete: bool = True
    damage: str = ""
    #: damage read around (a chunk whose message times are not its messages'), as (the
    #: chunk's byte offset, what): the content is sound, other readers may stumble
    notes: list = field(default_factory=list)
    #: (byte offset, declared uncompressed size) of a chunk a header read stopped in, not read
    #: to its end: its size and CRC are not checked (chunk_at checks them); None: none
    unchecked: tuple[int, int] | None = None

    def note(self, offset: int, what: str) -> None:
        if (offset, what) not in self.notes:
            self.notes.append((offset, what))


@dataclass
class GrowingBound:
    """A read whose chunks are bounded by what it has read so far (iter_messages' ``grow``; a
    log's fleet read: the ships that joined bound the ticks after them, in the same chunk too).

    A chunk declaring at most ``bound()`` (asked as the read reaches it) is read whole, as any
    read reads it. A larger zstd chunk is inflated as a stream, a piece at a time, its records
    parsed as they arrive: every record but its last must end within its first ``prefix``
    bytes (a writer closes a chunk at the record that takes it past its target size: all
    before it lie within that size); its last may run past them only if it is a message the
    read wants, of at most ``held`` bytes (checked as it arrives by ``check(topic)``'s checker,
    if any: ``checker(the bytes since its last call, final)`` raises LogError on bytes that
    cannot be one), and then
    the chunk is read to its end (size and CRC checked). Any other last record is not inflated
    at all: the chunk's (byte offset, declared size, the last record's topic (None: not a
    message) and channel id) is appended to ``deferred``, for the
    caller to read in full (chunk_at: size and CRC) once the read is done and its bound known,
    before it trusts what the read gave.

    ``passed``: topics whose messages what the read knows does not bound (a tick's commands:
    a ship may be given any number): a chunk's last record on one of them may run past the
    prefix, to the general bound (``max_chunk_bytes``), kept if wanted, else passed over
    (inflated a piece at a time, not held), ``check(topic)``'s checker, if any, on it as it
    arrives; either way the chunk is read to its end, its size and CRC checked. ``refuse``: the
    bound is final (the whole fleet is read): a chunk's last record past the prefix that is
    neither a wanted message within ``held`` nor on a ``passed`` topic is refused with
    ``refuse(declared size)``, not deferred. A chunk read as a stream gives its messages only
    once it is read to its end (iter_messages' caller sees none of an unchecked chunk), or,
    deferred, those before its last record, or, its last record on a ``passed`` topic and the
    chunk read to its end by a read before (``known``) and not wanted now, those before it."""

    bound: Callable[[], int]
    prefix: int
    held: int
    check: Callable[[str], Callable[[bytearray, bool], None] | None] | None = None
    deferred: list = field(default_factory=list)
    passed: frozenset = frozenset()
    refuse: Callable[[int], Exception] | None = None
    #: what reads of one file learned of its chunks, shared by them: (byte offset, declared
    #: size, CRC) of a chunk read to its end (size and CRC checked) whose last record, on a
    #: ``passed`` topic, ran past the prefix -> where that record begins. A later read that
    #: does not want it stops there, not inflating it again (the records before it are given).
    known: dict = field(default_factory=dict)


class ChunkBuffers:
    """Buffers chunks are decompressed into, handed back by a reader that is done with a chunk's
    messages (:func:`iter_messages`' ``buffers``): a fresh buffer per chunk costs the kernel's
    zeroing and a page fault per 4 kB (a fifth of a Parquet export's reading, measured), a
    buffer used again costs neither. A view into a buffer handed back then sees the next chunk."""

    def __init__(self):
        self._free: list[bytearray] = []

    def take(self, size: int) -> bytearray:
        while self._free:
            buf = self._free.pop()
            if len(buf) >= size:
                return buf
        return bytearray(size + size // 8)

    def give(self, buf) -> None:
        """``buf`` (a chunk's data's ``.obj``) may be used again; anything not taken from here
        is ignored."""
        if isinstance(buf, bytearray) and len(self._free) < 4:
            self._free.append(buf)



def _channel_record(data, where: str) -> Channel:
    """A Channel record's body parsed, or a LogError naming the file."""
    try:
        return Channel.read(ReadDataStream(io.BytesIO(data)))
    except Exception:
        raise LogError(f"{where}: a damaged channel record") from None


def _undecompressed(where: str, limits: ReadLimits, exc: Exception) -> LogError:
    """The error of a chunk zstd cannot decompress within the decoder's window."""
    return LogError(f"{where}: a chunk does not decompress ({exc}; the decoder's window is at "
                    f"most {limits.max_window_bytes:,} bytes, TOUCHDOWN_MAX_WINDOW_MIB)")


def _nothing_past(r, piece, declared: int, where: str) -> None:
    """A chunk read as a stream to its declared size (``r``: its decompressing reader) holds
    nothing more."""
    if r.readinto(piece):
        raise LogError(f"{where}: a chunk declares {declared:,} bytes uncompressed but holds "
                       f"more")

def _chunk_data(chunk: Chunk, where: str, limits: ReadLimits,
                buffers: ChunkBuffers | None = None) -> bytes:
    """The chunk's records, decompressed within bounds (module docstring); CRC checked."""
    return decompress_chunk(chunk.data, chunk.compression, chunk.uncompressed_size,
                            chunk.uncompressed_crc, where, limits, buffers=buffers)


def _check_declared(declared: int, where: str, limits: ReadLimits) -> None:
    if declared > limits.max_chunk_bytes:
        raise LogError(f"{where}: a chunk claims {declared:,} bytes uncompressed (limit "
                       f"{limits.max_chunk_bytes:,}, {limits.chunk_bound}); refusing it")


def decompress_chunk(records, compression: str, declared: int, crc: int, where: str,
                     limits: ReadLimits, lz4: bool = False,
                     buffers: ChunkBuffers | None = None) -> bytes:
    """A chunk's ``records`` field decompressed within bounds: at most ``declared`` bytes,
    which must be within the limits, and exactly that many; its CRC (``crc``, 0: none) checked.
    ``lz4``: take lz4 too (``touchdown doctor`` on any MCAP file; Touchdown's readers refuse it,
    as its writers never use it). ``buffers``: decompressed into one of them (a memoryview of
    it is returned). LogError naming ``where`` otherwise."""
    _check_declared(declared, where, limits)
    if compression == "":
        data = records
    elif compression == "zstd":
        try:
            dctx = zstandard.ZstdDecompressor(max_window_size=limits.max_window_bytes)
            # into a buffer of the declared size (checked above), and one byte more: enough to
            # know a chunk holds more than it declares
            out = bytearray(declared + 1) if buffers is None else buffers.take(declared + 1)
            view = memoryview(out)
            got = 0
            with dctx.stream_reader(records, read_across_frames=True) as r:  # (no copy)
                while got <= declared:
                    n = r.readinto(view[got:declared + 1])
                    if not n:
                        break
                    got += n
            view.release()
        except zstandard.ZstdError as exc:
            raise _undecompressed(where, limits, exc) from None
        data = out if got == len(out) and buffers is None else memoryview(out)[:got]
    elif compression == "lz4" and lz4:
        import lz4.frame as lz4f
        try:
            data = lz4f.LZ4FrameDecompressor().decompress(bytes(records),
                                                          max_length=declared + 1)
        except RuntimeError as exc:
            raise LogError(f"{where}: a chunk does not decompress (lz4: {exc})") from None
    else:
        raise LogError(f"{where}: chunk compression {compression!r} is not supported "
                       f"(zstd or none)")
    if len(data) != declared:
        raise LogError(f"{where}: a chunk declares {declared:,} bytes uncompressed but holds "
                       f"{'more' if len(data) > declared else f'{len(data):,}'}")
    if crc != 0 and crc32(data) != crc:
        raise LogError(f"{where}: a chunk's CRC does not match its contents")
    return data


def _chunk_records(data: bytes, where: str, limits: ReadLimits, chunk: Chunk | None = None,
                   status: ReadStatus | None = None, offset: int = -1
                   ) -> Iterator[Channel | Message]:
    """The channels and messages in a chunk's records; other records skipped. With ``chunk``
    (its record, at byte ``offset``) and ``status``: a chunk whose message_start_time and
    message_end_time are not its messages' first and last log times is noted there, once its
    records have all been read (a reader that seeks by log time may skip its messages)."""
    i, end, count = 0, len(data), 0
    lo = hi = None
    while i < end:
        if end - i < 9:
            raise LogError(f"{where}: a chunk ends inside a record")
        op = data[i]
        (length,) = struct.unpack_from("<Q", data, i + 1)
        start, stop = i + 9, i + 9 + length
        if stop > end:
            raise LogError(f"{where}: a record runs past the end of its chunk")
        count += 1
        if count > limits.max_records_per_chunk:
            raise LogError(f"{where}: a chunk holds more than {limits.max_records_per_chunk:,} "
                           f"records (TOUCHDOWN_MAX_RECORDS_PER_CHUNK); refusing it")
        if op == 0x05:
            if length < 22:
                raise LogError(f"{where}: a message record too short for its header")
            channel_id, sequence, log_time, publish_time = struct.unpack_from("<HIQQ", data, start)
            if lo is None or log_time < lo:
                lo = log_time
            if hi is None or log_time > hi:
                hi = log_time
            yield Message(channel_id=channel_id, sequence=sequence, log_time=log_time,
                          publish_time=publish_time, data=data[start + 22:stop])
        elif op == 0x04:
            yield _channel_record(data[start:stop], where)
        i = stop
    if chunk is not None and status is not None and lo is not None and (
            chunk.message_start_time, chunk.message_end_time) != (lo, hi):
        status.note(offset, f"its message times say {chunk.message_start_time}.."
                            f"{chunk.message_end_time}, its messages' log times are {lo}..{hi}")


def _streamed_records(chunk: Chunk, where: str, limits: ReadLimits, channels: dict[int, str],
                      wanted, held: int) -> Iterator[Channel | Message]:
    """A header read of ``chunk`` (iter_messages' ``header``): its channels (added to
    ``channels`` as they come), then the first message ``wanted(message, channels)`` takes, and
    nothing after it. A zstd chunk is inflated as a stream, a piece at a time: every record
    before that message must end within HEADER_PREAMBLE_BYTES (schemas, other messages: skipped
    as they pass, not held), and the message may hold at most ``held`` bytes; whatever the chunk
    declares beyond it is never inflated (so its size and CRC are not checked, unless it ends
    without the message: then both are). Another chunk (uncompressed: in memory already; any
    other compression is refused) is read as any other."""
    if chunk.compression != "zstd":
        yield from _chunk_records(_chunk_data(chunk, where, limits), where, limits)
        return
    declared = chunk.uncompressed_size
    _check_declared(declared, where, limits)
    piece = bytearray(_PIECE)
    state = {"got": 0, "crc": 0}

    def take(n: int, keep: bool) -> bytes:
        """The next ``n`` bytes of the records (``keep``: returned, else passed over)."""
        if state["got"] + n > declared:
            raise LogError(f"{where}: a record runs past the end of its chunk")
        out = bytearray(n) if keep else None
        done = 0
        while done < n:
            m = min(n - done, _PIECE)
            view = memoryview(out)[done:done + m] if keep else memoryview(piece)[:m]
            k = r.readinto(view)
            if not k:
                raise LogError(f"{where}: a chunk declares {declared:,} bytes uncompressed but "
                               f"holds {state['got'] + done:,}")
            state["crc"] = crc32(view[:k], state["crc"])
            done += k
        state["got"] += n
        return out

    count = 0
    try:
        dctx = zstandard.ZstdDecompressor(max_window_size=limits.max_window_bytes)
        with dctx.stream_reader(chunk.data, read_across_frames=True) as r:
            while state["got"] < declared:
                if declared - state["got"] < 9:
                    raise LogError(f"{where}: a chunk ends inside a record")
                op, length = struct.unpack("<BQ", take(9, True))
                count += 1
                if count > limits.max_records_per_chunk:
                    raise LogError(f"{where}: a chunk holds more than "
                                   f"{limits.max_records_per_chunk:,} records "
                                   f"(TOUCHDOWN_MAX_RECORDS_PER_CHUNK); refusing it")
                if op == 0x05:
                    if length < 22:
                        raise LogError(f"{where}: a message record too short for its header")
                    cid, seq, log_time, publish_time = struct.unpack("<HIQQ", take(22, True))
                    m = Message(channel_id=cid, sequence=seq, log_time=log_time,
                                publish_time=publish_time, data=b"")
                    if wanted(m, channels):
                        if length - 22 > held:
                            raise LogError(f"{where}: a header of {length - 22:,} bytes (limit "
                                           f"{held:,}); refusing it")
                        m.data = take(length - 22, True)  # (iter_messages: bytes)
                        yield m
                        return
                    length -= 22
                if state["got"] + length > HEADER_PREAMBLE_BYTES:
                    raise LogError(f"{where}: no header within the first "
                                   f"{HEADER_PREAMBLE_BYTES:,} bytes of its chunk; refusing it")
                data = take(length, op == 0x04)
                if op == 0x04:
                    rec = _channel_record(data, where)
                    _add_channel(channels, rec, where)
                    yield rec
            _nothing_past(r, piece, declared, where)
    except zstandard.ZstdError as exc:
        raise _undecompressed(where, limits, exc) from None
    if chunk.uncompressed_crc != 0 and state["crc"] != chunk.uncompressed_crc:
        raise LogError(f"{where}: a chunk's CRC does not match its contents")


def _grown_records(chunk: Chunk, where: str, limits: ReadLimits, channels: dict[int, str],
                   wanted, grow: GrowingBound, offset: int) -> Iterator[Channel | Message]:
    """A chunk over ``grow.bound()`` read as a stream (GrowingBound): its channels (added to
    ``channels`` as they come) and wanted messages, then, if its last record runs past
    ``grow.prefix`` and is not a wanted message, nothing more (the chunk, at byte ``offset``,
    is appended to ``grow.deferred``, not inflated further: at most a piece past the prefix).
    The records are parsed from a buffer of inflated pieces (one record at a time, as
    _chunk_records does), a record kept whole only if wanted. A chunk that is not zstd is read
    as any other (uncompressed: in memory already; any other compression is refused)."""
    if chunk.compression != "zstd":
        yield from _chunk_records(_chunk_data(chunk, where, limits), where, limits)
        return
    declared = chunk.uncompressed_size
    _check_declared(declared, where, limits)
    piece = bytearray(_PIECE)
    buf = bytearray()  # inflated, not yet parsed past: buf[pos:] is the chunk from byte `at`
    pos = inflated = crc = 0
    key = (offset, declared, chunk.uncompressed_crc)
    last_at = grow.known.get(key)  # (a read before checked the chunk: its last record here)
    passed_at = None

    def inflate(n: int) -> memoryview:
        """The next at most ``n`` bytes of the chunk (a piece at most), CRC counted."""
        nonlocal inflated, crc
        view = memoryview(piece)[:min(n, _PIECE, declared - inflated)]
        k = r.readinto(view) if len(view) else 0
        if not k:
            raise LogError(f"{where}: a chunk declares {declared:,} bytes uncompressed but "
                           f"holds {inflated:,}")
        crc = crc32(view[:k], crc)
        inflated += k
        return view[:k]

    def buffered(n: int) -> None:
        """At least ``n`` bytes in buf after pos (pieces read ahead: a piece past at most)."""
        nonlocal buf, pos
        if pos > _PIECE:
            del buf[:pos]
            pos = 0
        while len(buf) - pos < n:
            buf += inflate(_PIECE)

    def body(n: int, keep: bool, checker=None) -> bytearray | None:
        """The next ``n`` bytes (a record's body): returned if ``keep``, else passed over
        (``checker``, if any, called on each piece as it arrives, and at the end); never
        inflated past them."""
        nonlocal pos
        have = min(n, len(buf) - pos)
        first = buf[pos:pos + have]
        out = first if keep else None
        if checker is not None and have:
            checker(first, False)
        pos += have
        left = n - have
        while left:
            got = inflate(left)
            if keep:
                out += got
            if checker is not None:
                checker(got, False)
            left -= len(got)
        if checker is not None:
            checker(b"", True)
        return out

    count = 0
    try:
        dctx = zstandard.ZstdDecompressor(max_window_size=limits.max_window_bytes)
        with dctx.stream_reader(chunk.data, read_across_frames=True) as r:
            while inflated - (len(buf) - pos) < declared:
                at = inflated - (len(buf) - pos)  # the record's first byte in the chunk
                if declared - at < 9:
                    raise LogError(f"{where}: a chunk ends inside a record")
                buffered(9)
                op = buf[pos]
                (length,) = struct.unpack_from("<Q", buf, pos + 1)
                pos += 9
                end = at + 9 + length
                if end > declared:
                    raise LogError(f"{where}: a record runs past the end of its chunk")
                count += 1
                if count > limits.max_records_per_chunk:
                    raise LogError(f"{where}: a chunk holds more than "
                                   f"{limits.max_records_per_chunk:,} records "
                                   f"(TOUCHDOWN_MAX_RECORDS_PER_CHUNK); refusing it")
                past = end > grow.prefix
                if past and end != declared:
                    raise LogError(f"{where}: a record runs past the {grow.prefix:,} bytes "
                                   f"a writer fills before it ends a chunk (to byte {end:,}) "
                                   f"and is not its chunk's last; refusing it")
                if op == 0x05:
                    if length < 22:
                        raise LogError(f"{where}: a message record too short for its header")
                    buffered(22)
                    cid, seq, log_time, publish_time = struct.unpack_from("<HIQQ", buf, pos)
                    pos += 22
                    m = Message(channel_id=cid, sequence=seq, log_time=log_time,
                                publish_time=publish_time, data=b"")
                    topic = channels.get(cid)
                    free = past and topic in grow.passed  # (bounded by the chunk's declared)
                    if wanted(m, channels):
                        if length - 22 > grow.held and not free:
                            raise LogError(f"{where}: a message of {length - 22:,} bytes (limit "
                                           f"{grow.held:,}); refusing it")
                        checker = (grow.check(topic) if past and grow.check is not None
                                   else None)
                        m.data = body(length - 22, True, checker)
                        passed_at = at if free else passed_at
                        yield m
                        continue
                    length -= 22
                    if free and at == last_at:  # checked to its end by a read before
                        return
                    if free:  # the chunk's last record, not wanted: passed over, not held
                        body(length, False, grow.check(topic) if grow.check is not None
                             else None)
                        passed_at = at
                        continue
                elif op == 0x04 and not past:
                    data = body(length, True)
                    rec = _channel_record(data, where)
                    _add_channel(channels, rec, where)
                    yield rec
                    continue
                if past:  # the chunk's last record, not wanted: not inflated (past a piece)
                    if grow.refuse is not None:
                        raise grow.refuse(declared)
                    grow.deferred.append((offset, declared, channels.get(cid)
                                          if op == 0x05 else None, cid if op == 0x05 else -1))
                    return
                body(length, False)
            _nothing_past(r, piece, declared, where)
    except zstandard.ZstdError as exc:
        raise _undecompressed(where, limits, exc) from None
    if chunk.uncompressed_crc != 0 and crc != chunk.uncompressed_crc:
        raise LogError(f"{where}: a chunk's CRC does not match its contents")
    if passed_at is not None and offset >= 0:
        grow.known[key] = passed_at


def _records_of(chunk: Chunk, name: str, limits: ReadLimits, status: ReadStatus, offset: int,
                buffers: ChunkBuffers | None, header: int, channels: dict[int, str], wanted,
                grow: GrowingBound | None = None) -> Iterator[Channel | Message]:
    """A chunk's channels and messages: all of them, decompressed within bounds and checked,
    or for a header read (``header`` > 0) of a chunk declaring more than HEADER_PREAMBLE_BYTES
    those up to its first wanted message (_streamed_records; the chunk is left in
    ``status.unchecked``), or for a read bounded by what it has read (``grow``) of a chunk over
    that bound, as a stream (_grown_records; the chunk may be left in ``grow.deferred``)."""
    if grow is not None and not header and chunk.uncompressed_size > grow.bound():
        # (all of it, before any is given: a chunk streamed is checked, its size and CRC, at
        # its end, or deferred; its records before its last are within grow.prefix)
        yield from list(_grown_records(chunk, name, limits, channels, wanted, grow, offset))
        return
    if not header or chunk.uncompressed_size <= HEADER_PREAMBLE_BYTES:
        yield from _chunk_records(_chunk_data(chunk, name, limits, buffers), name, limits, chunk,
                                  status, offset)
        return
    for rec in _streamed_records(chunk, name, limits, channels, wanted, header):
        if isinstance(rec, Message) and chunk.compression == "zstd":
            status.unchecked = (offset, chunk.uncompressed_size)
        yield rec


def _add_channel(channels: dict[int, str], rec: Channel, where: str) -> None:
    """Channel records repeat (in chunks and the summary); one id must keep one topic."""
    known = channels.get(rec.id)
    if known is not None and known != rec.topic:
        raise LogError(f"{where}: channel {rec.id} is declared as {known!r} and as {rec.topic!r}")
    channels[rec.id] = rec.topic


def _has_footer(f: IO[bytes], size: int) -> bool:
    if size < len(MAGIC) * 2 + _FOOTER_RECORD:
        return False
    f.seek(size - len(MAGIC))
    return f.read(len(MAGIC)) == MAGIC


def iter_messages(f: IO[bytes], name: str, topics: set[str], start_ns: int | None = None,
                  end_ns: int | None = None, status: ReadStatus | None = None,
                  limits: ReadLimits | None = None, views: bool = False, walk: bool = False,
                  buffers: ChunkBuffers | None = None, header: int = 0,
                  grow: GrowingBound | None = None) -> Iterator[tuple[str, int, bytes]]:
    """(topic, log_time_ns, data) of the messages on ``topics`` with start <= log_time <= end,
    within ``limits`` (default: ReadLimits.from_environment()). ``views``: data as memoryviews
    into the decompressed chunk (no copy), else bytes; ``buffers``: the chunks decompressed into
    these (with ``views``: the caller hands each chunk's buffer, its data's ``.obj``, back when
    done with its messages). ``walk``: read the data section record by record, not through the
    summary (a finished file whose summary or footer is damaged, but whose data section is
    whole: logs.structure). ``header`` > 0: a log's header read, the first message on ``topics``
    and nothing more, holding at most ``header`` bytes (_streamed_records: the chunk it lies in is
    inflated only up to it, and left in ``status.unchecked`` for the caller to read in full,
    chunk_at, once it knows what bounds it). ``grow``: a read whose chunks are bounded by what
    it has read so far (GrowingBound: a chunk over its bound is read as a stream, and may be
    left in its ``deferred`` for the caller to read in full, chunk_at, once the read is done)."""
    messages = _messages(f, name, topics, start_ns, end_ns, status, limits, walk,
                         buffers if views else None, header, grow)
    if header:
        try:
            for topic, t_ns, data in messages:
                yield topic, t_ns, bytes(data)
                return
        finally:
            messages.close()
    elif views:
        yield from messages
    else:
        for topic, t_ns, data in messages:
            yield topic, t_ns, bytes(data)


def _messages(f: IO[bytes], name: str, topics: set[str], start_ns: int | None,
              end_ns: int | None, status: ReadStatus | None, limits: ReadLimits | None,
              walk: bool = False, buffers: ChunkBuffers | None = None, header: int = 0,
              grow: GrowingBound | None = None) -> Iterator[tuple[str, int, bytes]]:
    status = status if status is not None else ReadStatus()
    limits = limits if limits is not None else ReadLimits.from_environment()
    f.seek(0, io.SEEK_END)
    size = f.tell()
    f.seek(0)
    if f.read(len(MAGIC)) != MAGIC:
        raise LogError(f"{name}: not an MCAP file (bad magic)")

    def wanted(m: Message, channels: dict[int, str]) -> bool:
        topic = channels.get(m.channel_id)
        return (topic in topics and (start_ns is None or m.log_time >= start_ns)
                and (end_ns is None or m.log_time <= end_ns))

    if not _has_footer(f, size):  # cut, or its writer was killed: read the intact part
        status.complete = False
        yield from _walk(f, name, wanted, status, limits, buffers, header, grow)
        return
    footer = None if walk else _footer(f, name, size)
    if walk or footer.summary_start == 0:  # finished, without a summary section (MCAP allows
        # it), or with a damaged summary or footer (logs.structure): the data section, walked
        yield from _walk(f, name, wanted, status, limits, buffers, header, grow)
        if status.damage:  # a finished file is whole: damage in it is not a cut
            raise LogError(f"{name}: damaged ({status.damage})")
        return
    yield from _indexed(f, name, size, footer, wanted, start_ns, end_ns, limits, topics, status,
                        buffers, header, grow)


def _footer(f, name: str, size: int) -> Footer:
    try:
        f.seek(size - len(MAGIC) - _FOOTER_RECORD)
        footer = next(StreamReader(f, skip_magic=True, record_size_limit=64).records)
    except Exception:  # noqa: BLE001 - any failure to parse it is damage
        footer = None
    if not isinstance(footer, Footer) or not 0 <= footer.summary_start < size:
        raise LogError(f"{name}: damaged footer")
    return footer


def _indexed(f, name: str, size: int, footer: Footer, wanted, start_ns: int | None,
             end_ns: int | None, limits: ReadLimits, topics: set[str] = frozenset(),
             status: ReadStatus | None = None, buffers: ChunkBuffers | None = None,
             header: int = 0, grow: GrowingBound | None = None
             ) -> Iterator[tuple[str, int, bytes]]:
    status = status if status is not None else ReadStatus()
    try:
        channels, chunk_indexes = _summary(f, name, size, footer, limits)
        mine = {cid for cid, topic in channels.items() if topic in topics}
        for ci in chunk_indexes:
            if ((start_ns is not None and ci.message_end_time < start_ns)
                    or (end_ns is not None and ci.message_start_time > end_ns)):
                continue  # seeking: chunks outside the window are never read
            if ci.message_index_offsets and mine and not mine.intersection(
                    ci.message_index_offsets):
                continue  # the chunk's index lists no message of the topics asked for
            if (ci.chunk_start_offset < len(MAGIC)
                    or ci.chunk_start_offset + ci.chunk_length > footer.summary_start):
                raise LogError(f"{name}: a chunk index points outside the data section")
            if ci.chunk_length > limits.max_chunk_bytes:
                raise LogError(f"{name}: a chunk of {ci.chunk_length:,} bytes (limit "
                               f"{limits.max_chunk_bytes:,}, TOUCHDOWN_MAX_CHUNK_MIB)")
            chunk = _read_chunk(f, ci.chunk_start_offset, ci.chunk_length, name)
            for rec in _records_of(chunk, name, limits, status, ci.chunk_start_offset, buffers,
                                   header, channels, wanted, grow):
                if isinstance(rec, Channel):
                    _add_channel(channels, rec, name)
                elif wanted(rec, channels):
                    yield channels[rec.channel_id], rec.log_time, rec.data
    except LogError:
        raise
    except Exception as exc:  # CRC, zstd, struct, record-length errors: all mean damage
        raise LogError(f"{name}: damaged ({type(exc).__name__}: {exc})") from None


#: a file's summary as read (its channels, its chunk indexes in order of time), by the file
#: object, its size and where its summary starts: the several reads of one log parse it once
_SUMMARIES: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _summary(f, name: str, size: int, footer: Footer, limits: ReadLimits
             ) -> tuple[dict[int, str], list]:
    """(channels by id, chunk indexes in order of time) of the file's summary section."""
    key = (size, footer.summary_start, limits.max_chunk_bytes)
    try:
        known = _SUMMARIES.get(f)
    except TypeError:  # a file object that takes no weak reference: read each time
        known = None
    if known is not None and known[0] == key:
        return dict(known[1]), known[2]
    f.seek(footer.summary_start)
    summary_len = size - len(MAGIC) - _FOOTER_RECORD - footer.summary_start
    if summary_len > limits.max_chunk_bytes:
        raise LogError(f"{name}: the summary section is {summary_len:,} bytes (limit "
                       f"{limits.max_chunk_bytes:,}, TOUCHDOWN_MAX_CHUNK_MIB)")
    buf = io.BytesIO(f.read(summary_len))
    reader = StreamReader(buf, skip_magic=True, validate_crcs=True,
                          record_size_limit=limits.max_chunk_bytes).records
    channels: dict[int, str] = {}
    chunk_indexes = []
    while buf.tell() < summary_len:  # the summary has no terminator: stop at its end
        rec = next(reader)
        if isinstance(rec, Channel):
            _add_channel(channels, rec, name)
        elif type(rec).__name__ == "ChunkIndex":
            chunk_indexes.append(rec)
    chunk_indexes.sort(key=lambda c: (c.message_start_time, c.chunk_start_offset))
    try:
        _SUMMARIES[f] = (key, dict(channels), chunk_indexes)
    except TypeError:
        pass
    return channels, chunk_indexes


def _read_chunk(f, offset: int, length: int, name: str) -> Chunk:
    """The chunk record at ``offset`` of ``length`` bytes (its index's), parsed as mcap's reader
    parses it, without a reader per chunk."""
    f.seek(offset)
    raw = f.read(length)
    where = f"{name}: expected a chunk at offset {offset}"
    if len(raw) != length or length < 9 + 8 * 3 + 4 + 4 + 8 or raw[0] != 0x06:
        raise LogError(where)
    (body_len,) = struct.unpack_from("<Q", raw, 1)
    if 9 + body_len != length:
        raise LogError(f"{where} (its record is {9 + body_len:,} bytes, its index says "
                       f"{length:,})")
    start, end, size, crc, n = struct.unpack_from("<QQQII", raw, 9)
    o = 9 + 32 + n
    if o + 8 > length:
        raise LogError(where)
    compression = bytes(raw[41:o]).decode("utf-8", "replace")
    (records_len,) = struct.unpack_from("<Q", raw, o)
    if o + 8 + records_len != length:
        raise LogError(f"{where} (its records run past it)")
    return Chunk(compression=compression, data=memoryview(raw)[o + 8:], message_start_time=start,
                 message_end_time=end, uncompressed_crc=crc, uncompressed_size=size)


def _walk(f, name: str, wanted, status: ReadStatus, limits: ReadLimits,
          buffers: ChunkBuffers | None = None, header: int = 0,
          grow: GrowingBound | None = None) -> Iterator[tuple[str, int, bytes]]:
    f.seek(len(MAGIC))
    reader = StreamReader(f, skip_magic=True, emit_chunks=True, validate_crcs=True,
                          record_size_limit=limits.max_chunk_bytes)
    channels: dict[int, str] = {}
    records = reader.records
    while True:
        try:
            rec = next(records)
        except StopIteration:
            return
        except Exception as exc:  # the end of the intact part
            status.damage = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
            return
        if type(rec).__name__ == "DataEnd":  # the data section's end: the summary follows
            return
        batch: list = [rec]
        if isinstance(rec, Chunk):
            try:
                # where it began: the bytes read, less the record (opcode, length, fields)
                at = len(MAGIC) + reader._stream.count - (9 + 8 * 3 + 4 + 4 + 8 + len(
                    rec.compression.encode()) + len(rec.data))
                batch = list(_records_of(rec, name, limits, status, at, buffers, header,
                                         channels, wanted, grow))
            except LogError as exc:  # a damaged or refused chunk ends the intact part too
                status.damage = str(exc).removeprefix(f"{name}: ")
                return
        for r in batch:
            if isinstance(r, Channel):
                _add_channel(channels, r, name)
            elif isinstance(r, Message) and wanted(r, channels):
                yield channels[r.channel_id], r.log_time, r.data


def chunk_at(f: IO[bytes], offset: int, name: str, limits: ReadLimits | None = None) -> bytes:
    """The records of the chunk record at ``offset``, decompressed within ``limits`` and
    CRC-checked; LogError if there is no sound chunk there."""
    limits = limits if limits is not None else ReadLimits.from_environment()
    try:
        f.seek(offset)
        chunk = next(StreamReader(f, skip_magic=True, emit_chunks=True, validate_crcs=True,
                                  record_size_limit=limits.max_chunk_bytes).records)
    except LogError:
        raise
    except Exception as exc:  # noqa: BLE001 - any failure to parse it is damage
        raise LogError(f"{name}: damaged chunk at byte {offset:,} ({type(exc).__name__})") from None
    if not isinstance(chunk, Chunk):
        raise LogError(f"{name}: expected a chunk at byte {offset:,}")
    return _chunk_data(chunk, name, limits)


def chunk_checked_at(f: IO[bytes], offset: int, name: str, grow: GrowingBound,
                     channels: dict[int, str], limits: ReadLimits | None = None) -> None:
    """The chunk record at ``offset`` read to its end, its size and CRC checked, as a read with
    ``grow`` (a final bound: its ``refuse`` set) reads it: whole if it declares at most
    ``grow.bound()``, else as a stream whose last record past ``grow.prefix`` must be a message
    on a ``grow.passed`` topic (``channels``: the topics by channel id), passed over (checked by
    ``grow.check``'s checker as it arrives), not held; LogError otherwise."""
    limits = limits if limits is not None else ReadLimits.from_environment()
    try:
        f.seek(offset)
        chunk = next(StreamReader(f, skip_magic=True, emit_chunks=True, validate_crcs=True,
                                  record_size_limit=limits.max_chunk_bytes).records)
    except Exception as exc:  # noqa: BLE001 - any failure to parse it is damage
        raise LogError(f"{name}: damaged chunk at byte {offset:,} ({type(exc).__name__})") from None
    if not isinstance(chunk, Chunk):
        raise LogError(f"{name}: expected a chunk at byte {offset:,}")
    if chunk.uncompressed_size <= grow.bound():
        _chunk_data(chunk, name, limits)
        return
    for _ in _grown_records(chunk, name, limits, dict(channels), lambda m, c: False, grow,
                            offset):
        pass


__all__ = ["iter_messages", "ReadStatus", "ReadLimits", "ChunkBuffers", "GrowingBound",
           "chunk_at", "chunk_checked_at", "decompress_chunk", "HEADER_PREAMBLE_BYTES"]
