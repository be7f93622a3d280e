"""A log's MCAP structure, checked the way ``mcap doctor`` checks it: the records of the data
section, the message indexes after each chunk, the summary (chunk indexes, statistics, summary
offsets, its CRC) and the footer.

Touchdown reads a log's content through the summary's chunk indexes (or, without them, chunk by
chunk from the start) and checks every chunk's CRC, so damage to the structure around the content
(an overwritten message index, a damaged summary or footer) need not touch what it reads. Other
readers depend on that structure: a reader that walks the file record by record (mcap's
StreamReader and NonSeekingReader, ``mcap cat``) stops at the first damaged record, and one that
seeks by the summary misses or misreads what the damaged index points at. :func:`check` finds such
damage without decompressing anything (``deep``: also each message index entry against the chunk
it indexes), and :meth:`Structure.line` says it in one line.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import IO

import numpy as np

from touchdown.logs.mcap_records import (DATA_END_RECORD, FOOTER_RECORD, MAGIC, NAME,
                                         RecordError, chunk_header, parse)

try:
    from zlib_ng.zlib_ng import crc32
except ImportError:  # pragma: no cover
    from zlib import crc32

_FOOTER_RECORD = FOOTER_RECORD
#: the record opcodes of MCAP 0 (mcap.opcode.Opcode)
KNOWN = NAME
_DATA_OPS = {0x01, 0x03, 0x04, 0x05, 0x06, 0x07, 0x09, 0x0C, 0x0F}
#: the most bytes of a record outside a chunk parsed field by field (a larger attachment is
#: only framed): the header, schemas, channels, metadata of a Touchdown log are far smaller
MAX_PARSED_BYTES = 1 << 20
#: the most records the walk and the summary parse look at (a writer puts a chunk and a message
#: index per channel in it for every megabyte or so: far fewer), and the largest message index
#: or summary section read (a hostile file must not make the check slow or large)
MAX_RECORDS = 500_000
MAX_INDEX_BYTES = 64 << 20
_ENTRY = np.dtype([("t", "<u8"), ("off", "<u8")])
_SUMMARY_OPS = {0x03, 0x04, 0x08, 0x0A, 0x0B, 0x0D, 0x0E}
#: a chunk record's head read to parse its fields before its records (the compression's name
#: is a few bytes; a longer one is damage)
_CHUNK_HEAD = 4096


@dataclass
class ChunkRef:
    """A chunk record found in the data section: where it is (``offset``, ``length`` of the
    whole record), its messages' time span and its uncompressed size."""

    offset: int
    length: int
    start_ns: int
    end_ns: int
    uncompressed_size: int
    compression: str = ""
    compressed_size: int = 0
    #: channel id -> (offset of its message index record, entries: time "t" and offset "off")
    indexes: dict[int, tuple[int, np.ndarray]] = field(default_factory=dict)
    index_end: int = 0  # the end of the message index records that follow it


@dataclass
class Problem:
    part: str  # "data section", "message index", "summary", "footer", ...
    where: int  # byte offset
    what: str


@dataclass
class Structure:
    """What :func:`check` found."""

    size: int = 0
    chunks: list[ChunkRef] = field(default_factory=list)
    message_indexes: int = 0
    data_end: int = -1  # offset of the DataEnd record (-1: not reached)
    footer_ok: bool = False
    summary_ok: bool = False
    summary_records: int = 0
    chunk_indexes: int = 0
    statistics: dict = field(default_factory=dict)
    problems: list[Problem] = field(default_factory=list)
    #: the walk stopped at MAX_RECORDS records: the summary is not held to it
    walk_cut: bool = False
    #: the Data End record's CRC of the data section (0: not written), -1 if not reached
    data_crc: int = -1
    #: where the chunks the summary indexes begin (its chunk indexes' offsets, if it was read)
    indexed_chunks: list[int] = field(default_factory=list)

    def add(self, part: str, where: int, what: str) -> None:
        self.problems.append(Problem(part, where, what))

    @property
    def damaged(self) -> bool:
        return bool(self.problems)

    @property
    def content_reachable(self) -> bool:
        """Every chunk was found by walking the data section to its end."""
        return self.data_end >= 0

    def line(self) -> str:
        """One line: what is damaged, where, and what other readers will do ("" if nothing)."""
        if not self.problems:
            return ""
        p = self.problems[0]
        more = f" (and {len(self.problems) - 1} more problem(s))" if len(self.problems) > 1 else ""
        others = _CONSEQUENCES.get(p.part, _CONSEQUENCES["summary"])
        if p.part == "data end" and "CRC" in p.what:
            others = ("readers that check the data section's CRC (mcap's StreamReader with "
                      "CRCs on, `mcap doctor`) refuse the file, and the others may read the "
                      "changed byte as it is")
        return (f"the log's structure is damaged: {p.part} at byte {p.where:,}: {p.what}{more}; "
                f"its content is intact and was read through "
                f"{'its chunks' if not self.summary_ok else 'the chunk index'}, but {others} "
                f"(`touchdown doctor` for details)")


