"""Reading MCAP files that may be damaged or hostile, with bounded memory and no hangs.

The stock reader trusts a chunk's declared uncompressed size (a 33 KB file can make it allocate
1 GiB) and cannot read a file whose writer was killed before the footer. This reader:

* checks the magic, then reads the summary (chunk indexes, channels) when the footer is intact;
* otherwise (no footer: a killed writer, a truncated copy) walks the records from the start and
  keeps everything up to the first damaged byte, reporting that it recovered a prefix;
* refuses any record or chunk larger than ``MAX_RECORD_BYTES`` and any compression but zstd or
  none, before allocating for it; checks every CRC.

Every failure is a :class:`logs.LogError` with one line naming the file.
"""
from __future__ import annotations

import io
from dataclasses import dataclass
from typing import IO, Iterator

from mcap.records import Channel, Chunk, Footer, Message
from mcap.stream_reader import StreamReader, breakup_chunk

from logs import LogError

MAGIC = b"\x89MCAP0\r\n"
MAX_RECORD_BYTES = 256 * 1024 * 1024  # no Touchdown chunk comes near this (they are ~1 MiB)
_FOOTER_RECORD = 1 + 8 + 8 + 8 + 4  # opcode, length, summary_start, summary_offset_start, crc


@dataclass
class ReadStatus:
    """What a read found: ``complete`` False means the file ended early (no footer) and only a
    prefix was read; ``damage`` says what stopped the read."""

    complete: bool = True
    damage: str = ""


def _check_chunk(chunk: Chunk, where: str) -> None:
    if chunk.compression not in ("zstd", ""):
        raise LogError(f"{where}: chunk compression {chunk.compression!r} is not supported")
    if chunk.uncompressed_size > MAX_RECORD_BYTES:
        raise LogError(f"{where}: a chunk claims {chunk.uncompressed_size:,} bytes uncompressed "
                       f"(limit {MAX_RECORD_BYTES:,}); refusing it")


def _has_footer(f: IO[bytes], size: int) -> bool:
    if size < len(MAGIC) * 2 + _FOOTER_RECORD:
        return False
    f.seek(size - len(MAGIC))
    return f.read(len(MAGIC)) == MAGIC


def iter_messages(f: IO[bytes], name: str, topics: set[str], start_ns: int | None = None,
                  end_ns: int | None = None, status: ReadStatus | None = None
                  ) -> Iterator[tuple[str, int, bytes]]:
    """(topic, log_time_ns, data) of the messages on ``topics`` with start <= log_time <= end."""
    status = status if status is not None else ReadStatus()
    f.seek(0, io.SEEK_END)
    size = f.tell()
    f.seek(0)
    if f.read(len(MAGIC)) != MAGIC:
        raise LogError(f"{name}: not an MCAP file (bad magic)")

    def wanted(m: Message, channels: dict[int, str]) -> bool:
        topic = channels.get(m.channel_id)
        return (topic in topics and (start_ns is None or m.log_time >= start_ns)
                and (end_ns is None or m.log_time <= end_ns))

    if _has_footer(f, size):
        yield from _indexed(f, name, size, wanted, start_ns, end_ns)
        return
    status.complete = False
    yield from _walk(f, name, wanted, status)


def _indexed(f, name: str, size: int, wanted, start_ns: int | None, end_ns: int | None
             ) -> Iterator[tuple[str, int, bytes]]:
    try:
        f.seek(size - len(MAGIC) - _FOOTER_RECORD)
        footer = next(StreamReader(f, skip_magic=True, record_size_limit=64).records)
        if not isinstance(footer, Footer) or not 0 < footer.summary_start < size:
            raise LogError(f"{name}: damaged footer")
        f.seek(footer.summary_start)
        summary_len = size - len(MAGIC) - _FOOTER_RECORD - footer.summary_start
        if summary_len > MAX_RECORD_BYTES:
            raise LogError(f"{name}: summary section too large")
        buf = io.BytesIO(f.read(summary_len))
        reader = StreamReader(buf, skip_magic=True, validate_crcs=True,
                              record_size_limit=MAX_RECORD_BYTES).records
        channels: dict[int, str] = {}
        chunk_indexes = []
        while buf.tell() < summary_len:  # the summary has no terminator: stop at its end
            rec = next(reader)
            if isinstance(rec, Channel):
                channels[rec.id] = rec.topic
            elif type(rec).__name__ == "ChunkIndex":
                chunk_indexes.append(rec)
        chunk_indexes.sort(key=lambda c: (c.message_start_time, c.chunk_start_offset))
        for ci in chunk_indexes:
            if ((start_ns is not None and ci.message_end_time < start_ns)
                    or (end_ns is not None and ci.message_start_time > end_ns)):
                continue  # seeking: chunks outside the window are never read
            if ci.chunk_length > MAX_RECORD_BYTES or not 0 < ci.chunk_start_offset < size:
                raise LogError(f"{name}: a chunk index points outside the file or claims "
                               f"{ci.chunk_length:,} bytes")
            f.seek(ci.chunk_start_offset)
            chunk = next(StreamReader(f, skip_magic=True, emit_chunks=True, validate_crcs=True,
                                      record_size_limit=MAX_RECORD_BYTES).records)
            if not isinstance(chunk, Chunk):
                raise LogError(f"{name}: expected a chunk at offset {ci.chunk_start_offset}")
            _check_chunk(chunk, name)
            for rec in breakup_chunk(chunk, validate_crc=True):
                if isinstance(rec, Channel):
                    channels[rec.id] = rec.topic
                elif isinstance(rec, Message) and wanted(rec, channels):
                    yield channels[rec.channel_id], rec.log_time, rec.data
    except LogError:
        raise
    except Exception as exc:  # CRC, zstd, struct, record-length errors: all mean damage
        raise LogError(f"{name}: damaged ({type(exc).__name__}: {exc})") from None


def _walk(f, name: str, wanted, status: ReadStatus) -> Iterator[tuple[str, int, bytes]]:
    f.seek(len(MAGIC))
    reader = StreamReader(f, skip_magic=True, emit_chunks=True, validate_crcs=True,
                          record_size_limit=MAX_RECORD_BYTES)
    channels: dict[int, str] = {}
    records = reader.records
    while True:
        try:
            rec = next(records)
            batch = []
            if isinstance(rec, Chunk):
                _check_chunk(rec, name)
                batch = breakup_chunk(rec, validate_crc=True)
            else:
                batch = [rec]
        except StopIteration:
            return
        except LogError:
            raise
        except Exception as exc:  # the end of the intact part
            status.damage = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
            return
        for r in batch:
            if isinstance(r, Channel):
                channels[r.id] = r.topic
            elif isinstance(r, Message) and wanted(r, channels):
                yield channels[r.channel_id], r.log_time, r.data


__all__ = ["iter_messages", "ReadStatus", "MAX_RECORD_BYTES"]
