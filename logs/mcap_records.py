"""MCAP's records parsed strictly, as the MCAP specification defines them (version 0): every
string, byte array, map and array held within its record, every string valid UTF-8, every
fixed-size record exactly its size.

The stock readers differ in how they take a record whose field runs past its end: Python's
``mcap`` slices short and reads on, Foxglove's TypeScript reader refuses the file ("String
length 271 exceeds bounds of buffer"), Go's and Rust's refuse the record. Touchdown's checks
(logs.structure on every open, logs.examine for ``touchdown doctor``) hold every record to the
specification, so that a file one of those tools refuses is never called sound here.

Records may be extended by fields added at their end (the specification): bytes after the
known fields are allowed, except in the records it says will not be extended (Message, Data
End, Footer).
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any

import numpy as np

MAGIC = b"\x89MCAP0\r\n"
#: the record opcodes of MCAP 0
OP = {"header": 0x01, "footer": 0x02, "schema": 0x03, "channel": 0x04, "message": 0x05,
      "chunk": 0x06, "message index": 0x07, "chunk index": 0x08, "attachment": 0x09,
      "attachment index": 0x0A, "statistics": 0x0B, "metadata": 0x0C, "metadata index": 0x0D,
      "summary offset": 0x0E, "data end": 0x0F}
NAME = {op: name for name, op in OP.items()}
#: records allowed in the data section, in the summary section, and in a chunk
DATA_OPS = frozenset(OP[n] for n in ("schema", "channel", "message", "attachment", "chunk",
                                     "message index", "metadata", "data end"))
SUMMARY_OPS = frozenset(OP[n] for n in ("schema", "channel", "chunk index", "attachment index",
                                        "metadata index", "statistics"))
CHUNK_OPS = frozenset(OP[n] for n in ("schema", "channel", "message"))
#: the bytes of a footer record (opcode, length, its three fields) and of a data end record
FOOTER_RECORD = 1 + 8 + 8 + 8 + 4
DATA_END_RECORD = 1 + 8 + 4
#: a message record's fields before its data
MESSAGE_HEADER = 2 + 4 + 8 + 8
#: a message index entry: (log time, offset in the uncompressed chunk)
INDEX_ENTRY = np.dtype([("t", "<u8"), ("off", "<u8")])


class RecordError(ValueError):
    """A record that does not hold what the specification says it holds (one line)."""


@dataclass
class Record:
    """A parsed record: its opcode and its fields by name (the specification's names)."""

    op: int
    fields: dict[str, Any]

    def __getattr__(self, name: str):
        try:
            return self.fields[name]
        except KeyError:
            raise AttributeError(name) from None

    @property
    def kind(self) -> str:
        return NAME.get(self.op, f"opcode 0x{self.op:02x}")


class Fields:
    """A record's body read field by field, each within the body (RecordError otherwise)."""

    def __init__(self, body, what: str):
        self.b = memoryview(body)
        self.o = 0
        self.what = what

    def _need(self, n: int, name: str) -> None:
        if self.o + n > len(self.b):
            raise RecordError(f"{self.what}: its {name} runs past the end of the record "
                              f"({n:,} bytes from byte {self.o:,} of {len(self.b):,})")

    def _int(self, fmt: str, name: str) -> int:
        n = struct.calcsize(fmt)
        self._need(n, name)
        (v,) = struct.unpack_from(fmt, self.b, self.o)
        self.o += n
        return v

    def u8(self, name: str) -> int:
        return self._int("<B", name)

    def u16(self, name: str) -> int:
        return self._int("<H", name)

    def u32(self, name: str) -> int:
        return self._int("<I", name)

    def u64(self, name: str) -> int:
        return self._int("<Q", name)

    def _prefixed(self, prefix: str, name: str) -> memoryview:
        n = self._int(prefix, f"{name}'s length")
        if self.o + n > len(self.b):
            raise RecordError(f"{self.what}: its {name}'s length {n:,} runs past the end of the "
                              f"record ({len(self.b) - self.o:,} bytes left)")
        v = self.b[self.o:self.o + n]
        self.o += n
        return v

    def string(self, name: str) -> str:
        raw = self._prefixed("<I", name)
        try:
            return str(raw, "utf-8")
        except UnicodeDecodeError:
            raise RecordError(f"{self.what}: its {name} is not valid UTF-8") from None

    def bytes32(self, name: str) -> memoryview:
        return self._prefixed("<I", name)

    def bytes64(self, name: str) -> memoryview:
        return self._prefixed("<Q", name)

    def string_map(self, name: str) -> dict[str, str]:
        inner = Fields(self._prefixed("<I", name), f"{self.what}: its {name}")
        out: dict[str, str] = {}
        while inner.o < len(inner.b):
            key = inner.string("key")
            out[key] = inner.string(f"value of {key!r}")
        return out

    def id_map(self, name: str) -> dict[int, int]:
        """``Map<uint16, uint64>``: whole entries of 10 bytes."""
        raw = self._prefixed("<I", name)
        if len(raw) % 10:
            raise RecordError(f"{self.what}: its {name} takes {len(raw):,} bytes, not whole "
                              f"entries of 10")
        return {k: v for k, v in struct.iter_unpack("<HQ", raw)}

    def entries(self, name: str) -> np.ndarray:
        """``Array<Tuple<Timestamp, uint64>>``: whole entries of 16 bytes."""
        raw = self._prefixed("<I", name)
        if len(raw) % 16:
            raise RecordError(f"{self.what}: its {name} take {len(raw):,} bytes, not whole "
                              f"entries of 16")
        return np.frombuffer(raw, INDEX_ENTRY)

    def rest(self) -> memoryview:
        v = self.b[self.o:]
        self.o = len(self.b)
        return v

    def end(self, exact: bool) -> None:
        """``exact``: a record the specification will not extend holds nothing more."""
        if exact and self.o != len(self.b):
            raise RecordError(f"{self.what}: {len(self.b) - self.o:,} bytes after its last field")


def _header(f: Fields) -> dict:
    return {"profile": f.string("profile"), "library": f.string("library")}


def _footer(f: Fields) -> dict:
    return {"summary_start": f.u64("summary_start"),
            "summary_offset_start": f.u64("summary_offset_start"),
            "summary_crc": f.u32("summary_crc")}


def _schema(f: Fields) -> dict:
    return {"id": f.u16("id"), "name": f.string("name"), "encoding": f.string("encoding"),
            "data": f.bytes32("data")}


def _channel(f: Fields) -> dict:
    return {"id": f.u16("id"), "schema_id": f.u16("schema_id"), "topic": f.string("topic"),
            "message_encoding": f.string("message_encoding"),
            "metadata": f.string_map("metadata")}


def _message(f: Fields) -> dict:
    return {"channel_id": f.u16("channel_id"), "sequence": f.u32("sequence"),
            "log_time": f.u64("log_time"), "publish_time": f.u64("publish_time"),
            "data": f.rest()}


def _chunk(f: Fields) -> dict:
    return {"message_start_time": f.u64("message_start_time"),
            "message_end_time": f.u64("message_end_time"),
            "uncompressed_size": f.u64("uncompressed_size"),
            "uncompressed_crc": f.u32("uncompressed_crc"),
            "compression": f.string("compression"), "records": f.bytes64("records")}


def _message_index(f: Fields) -> dict:
    return {"channel_id": f.u16("channel_id"), "records": f.entries("records")}


def _chunk_index(f: Fields) -> dict:
    return {"message_start_time": f.u64("message_start_time"),
            "message_end_time": f.u64("message_end_time"),
            "chunk_start_offset": f.u64("chunk_start_offset"),
            "chunk_length": f.u64("chunk_length"),
            "message_index_offsets": f.id_map("message_index_offsets"),
            "message_index_length": f.u64("message_index_length"),
            "compression": f.string("compression"), "compressed_size": f.u64("compressed_size"),
            "uncompressed_size": f.u64("uncompressed_size")}


def _attachment(f: Fields) -> dict:
    out = {"log_time": f.u64("log_time"), "create_time": f.u64("create_time"),
           "name": f.string("name"), "media_type": f.string("media_type"),
           "data": f.bytes64("data")}
    out["crc_covers"] = f.o  # the CRC is of every byte before it
    out["crc"] = f.u32("crc")
    return out


def _attachment_index(f: Fields) -> dict:
    return {"offset": f.u64("offset"), "length": f.u64("length"), "log_time": f.u64("log_time"),
            "create_time": f.u64("create_time"), "data_size": f.u64("data_size"),
            "name": f.string("name"), "media_type": f.string("media_type")}


def _statistics(f: Fields) -> dict:
    return {"message_count": f.u64("message_count"), "schema_count": f.u16("schema_count"),
            "channel_count": f.u32("channel_count"),
            "attachment_count": f.u32("attachment_count"),
            "metadata_count": f.u32("metadata_count"), "chunk_count": f.u32("chunk_count"),
            "message_start_time": f.u64("message_start_time"),
            "message_end_time": f.u64("message_end_time"),
            "channel_message_counts": f.id_map("channel_message_counts")}


def _metadata(f: Fields) -> dict:
    return {"name": f.string("name"), "metadata": f.string_map("metadata")}


def _metadata_index(f: Fields) -> dict:
    return {"offset": f.u64("offset"), "length": f.u64("length"), "name": f.string("name")}


def _summary_offset(f: Fields) -> dict:
    return {"group_opcode": f.u8("group_opcode"), "group_start": f.u64("group_start"),
            "group_length": f.u64("group_length")}


def _data_end(f: Fields) -> dict:
    return {"data_section_crc": f.u32("data_section_crc")}


_PARSERS = {0x01: _header, 0x02: _footer, 0x03: _schema, 0x04: _channel, 0x05: _message,
            0x06: _chunk, 0x07: _message_index, 0x08: _chunk_index, 0x09: _attachment,
            0x0A: _attachment_index, 0x0B: _statistics, 0x0C: _metadata,
            0x0D: _metadata_index, 0x0E: _summary_offset, 0x0F: _data_end}
#: records the specification will not extend: exactly their fields
_EXACT = {0x02, 0x0F}


def parse(op: int, body, where: str = "") -> Record:
    """The record of opcode ``op`` with content ``body``, every field checked (RecordError
    naming the record and the field). An unknown opcode is a RecordError too."""
    parser = _PARSERS.get(op)
    if parser is None:
        raise RecordError(f"{where}an unknown record (opcode 0x{op:02x})")
    f = Fields(body, f"{where}the {NAME[op]} record")
    fields = parser(f)
    f.end(op in _EXACT)
    return Record(op, fields)


def chunk_header(body, where: str = "", total: int | None = None) -> Record:
    """A chunk record's fields before its records (the first 36 bytes and its compression),
    and the records' length, checked against the record's content length (``total``; default
    ``len(body)``: ``body`` may be only the record's head); ``records`` is not read."""
    f = Fields(body, f"{where}the chunk record")
    total = len(f.b) if total is None else total
    fields = {"message_start_time": f.u64("message_start_time"),
              "message_end_time": f.u64("message_end_time"),
              "uncompressed_size": f.u64("uncompressed_size"),
              "uncompressed_crc": f.u32("uncompressed_crc"),
              "compression": f.string("compression")}
    n = f.u64("records' length")
    if f.o + n > total:
        raise RecordError(f"{f.what}: its records' length {n:,} runs past the end of the record "
                          f"({total - f.o:,} bytes left)")
    fields["records_at"] = f.o  # where the records begin in the body
    fields["compressed_size"] = n
    return Record(0x06, fields)


def records(data, where: str, limit: int | None = None):
    """(offset, opcode, body) of each record of ``data`` (a chunk's uncompressed records),
    framing checked: RecordError at a record that runs past the end. ``limit``: at most this
    many records (RecordError past it)."""
    buf = memoryview(data)
    i, end, count = 0, len(buf), 0
    while i < end:
        if end - i < 9:
            raise RecordError(f"{where}: ends inside a record's opcode and length (byte {i:,})")
        op = buf[i]
        (length,) = struct.unpack_from("<Q", buf, i + 1)
        if length > end - i - 9:
            raise RecordError(f"{where}: the {NAME.get(op, f'opcode 0x{op:02x}')} record at "
                              f"byte {i:,} runs past the end ({length:,} bytes)")
        count += 1
        if limit is not None and count > limit:
            raise RecordError(f"{where}: more than {limit:,} records")
        yield i, op, buf[i + 9:i + 9 + length]
        i += 9 + length


__all__ = ["MAGIC", "OP", "NAME", "DATA_OPS", "SUMMARY_OPS", "CHUNK_OPS", "FOOTER_RECORD",
           "DATA_END_RECORD", "MESSAGE_HEADER", "INDEX_ENTRY", "RecordError", "Record",
           "Fields", "parse", "chunk_header", "records"]