#: what other readers do with a file whose first problem is in this part (Structure.line)
_WALKERS = ("readers that walk the file record by record (mcap's StreamReader, `mcap cat`) stop "
            "there, and readers that seek by its index may miss messages")
_STRICT = ("readers that check every record's fields (Foxglove's, `mcap doctor`) refuse the "
           "file")
_CONSEQUENCES = {
    "data section": _WALKERS, "message index": _WALKERS,
    **{part: _STRICT for part in ("header", "schema", "channel", "message", "attachment",
                                  "metadata", "data end")},
    "chunk": ("readers that seek by log time (Foxglove, mcap's make_reader) may skip or "
              "misplace its messages"),
    "summary": ("readers that seek by the summary (mcap's make_reader on a file, Foxglove) may "
                "fail, misorder or miss messages; readers that walk the file are not affected"),
}


def _u64(b: bytes, o: int) -> int:
    return struct.unpack_from("<Q", b, o)[0]


def check(f: IO[bytes], size: int | None = None) -> Structure:
    """Walk the data section's records (their framing and, outside chunks, their fields; not
    the chunks' compressed contents), then the footer and summary, and hold each to the other
    (module docstring). The data section is walked to its Data End record whatever the footer
    says, so a damaged footer or summary start cannot hide the data."""
    if size is None:
        f.seek(0, 2)
        size = f.tell()
    s = Structure(size=size)
    f.seek(0)
    head = f.read(len(MAGIC))
    if head != MAGIC:
        s.add("magic", 0, "not an MCAP file")
        return s
    f.seek(size - len(MAGIC))
    tail_magic = size >= 2 * len(MAGIC) + _FOOTER_RECORD and f.read(len(MAGIC)) == MAGIC
    footer_at = size - len(MAGIC) - _FOOTER_RECORD if tail_magic else size
    footer = _footer(f, s, footer_at) if tail_magic else None
    if not tail_magic:
        s.add("footer", size, "the file ends without a footer (cut, or its writer was killed)")
    summary = _read_summary(f, s, footer, footer_at) if footer is not None and footer[0] else None
    hints = sorted(ci[1] for ci in summary[0]) if summary else []
    s.indexed_chunks = hints
    _walk(f, s, footer_at, hints)
    if footer is not None and s.data_end >= 0 and footer[0] and \
            footer[0] != s.data_end + DATA_END_RECORD:
        # (its summary's CRC, which covers the footer's fields, said so too: the footer is
        # the cause)
        s.problems = [p for p in s.problems if not (p.part == "summary" and p.where == footer[0])]
        s.add("footer", footer_at, f"its summary start {footer[0]:,} is not where the summary "
                                   f"begins (byte {s.data_end + DATA_END_RECORD:,}, after the "
                                   f"data end record)")
        s.footer_ok = False
        summary = None
    if summary is not None and not s.walk_cut:
        _cross_check(s, *summary)
    elif summary is not None:
        s.summary_ok = True  # not held to a walk that stopped short
    return s


