"""An MCAP file examined record by record, as ``mcap doctor`` examines it and more strictly:
what ``touchdown doctor`` reports of a file's structure (its content is logs.reader's).

Every check of the Go ``mcap doctor`` (go/cli/mcap/cmd/doctor.go, and its Rust successor) is made,
with the same words where they fit, and these beside them:

- every record parsed strictly (logs.mcap_records): a string, byte array, map or array whose
  length runs past its record, a string that is not UTF-8, a footer or data end of the wrong
  size; the first record a Header, the last a Footer followed by the magic, no record outside
  its section (a chunk index in the data section, a message in the summary);
- each chunk decompressed (bounded: logs.safe_read) and its CRC checked; its records framed
  within it; its message_start_time and message_end_time against its messages' log times;
- the message index records after each chunk: one per channel with messages in the chunk,
  each entry pointing at a message of its channel at its time, and none left out;
- the data section's CRC (the Data End record's), the summary's CRC (the footer's), each
  attachment's CRC;
- each chunk index against its chunk (offset, length, times, compression, sizes, the offsets
  and total length of the message index records after it), and every chunk indexed;
- the statistics (every count, the first and last log time, each channel's message count);
- the summary grouped by opcode, each summary offset against the group it points at, the
  footer's summary_start and summary_offset_start where those sections begin;
- each attachment index and metadata index against the record it points at;
- schemas and channels: id 0, unknown schema, a message before its channel, records of one id
  that differ, summary copies of records not in the data section, indexed chunks' channels and
  schemas missing from the summary.

A finding is an error (the file is damaged or breaks the specification: ``touchdown doctor``
exits 1) or a warning (allowed, but a reader may stumble: messages out of log-time order, an
unknown profile). Nothing here trusts a length it has not checked against the file: records are
read within the file, chunks decompressed within logs.safe_read's limits.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import IO

import numpy as np

from touchdown.logs import LogError
from touchdown.logs.mcap_records import (CHUNK_OPS, DATA_OPS, FOOTER_RECORD,
                                         MAGIC, NAME, OP, SUMMARY_OPS, RecordError, chunk_header,
                                         parse, records)
from touchdown.logs.safe_read import ReadLimits, decompress_chunk

try:
    from zlib_ng.zlib_ng import crc32
except ImportError:  # pragma: no cover
    from zlib import crc32

#: the well-known profiles (the MCAP registry)
PROFILES = ("", "ros1", "ros2")
#: bytes read at a time where a record is only checksummed
_PIECE = 16 << 20


@dataclass
class Finding:
    level: str  # "error" or "warning"
    part: str  # "header", "chunk", "message index", "summary", "statistics", "footer", ...
    where: int  # byte offset in the file
    what: str

    def line(self) -> str:
        word = "problem" if self.level == "error" else "warning"
        return f"{word}: {self.part} at byte {self.where:,}: {self.what}"


@dataclass
class ChunkSeen:
    """A chunk found in the data section, and what its records hold."""

    offset: int
    length: int  # the whole record's
    start_ns: int
    end_ns: int
    compression: str
    compressed_size: int
    uncompressed_size: int
    #: channel id -> (offsets of its messages in the uncompressed records, their log times)
    messages: dict[int, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    #: channel id -> (offset of its message index record, the record's whole length)
    indexes: dict[int, tuple[int, int]] = field(default_factory=dict)
    readable: bool = True  # decompressed, its CRC matched, its records framed


@dataclass
class Examination:
    """What :func:`examine` found."""

    size: int = 0
    findings: list[Finding] = field(default_factory=list)
    records: dict[str, int] = field(default_factory=dict)  # record name -> how many
    chunks: list[ChunkSeen] = field(default_factory=list)
    messages: int = 0
    index_entries: int = 0  # message index entries checked against their chunks
    data_end: int = -1
    data_crc: str = "not reached"  # "matches", "absent" (0), "DIFFERS", "not reached"
    summary_crc: str = "not reached"
    footer: bool = False
    topics: set = field(default_factory=set)  # every channel's topic

    def error(self, part: str, where: int, what: str) -> None:
        self.findings.append(Finding("error", part, where, what))

    def warn(self, part: str, where: int, what: str) -> None:
        self.findings.append(Finding("warning", part, where, what))

    @property
    def errors(self) -> list[Finding]:
        return [f for f in self.findings if f.level == "error"]

    @property
    def warnings(self) -> list[Finding]:
        return [f for f in self.findings if f.level == "warning"]


class _Doctor:
    def __init__(self, f: IO[bytes], name: str, limits: ReadLimits):
        self.f, self.name, self.limits = f, name, limits
        self.x = Examination()
        self.schemas: dict[int, tuple] = {}  # id -> (name, encoding, data) of the data section
        self.channels: dict[int, tuple] = {}  # id -> (schema, topic, encoding, metadata)
        self.summary_schemas: set[int] = set()
        self.summary_channels: set[int] = set()
        self.channel_counts: dict[int, int] = {}
        self.min_t: int | None = None
        self.max_t: int | None = None
        self.attachments: dict[int, dict] = {}  # offset -> fields (and length)
        self.metadata: dict[int, tuple[int, str]] = {}  # offset -> (length, name)
        self.chunk_indexes: dict[int, tuple[int, dict]] = {}  # chunk offset -> (at, fields)
        self.attachment_indexes: list[tuple[int, dict]] = []
        self.metadata_indexes: list[tuple[int, dict]] = []
        self.statistics: tuple[int, dict] | None = None
        self.summary_offsets: list[tuple[int, dict]] = []
        self.summary_records: list[tuple[int, int, int]] = []  # (offset, op, whole length)
        self.summary_start = -1  # the first record after the data end
        self.offset_start = -1  # the first summary offset record
        self.last_chunk: ChunkSeen | None = None
        self.index_run_end = -1  # where the message index records after last_chunk end
        self.top_level_message = False
        #: messages whose log time is less than an earlier one's: [count, first's record, line]
        self.disorder: list | None = None

    # -- the walk ---------------------------------------------------------------------------
    def run(self) -> Examination:
        f, x = self.f, self.x
        f.seek(0, 2)
        size = x.size = f.tell()
        f.seek(0)
        if f.read(len(MAGIC)) != MAGIC:
            x.error("magic", 0, "the file does not begin with MCAP's magic: not an MCAP file")
            return x
        f.seek(max(0, size - len(MAGIC)))
        tail = size >= 2 * len(MAGIC) + FOOTER_RECORD and f.read(len(MAGIC)) == MAGIC
        end = size - len(MAGIC) if tail else size
        if not tail:
            x.error("footer", size, "the file does not end with MCAP's magic (cut, or its "
                                    "writer was killed): no footer, no summary")
        footer_at = end - FOOTER_RECORD if tail else -1
        hints = _chunk_hints(f, size) if tail else []
        crc = crc32(MAGIC)
        pos = len(MAGIC)
        first = True
        section = "data"
        last_summary_op = None
        seen_ops: set[int] = set()
        while pos < end:
            self.f.seek(pos)
            head = self.f.read(9)
            if len(head) < 9:
                x.error("data section" if section == "data" else section, pos,
                        f"the file ends inside a record's opcode and length ({len(head)} "
                        f"byte(s))")
                break
            op, length = head[0], struct.unpack_from("<Q", head, 1)[0]
            what = NAME.get(op, f"opcode 0x{op:02x}")
            if pos == footer_at and (op, length) != (OP["footer"], FOOTER_RECORD - 9):
                x.error("footer", pos, f"not a Footer record where the file's last record is "
                                       f"(opcode 0x{op:02x}, length {length:,})")
                break
            bad = ("not a record: opcode 0x00 is not valid" if op == 0 else
                   f"a {what} record of {length:,} bytes runs past the end of the file "
                   f"({end - pos - 9:,} bytes left)" if length > end - pos - 9 else "")
            if bad:
                in_run = self.last_chunk is not None and pos == self.index_run_end
                x.error("message index" if in_run else self._part(section), pos, bad)
                later = [h for h in hints if h > pos] if section == "data" else []
                if not later:
                    break
                x.warn("data section", later[0], f"the walk goes on at byte {later[0]:,}, the "
                                                 f"next chunk the summary indexes (the data "
                                                 f"section's CRC is not checked)")
                self._end_index_run(pos)
                pos, crc = later[0], None
                continue
            x.records[what] = x.records.get(what, 0) + 1
            whole = 9 + length
            body = self._body(op, length, pos)
            if op == OP["data end"] or crc is None:
                pass  # the CRC is of the bytes before the Data End record
            elif section == "data" and body is not None:
                crc = crc32(head, crc)
                crc = crc32(body, crc)
            elif section == "data":  # too large to hold: checksummed piece by piece
                crc = self._crc_of(pos, whole, crc)
            if first and op != OP["header"]:
                x.error("header", pos, f"the first record is a {what}, not a Header")
            first = False
            if op != OP["message index"]:
                self._end_index_run(pos)
            if op == OP["footer"]:
                self._footer(pos, body, end)
                pos += whole
                if pos != end:
                    x.error("footer", pos, f"{end - pos:,} bytes after the footer, before the "
                                           f"magic")
                break
            if section == "data":
                if op == OP["data end"]:
                    self._data_end(pos, body, crc)
                    section = "summary"
                    self.summary_start = pos + whole
                elif op == OP["header"] and pos != len(MAGIC):
                    x.error("data section", pos, "a second Header record")
                elif op not in DATA_OPS and op != OP["header"]:
                    self._unexpected(op, pos, "the data section")
                else:
                    self._data_record(op, pos, whole, body)
            else:
                if op == OP["summary offset"]:
                    section = "summary offsets"
                    if self.offset_start < 0:
                        self.offset_start = pos
                    self._summary_record(op, pos, body)
                elif section == "summary offsets":
                    self._unexpected(op, pos, "the summary offset section")
                elif op not in SUMMARY_OPS:
                    self._unexpected(op, pos, "the summary section")
                else:
                    if op != last_summary_op and op in seen_ops:
                        x.error("summary", pos, f"a {what} record apart from the others of its "
                                                f"kind (the summary must be grouped by opcode)")
                    seen_ops.add(op)
                    last_summary_op = op
                    self.summary_records.append((pos, op, whole))
                    self._summary_record(op, pos, body)
            pos += whole
        self._end_index_run(pos)
        if x.data_end < 0:
            x.error("data section", pos, "the file has no Data End record")
        if not x.footer and tail and not any(f.part == "footer" for f in x.errors):
            x.error("footer", pos, "the file has no Footer record")
        if self.disorder is not None:
            n, at, line = self.disorder
            x.warn("message", at, line + (f" (and {n - 1:,} more message(s) out of log-time "
                                          f"order)" if n > 1 else ""))
        self._cross_check()
        return x

    def _part(self, section: str) -> str:
        return {"data": "data section", "summary": "summary",
                "summary offsets": "summary offsets"}[section]

    def _body(self, op: int, length: int, pos: int):
        """The record's content, or None for one too large to hold (only checksummed)."""
        if length > self.limits.max_chunk_bytes:
            if op == OP["chunk"]:
                self.x.error("chunk", pos, f"a chunk record of {length:,} bytes (more than "
                                           f"{self.limits.max_chunk_bytes:,} read, "
                                           f"{self.limits.chunk_bound})")
            elif op == OP["attachment"]:
                self.x.warn("attachment", pos, f"an attachment of {length:,} bytes: not read "
                                               f"(its CRC is not checked)")
            else:
                self.x.error(NAME.get(op, "record"), pos, f"a record of {length:,} bytes")
            return None
        self.f.seek(pos + 9)
        return self.f.read(length)

    def _crc_of(self, pos: int, n: int, crc: int) -> int:
        self.f.seek(pos)
        while n > 0:
            piece = self.f.read(min(n, _PIECE))
            if not piece:
                break
            crc = crc32(piece, crc)
            n -= len(piece)
        return crc

    def _unexpected(self, op: int, pos: int, where: str) -> None:
        if op >= 0x80:
            self.x.warn("record", pos, f"a private record (opcode 0x{op:02x}) in {where}")
        elif op not in NAME:
            self.x.warn("record", pos, f"an unknown record (opcode 0x{op:02x}, reserved) in "
                                       f"{where}")
        else:
            self.x.error("record", pos, f"a {NAME[op]} record in {where}, where the "
                                        f"specification allows none")

    def _parse(self, op: int, body, pos: int, part: str):
        try:
            return parse(op, body)
        except RecordError as exc:
            self.x.error(part, pos, str(exc))
            return None

    # -- data section -----------------------------------------------------------------------
    def _data_record(self, op: int, pos: int, whole: int, body) -> None:
        x = self.x
        if body is None:
            return
        if op == OP["chunk"]:
            self._chunk(pos, whole, body)
            return
        if op == OP["message index"]:
            self._message_index(pos, whole, body)
            return
        rec = self._parse(op, body, pos, NAME[op])
        if rec is None:
            return
        if op == OP["header"]:
            if not rec.library:
                x.warn("header", pos, "Header.library is empty: set it to the software that "
                                      "wrote the file")
            if rec.profile not in PROFILES:
                x.warn("header", pos, f"Header.profile {rec.profile!r} is not a well-known "
                                      f"profile")
        elif op == OP["schema"]:
            self._schema(rec, pos, summary=False)
        elif op == OP["channel"]:
            self._channel(rec, pos, summary=False)
        elif op == OP["message"]:
            self.top_level_message = True
            self._message(rec.channel_id, rec.log_time, pos)
        elif op == OP["attachment"]:
            computed = crc32(memoryview(body)[:rec.crc_covers])
            if rec.crc and rec.crc != computed:
                x.error("attachment", pos, f"the attachment {rec.name!r}'s CRC does not match "
                                           f"its contents ({computed:08x} != {rec.crc:08x})")
            self.attachments[pos] = {**rec.fields, "length": whole}
        elif op == OP["metadata"]:
            self.metadata[pos] = (whole, rec.name)

    def _schema(self, rec, pos: int, summary: bool) -> None:
        x = self.x
        key = (rec.name, rec.encoding, bytes(rec.data))
        if rec.id == 0:
            x.error("schema", pos, "Schema.id 0 is reserved: no schema record may have it")
        if not rec.encoding and len(rec.data):
            x.error("schema", pos, f"schema {rec.id} has an empty encoding but "
                                   f"{len(rec.data):,} bytes of data")
        elif not rec.encoding and not summary:
            x.warn("schema", pos, f"schema {rec.id} ({rec.name!r}) has an empty encoding and "
                                  f"no data")
        previous = self.schemas.get(rec.id)
        if previous is not None and previous != key:
            x.error("schema", pos, f"two schema records with id {rec.id} differ")
        if summary:
            if previous is None:
                x.error("summary", pos, f"schema {rec.id} in the summary is not in the data "
                                        f"section")
            self.summary_schemas.add(rec.id)
        else:
            self.schemas.setdefault(rec.id, key)

    def _channel(self, rec, pos: int, summary: bool) -> None:
        x = self.x
        key = (rec.schema_id, rec.topic, rec.message_encoding, rec.metadata)
        previous = self.channels.get(rec.id)
        if previous is not None and previous != key:
            x.error("channel", pos, f"two channel records with id {rec.id} differ (topic "
                                    f"{previous[1]!r} / {rec.topic!r})")
        if rec.schema_id and rec.schema_id not in self.schemas:
            x.error("channel", pos, f"channel {rec.id} ({rec.topic!r}) names schema "
                                    f"{rec.schema_id}, not defined before it")
        if summary:
            if previous is None:
                x.error("summary", pos, f"channel {rec.id} in the summary is not in the data "
                                        f"section")
            self.summary_channels.add(rec.id)
        else:
            self.channels.setdefault(rec.id, key)
            self.x.topics.add(rec.topic)

    def _message(self, channel: int, t: int, pos: int) -> None:
        if channel not in self.channels:
            self.x.error("message", pos, f"a message on channel {channel} before any channel "
                                         f"record of that id")
        if self.max_t is not None and t < self.max_t:
            if self.disorder is None:
                topic = self.channels.get(channel, (0, "?"))[1]
                self.disorder = [0, pos, f"Message.log_time {t} on {topic!r} is less than the "
                                         f"latest log time {self.max_t}"]
            self.disorder[0] += 1
        self.x.messages += 1
        self.channel_counts[channel] = self.channel_counts.get(channel, 0) + 1
        self.min_t = t if self.min_t is None else min(self.min_t, t)
        self.max_t = t if self.max_t is None else max(self.max_t, t)

    def _chunk(self, pos: int, whole: int, body) -> None:
        x = self.x
        try:
            h = chunk_header(body)
        except RecordError as exc:
            x.error("chunk", pos, str(exc))
            return
        c = ChunkSeen(pos, whole, h.message_start_time, h.message_end_time, h.compression,
                      h.compressed_size, h.uncompressed_size)
        x.chunks.append(c)
        self.last_chunk, self.index_run_end = c, pos + whole
        at = h.records_at
        try:
            data = decompress_chunk(memoryview(body)[at:at + h.compressed_size], h.compression,
                                    h.uncompressed_size, h.uncompressed_crc, self.name,
                                    self.limits, lz4=True)
        except LogError as exc:
            c.readable = False
            x.error("chunk", pos, str(exc).removeprefix(f"{self.name}: "))
            return
        offsets: dict[int, list[int]] = {}
        times: dict[int, list[int]] = {}
        lo = hi = None
        try:
            for off, op, rbody in records(data, "its records",
                                          self.limits.max_records_per_chunk):
                if op not in CHUNK_OPS:
                    x.error("chunk", pos, f"a {NAME.get(op, f'opcode 0x{op:02x}')} record "
                                          f"inside a chunk (at byte {off:,} of its records)")
                    continue
                try:
                    rec = parse(op, rbody)
                except RecordError as exc:
                    x.error("chunk", pos, f"at byte {off:,} of its records: {exc}")
                    continue
                if op == OP["schema"]:
                    self._schema(rec, pos, summary=False)
                elif op == OP["channel"]:
                    self._channel(rec, pos, summary=False)
                else:
                    t = rec.log_time
                    self._message(rec.channel_id, t, pos)
                    offsets.setdefault(rec.channel_id, []).append(off)
                    times.setdefault(rec.channel_id, []).append(t)
                    lo = t if lo is None else min(lo, t)
                    hi = t if hi is None else max(hi, t)
        except RecordError as exc:
            c.readable = False
            x.error("chunk", pos, str(exc))
        c.messages = {ch: (np.array(offsets[ch], np.uint64), np.array(times[ch], np.uint64))
                      for ch in offsets}
        if lo is not None:
            if lo != c.start_ns:
                x.error("chunk", pos, f"Chunk.message_start_time {c.start_ns} does not match "
                                      f"the earliest message log time {lo}")
            if hi != c.end_ns:
                x.error("chunk", pos, f"Chunk.message_end_time {c.end_ns} does not match the "
                                      f"latest message log time {hi}")
        elif c.readable and (c.start_ns or c.end_ns):
            x.error("chunk", pos, f"a chunk with no message has times {c.start_ns}.."
                                  f"{c.end_ns} (zero, the specification says)")

    def _message_index(self, pos: int, whole: int, body) -> None:
        x = self.x
        rec = self._parse(OP["message index"], body, pos, "message index")
        c = self.last_chunk
        if c is None or pos != self.index_run_end:
            x.error("message index", pos, "a message index record that does not follow a chunk "
                                          "(or the message index records after one)")
            return
        self.index_run_end = pos + whole
        if rec is None:
            return
        ch = rec.channel_id
        if ch in c.indexes:
            x.error("message index", pos, f"a second message index of channel {ch} after the "
                                          f"chunk at byte {c.offset:,}")
            return
        c.indexes[ch] = (pos, whole)
        if not c.readable:
            return
        entries = rec.records
        x.index_entries += entries.shape[0]
        mine = c.messages.get(ch)
        if mine is None:
            x.error("message index", pos, f"an index of channel {ch}, which has no message in "
                                          f"the chunk at byte {c.offset:,}")
            return
        got = np.sort(entries, order=("off", "t"))
        want = np.zeros(mine[0].shape[0], got.dtype)
        want["off"], want["t"] = mine
        want = np.sort(want, order=("off", "t"))
        if got.shape != want.shape or not np.array_equal(got, want):
            missing = np.setdiff1d(want, got).shape[0] if got.shape != want.shape else 0
            wrong = np.setdiff1d(got, want)
            if wrong.shape[0]:
                t, off = int(wrong[0]["t"]), int(wrong[0]["off"])
                x.error("message index", pos,
                        f"an entry (time {t}, byte {off:,}) does not point at a message of "
                        f"channel {ch} at that time in the chunk at byte {c.offset:,} "
                        f"({wrong.shape[0]} such entries)")
            else:
                x.error("message index", pos,
                        f"its {got.shape[0]:,} entries leave out {missing:,} of channel {ch}'s "
                        f"{want.shape[0]:,} messages in the chunk at byte {c.offset:,}")
        if entries.shape[0] > 1 and (np.diff(entries["t"].astype(np.int64)) < 0).any():
            x.warn("message index", pos, "its entries are not in log-time order")

    def _end_index_run(self, pos: int) -> None:
        """The message index records after the last chunk have ended: one per channel with
        messages in it, if any."""
        c = self.last_chunk
        if c is None:
            return
        self.last_chunk = None
        if c.indexes and c.readable:
            missing = sorted(set(c.messages) - set(c.indexes))
            if missing:
                self.x.error("message index", c.offset + c.length,
                             f"no message index for channel(s) {missing} after the chunk at byte "
                             f"{c.offset:,}, which holds messages of them")

    def _data_end(self, pos: int, body, crc: int) -> None:
        x = self.x
        rec = self._parse(OP["data end"], body, pos, "data end")
        x.data_end = pos
        if rec is None:
            return
        if rec.data_section_crc == 0:
            x.data_crc = "absent"
        elif crc is None:
            x.data_crc = "not checked"
        elif rec.data_section_crc == crc:
            x.data_crc = "matches"
        else:
            x.data_crc = "DIFFERS"
            x.error("data end", pos, f"the data section's CRC does not match its bytes "
                                     f"({crc:08x} != {rec.data_section_crc:08x}): a byte "
                                     f"before it changed")

    # -- summary ----------------------------------------------------------------------------
    def _summary_record(self, op: int, pos: int, body) -> None:
        if body is None:
            return
        rec = self._parse(op, body, pos, "summary" if op != OP["summary offset"]
                          else "summary offsets")
        if rec is None:
            return
        if op == OP["schema"]:
            self._schema(rec, pos, summary=True)
        elif op == OP["channel"]:
            self._channel(rec, pos, summary=True)
        elif op == OP["chunk index"]:
            if rec.chunk_start_offset in self.chunk_indexes:
                self.x.error("summary", pos, f"a second chunk index of the chunk at byte "
                                             f"{rec.chunk_start_offset:,}")
            self.chunk_indexes[rec.chunk_start_offset] = (pos, rec.fields)
        elif op == OP["attachment index"]:
            self.attachment_indexes.append((pos, rec.fields))
        elif op == OP["metadata index"]:
            self.metadata_indexes.append((pos, rec.fields))
        elif op == OP["statistics"]:
            if self.statistics is not None:
                self.x.error("summary", pos, "a second Statistics record")
            else:
                self.statistics = (pos, rec.fields)
                if rec.channel_message_counts:
                    missing = sorted((set(self.channels) | set(rec.channel_message_counts))
                                     - self.summary_channels)
                    if missing:
                        self.x.error("statistics", pos,
                                     f"it counts messages per channel, but channel(s) "
                                     f"{missing[:10]} are not in the summary before it")
        elif op == OP["summary offset"]:
            self.summary_offsets.append((pos, rec.fields))

    def _footer(self, pos: int, body, end: int) -> None:
        x = self.x
        rec = self._parse(OP["footer"], body, pos, "footer")
        x.footer = True
        if rec is None:
            return
        if pos + FOOTER_RECORD != end:
            return  # said by the caller
        has_summary = bool(self.summary_records) or self.offset_start >= 0
        want_start = self.summary_start if has_summary else 0
        if rec.summary_start != want_start:
            x.error("footer", pos, f"its summary_start {rec.summary_start:,} is not where the "
                                   f"summary section begins "
                                   f"({want_start:,}{'' if has_summary else ': none'})")
        want_offsets = max(self.offset_start, 0)
        if rec.summary_offset_start != want_offsets:
            x.error("footer", pos, f"its summary_offset_start {rec.summary_offset_start:,} is "
                                   f"not where the summary offset section begins "
                                   f"({want_offsets:,}{'' if want_offsets else ': none'})")
        if rec.summary_crc == 0:
            x.summary_crc = "absent"
            return
        # the CRC covers the summary from where the footer says it starts (the reader's view)
        start = rec.summary_start if 0 < rec.summary_start <= pos else pos
        crc = self._crc_of(start, pos - start, 0)
        crc = crc32(struct.pack("<BQQQ", OP["footer"], 20, rec.summary_start,
                                rec.summary_offset_start), crc)
        if crc == rec.summary_crc:
            x.summary_crc = "matches"
        else:
            x.summary_crc = "DIFFERS"
            x.error("summary", start, f"its CRC does not match the footer's ({crc:08x} != "
                                      f"{rec.summary_crc:08x})")

    # -- after the walk ---------------------------------------------------------------------
    def _cross_check(self) -> None:
        x = self.x
        chunks = {c.offset: c for c in x.chunks}
        for chunk_at, (at, ci) in sorted(self.chunk_indexes.items()):
            c = chunks.get(chunk_at)
            if c is None:
                x.error("summary", at, f"a chunk index points at byte {chunk_at:,}, where no "
                                       f"chunk record begins")
                continue
            if ci["chunk_length"] != c.length:
                x.error("summary", at, f"the chunk index of the chunk at byte {chunk_at:,} says "
                                       f"{ci['chunk_length']:,} bytes, the record is "
                                       f"{c.length:,}")
                continue
            for key, mine, what in (("message_start_time", c.start_ns, "message start time"),
                                    ("message_end_time", c.end_ns, "message end time"),
                                    ("compression", c.compression, "compression"),
                                    ("compressed_size", c.compressed_size, "compressed size"),
                                    ("uncompressed_size", c.uncompressed_size,
                                     "uncompressed size")):
                if ci[key] != mine:  # (either may be the damaged one)
                    x.error("chunk", chunk_at, f"its {what} is {mine!r}, its chunk index's (at "
                                               f"byte {at:,}) {ci[key]!r}")
            offsets = ci["message_index_offsets"]
            found = {ch: o for ch, (o, _n) in c.indexes.items()}
            if offsets and offsets != found:
                wrong = sorted(ch for ch in set(offsets) | set(found)
                               if offsets.get(ch) != found.get(ch))
                x.error("summary", at, f"the chunk index of the chunk at byte {chunk_at:,} "
                                       f"points at message indexes that are not there, or "
                                       f"leaves some out (channel(s) {wrong[:10]})")
            run = sum(n for _o, n in c.indexes.values())
            if offsets and ci["message_index_length"] != run:
                x.error("summary", at, f"the chunk index of the chunk at byte {chunk_at:,} says "
                                       f"its message indexes take {ci['message_index_length']:,} "
                                       f"bytes; they take {run:,}")
            for ch in sorted(c.messages):
                if ch not in self.summary_channels:
                    x.error("summary", at, f"the indexed chunk at byte {chunk_at:,} holds "
                                           f"messages of channel {ch}, not in the summary")
                schema = self.channels.get(ch, (0,))[0]
                if schema and schema not in self.summary_schemas:
                    x.error("summary", at, f"the indexed chunk at byte {chunk_at:,} holds "
                                           f"messages of schema {schema}, not in the summary")
        if self.chunk_indexes or self.summary_records:
            for c in x.chunks:
                if c.offset not in self.chunk_indexes:
                    x.error("summary", c.offset, f"no chunk index for the chunk at byte "
                                                 f"{c.offset:,}")
        if self.chunk_indexes and self.top_level_message:
            x.warn("data section", 0, "messages outside chunks in an indexed file: readers "
                                      "that use the index will miss them")
        for at, ai in self.attachment_indexes:
            a = self.attachments.get(ai["offset"])
            if a is None:
                x.error("summary", at, f"an attachment index points at byte {ai['offset']:,}, "
                                       f"where no attachment record begins")
                continue
            for key in ("length", "log_time", "create_time", "name", "media_type"):
                if a[key] != ai[key]:
                    x.error("summary", at, f"the attachment index of {a['name']!r} says {key} "
                                           f"{ai[key]!r}, the record {a[key]!r}")
            if ai["data_size"] != len(a["data"]):
                x.error("summary", at, f"the attachment index of {a['name']!r} says "
                                       f"{ai['data_size']:,} bytes of data, the record holds "
                                       f"{len(a['data']):,}")
        if self.summary_records or self.attachment_indexes:
            indexed = {ai["offset"] for _at, ai in self.attachment_indexes}
            for off, a in self.attachments.items():
                if off not in indexed:
                    x.error("summary", off, f"no attachment index for the attachment "
                                            f"{a['name']!r}")
        for at, mi in self.metadata_indexes:
            m = self.metadata.get(mi["offset"])
            if m is None:
                x.error("summary", at, f"a metadata index points at byte {mi['offset']:,}, "
                                       f"where no metadata record begins")
            elif (mi["length"], mi["name"]) != m:
                x.error("summary", at, f"the metadata index of {m[1]!r} says {mi['length']:,} "
                                       f"bytes named {mi['name']!r}, the record "
                                       f"{m[0]:,} bytes named {m[1]!r}")
        if self.metadata_indexes:
            indexed = {mi["offset"] for _at, mi in self.metadata_indexes}
            for off, (_n, name) in self.metadata.items():
                if off not in indexed:
                    x.warn("summary", off, f"no metadata index for the metadata {name!r}")
        self._statistics()
        self._summary_offsets()

    def _statistics(self) -> None:
        if self.statistics is None:
            return
        x = self.x
        at, s = self.statistics
        if not all(c.readable for c in x.chunks):
            return  # the counts of an unreadable chunk are unknown: said already
        truth = {"message_count": x.messages,
                 "schema_count": len([k for k in self.schemas if k]),
                 "channel_count": len(self.channels),
                 "attachment_count": len(self.attachments),
                 "metadata_count": len(self.metadata), "chunk_count": len(x.chunks)}
        if x.messages:
            truth["message_start_time"] = self.min_t
            truth["message_end_time"] = self.max_t
        for key, value in truth.items():
            if s[key] != value:
                x.error("statistics", at, f"Statistics.{key} is {s[key]:,}, the file holds "
                                          f"{value:,}")
        counts = s["channel_message_counts"]
        if counts:
            wrong = sorted(ch for ch in set(counts) | set(self.channel_counts)
                           if counts.get(ch, 0) != self.channel_counts.get(ch, 0))
            for ch in wrong[:5]:
                x.error("statistics", at, f"Statistics.channel_message_counts[{ch}] is "
                                          f"{counts.get(ch, 0):,}, the file holds "
                                          f"{self.channel_counts.get(ch, 0):,}")

    def _summary_offsets(self) -> None:
        x = self.x
        groups: dict[int, tuple[int, int]] = {}
        for pos, op, whole in self.summary_records:
            start, end = groups.get(op, (pos, pos))
            groups[op] = (start, pos + whole)
        for at, so in self.summary_offsets:
            op = so["group_opcode"]
            name = NAME.get(op, f"opcode 0x{op:02x}")
            group = groups.get(op)
            if group is None and so["group_length"] == 0:
                continue  # an empty group (the Python writer's, for indexes it has none of)
            if group is None:
                x.error("summary offsets", at, f"a summary offset of a group of {name} records, "
                                               f"which the summary does not hold")
            elif (so["group_start"], so["group_length"]) != (group[0], group[1] - group[0]):
                x.error("summary offsets", at,
                        f"the summary offset of the {name} records says bytes "
                        f"{so['group_start']:,} + {so['group_length']:,}; they are at "
                        f"{group[0]:,} + {group[1] - group[0]:,}")


def _chunk_hints(f, size: int) -> list[int]:
    """The chunks the summary indexes (their offsets, sorted), to go on past a damaged record of
    the data section, as logs.structure does; [] if the summary cannot be read."""
    from touchdown.logs.structure import check
    s = check(f, size)
    return sorted(c for c in s.indexed_chunks)


def examine(f: IO[bytes], name: str = "", limits: ReadLimits | None = None) -> Examination:
    """Every record of the MCAP file ``f`` checked (module docstring)."""
    limits = limits if limits is not None else ReadLimits.from_environment()
    return _Doctor(f, name, limits).run()


__all__ = ["examine", "Examination", "Finding", "ChunkSeen"]