def _footer(f, s: Structure, at: int):
    f.seek(at)
    rec = f.read(_FOOTER_RECORD)
    if rec[0] != 0x02 or _u64(rec, 1) != 8 + 8 + 4:
        s.add("footer", at, f"not a footer record (opcode 0x{rec[0]:02x})")
        return None
    summary_start, summary_offset_start = _u64(rec, 9), _u64(rec, 17)
    summary_crc = struct.unpack_from("<I", rec, 25)[0]
    if summary_start and not len(MAGIC) < summary_start <= at:
        s.add("footer", at, f"its summary start {summary_start:,} is outside the file")
        return None
    if summary_offset_start and not summary_start <= summary_offset_start <= at:
        s.add("footer", at, f"its summary offset start {summary_offset_start:,} is outside the "
                            f"summary")
        return None
    s.footer_ok = True
    return summary_start, summary_offset_start, summary_crc


def _read_summary(f, s: Structure, footer, footer_at: int):
    """(chunk indexes as (record offset, chunk start, chunk length, {channel: index offset},
    the index's fields), the statistics' fields or None), or None if the summary is damaged
    (its CRC, a record's framing or fields)."""
    start, offset_start, crc = footer
    if footer_at - start > MAX_INDEX_BYTES * 4:
        s.add("summary", start, f"a summary section of {footer_at - start:,} bytes (at most "
                                f"{MAX_INDEX_BYTES * 4:,} read)")
        return None
    f.seek(start)
    data = f.read(footer_at - start)
    if crc:
        whole = data + struct.pack("<BQQQ", 0x02, 20, start, offset_start)
        if crc32(whole) != crc:
            s.add("summary", start, "its CRC does not match the footer's")
            return None
    indexes, stats = [], None
    pos = 0
    while pos < len(data):
        at = start + pos
        if len(data) - pos < 9:
            s.add("summary", at, "ends inside a record")
            return None
        op, length = data[pos], _u64(data, pos + 1)
        if op not in _SUMMARY_OPS or pos + 9 + length > len(data):
            s.add("summary", at, f"not a record (opcode 0x{op:02x}, length {length:,})")
            return None
        body = data[pos + 9:pos + 9 + length]
        s.summary_records += 1
        if s.summary_records > MAX_RECORDS:
            s.add("summary", at, f"more than {MAX_RECORDS:,} records")
            return None
        try:
            rec = parse(op, body)
        except RecordError as exc:
            s.add("summary", at, str(exc))
            return None
        if op == 0x08:
            indexes.append((at, rec.chunk_start_offset, rec.chunk_length,
                            rec.message_index_offsets, rec.fields))
        elif op == 0x0B:
            stats = rec.fields
        pos += 9 + length
    s.chunk_indexes = len(indexes)
    return indexes, stats


def _walk(f, s: Structure, limit: int, hints: list[int]) -> None:
    """The data section's records from the header to DataEnd: framing, every record outside a
    chunk parsed field by field (the header first), each chunk's fields before its records,
    and its message indexes (which must follow their chunk and point inside it). Past a
    damaged record the walk goes on at the next chunk the summary knows of (``hints``), if
    any."""
    pos = len(MAGIC)
    last: ChunkRef | None = None
    count = 0
    while pos < limit:
        count += 1
        if count > MAX_RECORDS:
            s.walk_cut = True
            return
        f.seek(pos)
        head = f.read(9)
        op, length = (head[0], _u64(head, 1)) if len(head) == 9 else (-1, 0)
        if op not in _DATA_OPS or pos + 9 + length > limit:
            part = "message index" if last is not None and pos == last.index_end else \
                "data section"
            s.add(part, pos, f"not a record (opcode 0x{max(op, 0):02x}, length {length:,})")
            later = [h for h in hints if h > pos]
            if not later:
                return
            pos, last = later[0], None
            continue
        if (pos == len(MAGIC)) != (op == 0x01):
            s.add("header", pos, "the first record is not a header" if pos == len(MAGIC) else
                  "a second header record")
        if op == 0x06:
            body = f.read(min(length, _CHUNK_HEAD))
            try:
                h = chunk_header(body, total=length)
            except RecordError as exc:
                s.add("data section", pos, str(exc))
                later = [h for h in hints if h > pos]
                if not later:
                    return
                pos, last = later[0], None
                continue
            last = ChunkRef(pos, 9 + length, h.message_start_time, h.message_end_time,
                            h.uncompressed_size, h.compression, h.compressed_size)
            last.index_end = pos + 9 + length
            s.chunks.append(last)
        elif op == 0x07:
            body = f.read(length) if length <= MAX_INDEX_BYTES else b""
            problem = _message_index(body, last) if body else \
                f"a message index of {length:,} bytes (at most {MAX_INDEX_BYTES:,} read)"
            if problem.startswith("its message index"):  # the chunk's times, or the entry's
                s.add("chunk", last.offset, problem)
            elif problem:
                s.add("message index", pos, problem)
            else:
                channel = struct.unpack_from("<H", body, 0)[0]
                last.indexes[channel] = (pos, np.frombuffer(body, _ENTRY, offset=6))
                s.message_indexes += 1
            if last is not None and pos == last.index_end:
                last.index_end = pos + 9 + length
        elif length <= MAX_PARSED_BYTES:  # the header, schema, channel, metadata, data end...
            try:
                rec = parse(op, f.read(length))
            except RecordError as exc:
                s.add(NAME[op], pos, str(exc))
            else:
                if op == 0x0F:
                    s.data_crc = rec.data_section_crc
        if op == 0x0F:
            s.data_end = pos
            return
        pos += 9 + length
    s.add("data section", limit, "no data end record before the summary")


def _message_index(body: bytes, chunk: ChunkRef | None) -> str:
    if chunk is None:
        return "a message index before any chunk"
    if len(body) < 6:
        return "too short"
    n_bytes = struct.unpack_from("<I", body, 2)[0]
    if n_bytes % 16 or 6 + n_bytes != len(body):
        return f"its entries take {n_bytes:,} bytes of its {len(body) - 6:,}"
    e = np.frombuffer(body, _ENTRY, offset=6)
    bad = np.flatnonzero(e["off"] >= chunk.uncompressed_size)
    if bad.size:
        k = int(bad[0])
        return (f"entry {k} points at byte {int(e['off'][k]):,} of a chunk of "
                f"{chunk.uncompressed_size:,} bytes")
    bad = np.flatnonzero((e["t"] < chunk.start_ns) | (e["t"] > chunk.end_ns))
    if bad.size:
        k = int(bad[0])
        return (f"its message index's entry {k} (channel "
                f"{struct.unpack_from('<H', body, 0)[0]}) has time {int(e['t'][k])}, outside "
                f"the chunk's message times {chunk.start_ns}..{chunk.end_ns}")
    return ""


#: the fields a chunk index repeats of its chunk's: (its field, ChunkRef's, what it is)
_REPEATED = (("message_start_time", "start_ns", "message start time"),
             ("message_end_time", "end_ns", "message end time"),
             ("compression", "compression", "compression"),
             ("compressed_size", "compressed_size", "compressed size"),
             ("uncompressed_size", "uncompressed_size", "uncompressed size"))


def _cross_check(s: Structure, indexes: list, stats: dict | None) -> None:
    """The summary's chunk indexes against the chunks and message indexes the walk found, and
    its statistics against them."""
    by_offset = {c.offset: c for c in s.chunks}
    ok = True
    seen = set()
    index_problem = any(p.part == "message index" for p in s.problems)
    for at, chunk_start, chunk_length, offsets, fields_ in indexes:
        c = by_offset.get(chunk_start)
        if c is None or c.length != chunk_length:
            s.add("summary", at, f"a chunk index points at byte {chunk_start:,}, where no chunk "
                                 f"of {chunk_length:,} bytes starts")
            ok = False
            continue
        seen.add(chunk_start)
        for key, attr, what in _REPEATED:
            if fields_[key] != getattr(c, attr):
                # the chunk's own field or its index's is wrong: either way a reader that
                # seeks by the index and one that reads the chunk disagree
                s.add("chunk", chunk_start, f"its {what} is {getattr(c, attr)!r}, its chunk "
                                            f"index's (at byte {at:,}) {fields_[key]!r}")
                break
        if not index_problem and c.indexes and set(offsets) != set(c.indexes):
            # the reader skips a chunk whose index lists none of the channels it wants: an
            # index that leaves one out would hide its messages
            s.add("summary", at, f"the chunk index of the chunk at byte {chunk_start:,} lists "
                                 f"channels {sorted(offsets)}, its message indexes "
                                 f"{sorted(c.indexes)}")
            ok = False
            continue
        for ch, off in offsets.items():
            found = c.indexes.get(ch)
            if (found is None or found[0] != off) and not index_problem:
                s.add("message index", off, f"the chunk index of the chunk at byte "
                                            f"{chunk_start:,} points here for channel {ch}, but "
                                            f"no message index of that channel is here")
                index_problem = True
    missing = [c.offset for c in s.chunks if c.offset not in seen]
    if missing:
        s.add("summary", missing[0], f"no chunk index for the chunk at byte {missing[0]:,} "
                                     f"({len(missing)} chunk(s) unindexed)")
        ok = False
    if ok and stats is not None:
        total = sum(e.shape[0] for c in s.chunks for _, e in c.indexes.values())
        if not index_problem and stats["message_count"] != total:
            s.add("summary", 0, f"its statistics count {stats['message_count']:,} messages, the "
                                f"message indexes {total:,}")
        elif stats["chunk_count"] != len(s.chunks):
            s.add("summary", 0, f"its statistics count {stats['chunk_count']:,} chunks, the data "
                                f"section holds {len(s.chunks):,}")
        elif s.chunks and (stats["message_start_time"], stats["message_end_time"]) != (
                min(c.start_ns for c in s.chunks), max(c.end_ns for c in s.chunks)):
            s.add("summary", 0, f"its statistics' log times {stats['message_start_time']}.."
                                f"{stats['message_end_time']} are not its chunks' "
                                f"{min(c.start_ns for c in s.chunks)}.."
                                f"{max(c.end_ns for c in s.chunks)}")
    s.summary_ok = ok


def data_crc_matches(f, s: Structure) -> bool | None:
    """Whether the data section's bytes (the file's first ``s.data_end`` bytes) have the CRC
    its Data End record holds: None when it holds none (0: a log written before the writer
    wrote one, issue 37) or was not reached. Reads the data section once."""
    if s.data_end < 0 or s.data_crc <= 0:
        return None
    f.seek(0)
    crc, left = 0, s.data_end
    while left > 0:
        piece = f.read(min(left, 16 << 20))
        if not piece:
            return False
        crc = crc32(piece, crc)
        left -= len(piece)
    return crc == s.data_crc


def check_entries(f, s: Structure, name: str) -> int:
    """``mcap doctor``'s deeper check: every message index entry must point at a message record
    of its channel and time inside its (decompressed) chunk. Returns the entries checked; the
    problems are added to ``s``."""
    from touchdown.logs import LogError
    from touchdown.logs.safe_read import chunk_at
    checked = 0
    for c in s.chunks:
        if not c.indexes:
            continue
        try:
            data = chunk_at(f, c.offset, name)
        except LogError as exc:
            s.add("chunk", c.offset, str(exc).removeprefix(f"{name}: "))
            continue
        for channel, (at, entries) in c.indexes.items():
            for t, off in entries.tolist():
                checked += 1
                ok = off + 9 + 22 <= len(data) and data[off] == 0x05
                if ok:
                    ch, _seq, log_time = struct.unpack_from("<HIQ", data, off + 9)
                    ok = ch == channel and log_time == t
                if not ok:
                    s.add("message index", at, f"an entry (time {t}, byte {off:,}) does not "
                                               f"point at a message of channel {channel} at "
                                               f"that time")
                    break
    return checked


__all__ = ["check", "check_entries", "data_crc_matches", "Structure", "ChunkRef", "Problem"]
