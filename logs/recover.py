"""``touchdown recover LOG -o OUT``: the readable part of a killed writer's or a damaged MCAP
file, rewritten as a complete, indexed MCAP (chunked, zstd, every CRC, a summary with chunk
indexes, statistics and summary offsets), as ``mcap recover`` does.

The file is read record by record from its start, every record held to the specification
(logs.mcap_records) and every chunk decompressed within bounds with its CRC checked
(logs.safe_read); the first damaged record ends the readable part (a log's ticks must follow one
another: nothing after a gap is kept). Schemas, channels, messages (their log and publish times
and sequence numbers), metadata and attachments are written again in the order read.

A Touchdown log whose read stopped short keeps only whole ticks: what was logged at the last
tick read is dropped (its events may be in the part that was lost), and a LogSummary is added
(``complete = false``, reason ``recovered``, the last tick kept and the events kept), so that
``touchdown replay --verify OUT`` checks the whole of it. A log that ends with its own summary is
kept as it is.
"""
from __future__ import annotations

import os
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Iterator

from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import register_schema

from touchdown.logs import LogError
from touchdown.logs.header import TOPIC_EVENTS, TOPIC_SCENARIO, TOPIC_SUMMARY, TOPIC_TICKS
from touchdown.logs.mcap_records import (CHUNK_OPS, FOOTER_RECORD, MAGIC, NAME, OP,
                                         RecordError, chunk_header, parse, records)
from touchdown.logs.safe_read import ReadLimits, decompress_chunk
from touchdown.proto import touchdown_pb2 as pb
from touchdown.sim import __version__ as PROJECT_VERSION

#: LogSummary.reason of a log rewritten by recover from a part of its file
REASON = "recovered"


@dataclass
class Recovered:
    """What :func:`recover` read and wrote."""

    messages: int = 0  # written (the added summary included)
    read: int = 0  # read from the file
    dropped: int = 0  # read but not written (the last, perhaps partial, tick)
    schemas: int = 0
    channels: int = 0
    metadata: int = 0
    attachments: int = 0
    #: why the read stopped before the file's Data End record ("" if it got there)
    damage: str = ""
    damage_at: int = -1
    touchdown: bool = False
    first_tick: int | None = None
    last_tick: int | None = None
    events: int = 0
    summary_added: bool = False
    notes: list[str] = field(default_factory=list)


def _records(f: IO[bytes], size: int, limits: ReadLimits, out: Recovered
             ) -> Iterator[tuple[str, object]]:
    """("header" | "schema" | "channel" | "message" | "metadata" | "attachment", record) of
    the file from its start to its Data End, or to the first damage (``out.damage``)."""
    end = size
    f.seek(max(0, size - len(MAGIC)))
    if size >= 2 * len(MAGIC) + FOOTER_RECORD and f.read(len(MAGIC)) == MAGIC:
        end = size - len(MAGIC)
    pos = len(MAGIC)

    def stop(what: str) -> None:
        out.damage, out.damage_at = what, pos

    while pos < end:
        f.seek(pos)
        head = f.read(9)
        if len(head) < 9:
            return stop("the file ends inside a record")
        op, length = head[0], struct.unpack_from("<Q", head, 1)[0]
        if op == 0:
            return stop("not a record (opcode 0x00)")
        if length > end - pos - 9:
            return stop(f"a {NAME.get(op, f'opcode 0x{op:02x}')} record of {length:,} bytes runs "
                        f"past the end of the file ({end - pos - 9:,} bytes left)")
        if op == OP["data end"]:
            return
        if length > limits.max_chunk_bytes:
            return stop(f"a {NAME.get(op, 'record')} of {length:,} bytes (limit "
                        f"{limits.max_chunk_bytes:,}, {limits.chunk_bound})")
        body = f.read(length)
        try:
            if op == OP["chunk"]:
                h = chunk_header(body)
                at = h.records_at
                data = decompress_chunk(memoryview(body)[at:at + h.compressed_size],
                                        h.compression, h.uncompressed_size,
                                        h.uncompressed_crc, "", limits, lz4=True)
                inner = [(NAME[rop], parse(rop, rbody)) for _o, rop, rbody in
                         records(data, "the chunk", limits.max_records_per_chunk)
                         if rop in CHUNK_OPS]
                yield from inner  # the chunk is whole before any of it is taken
            elif op in (OP["header"], OP["schema"], OP["channel"], OP["message"],
                        OP["metadata"], OP["attachment"]):
                rec = parse(op, body)
                if op == OP["attachment"]:
                    from touchdown.logs.examine import crc32
                    if rec.crc and crc32(memoryview(body)[:rec.crc_covers]) != rec.crc:
                        raise RecordError("an attachment's CRC does not match its contents")
                yield NAME[op], rec
            # message indexes, and records of the summary in the wrong place: not content
        except (RecordError, LogError) as exc:
            return stop(str(exc).removeprefix(": "))
        pos += 9 + length
    if pos >= end:
        stop("the file ends without a Data End record (cut, or its writer was killed)")


def recover(path: str | os.PathLike, out_path: str | os.PathLike,
            limits: ReadLimits | None = None) -> Recovered:
    """Rewrite the readable part of ``path`` as a complete MCAP at ``out_path`` (module
    docstring); written to ``OUT.partial`` and renamed once whole. LogError if ``path`` is not
    an MCAP file or holds nothing readable."""
    limits = limits if limits is not None else ReadLimits.from_environment()
    path, out_path = Path(path), Path(out_path)
    res = Recovered()
    try:
        f = open(path, "rb")
    except OSError as exc:
        raise LogError(f"{path}: cannot open: {exc.strerror}") from None
    with f:
        f.seek(0, 2)
        size = f.tell()
        f.seek(0)
        if f.read(len(MAGIC)) != MAGIC:
            raise LogError(f"{path}: not an MCAP file (bad magic)")
        taken = list(_records(f, size, limits, res))
    header = next((r for kind, r in taken if kind == "header"), None)
    schemas = {r.id: r for kind, r in taken if kind == "schema"}
    channels = {r.id: r for kind, r in taken if kind == "channel"}
    topic_of = {cid: c.topic for cid, c in channels.items()}
    messages = [r for kind, r in taken if kind == "message" and r.channel_id in channels]
    res.read = sum(1 for kind, _r in taken if kind == "message")
    if res.read != len(messages):
        res.notes.append(f"{res.read - len(messages)} message(s) of channels never declared "
                         f"were left out")
    res.touchdown = TOPIC_SCENARIO in topic_of.values()
    tick_ns = [m.log_time for m in messages if topic_of[m.channel_id] == TOPIC_TICKS]
    summary_kept = any(topic_of[m.channel_id] == TOPIC_SUMMARY for m in messages)
    if res.touchdown and not tick_ns:
        raise LogError(f"{path}: no tick record is readable ({res.damage or 'none written'}): "
                       f"nothing to recover")
    if not messages and not res.touchdown:
        raise LogError(f"{path}: no message is readable ({res.damage or 'none written'})")
    add_summary = None
    if res.touchdown and not summary_kept:
        scenario = pb.ScenarioRecord.FromString(next(
            m.data for m in messages if topic_of[m.channel_id] == TOPIC_SCENARIO))
        dt_ns = int(round(scenario.dt_s * 1e9))
        cut_ns = max(tick_ns)
        if res.damage and len(tick_ns) > 1:
            # the last tick read may have lost its events (and what followed it) with the rest
            kept = [m for m in messages if m.log_time < cut_ns]
            res.dropped = len(messages) - len(kept)
            messages = kept
            cut_ns = max(m.log_time for m in messages if topic_of[m.channel_id] == TOPIC_TICKS)
        events = sum(1 for m in messages if topic_of[m.channel_id] == TOPIC_EVENTS)
        add_summary = (cut_ns, pb.LogSummary(last_tick=cut_ns // dt_ns, complete=False,
                                             reason=REASON, event_count=events))
    if res.touchdown:
        ticks = sorted(m.log_time for m in messages if topic_of[m.channel_id] == TOPIC_TICKS)
        scenario = pb.ScenarioRecord.FromString(next(
            m.data for m in messages if topic_of[m.channel_id] == TOPIC_SCENARIO))
        dt_ns = int(round(scenario.dt_s * 1e9))
        res.first_tick, res.last_tick = ticks[0] // dt_ns, ticks[-1] // dt_ns
        res.events = sum(1 for m in messages if topic_of[m.channel_id] == TOPIC_EVENTS)
    partial = out_path.with_name(out_path.name + ".partial")
    try:
        with open(partial, "wb") as out:
            w = Writer(out, chunk_size=1 << 20, compression=CompressionType.ZSTD,
                       enable_crcs=True, enable_data_crcs=True)
            library = header.library if header is not None else ""
            w.start(profile=header.profile if header is not None else "",
                    library=f"{library}; recovered by touchdown {PROJECT_VERSION}".lstrip("; "))
            new_schema = {}
            for sid, sch in schemas.items():
                new_schema[sid] = w.register_schema(sch.name, sch.encoding, bytes(sch.data))
            new_channel = {}
            for cid, ch in channels.items():
                new_channel[cid] = w.register_channel(ch.topic, ch.message_encoding,
                                                      new_schema.get(ch.schema_id, 0),
                                                      dict(ch.metadata))
            res.schemas, res.channels = len(new_schema), len(new_channel)
            for kind, r in taken:
                if kind == "metadata":
                    w.add_metadata(r.name, dict(r.metadata))
                    res.metadata += 1
                elif kind == "attachment":
                    w.add_attachment(r.create_time, r.log_time, r.name, r.media_type,
                                     bytes(r.data))
                    res.attachments += 1
            for m in messages:
                w.add_message(new_channel[m.channel_id], log_time=m.log_time, data=bytes(m.data),
                              publish_time=m.publish_time, sequence=m.sequence)
            res.messages = len(messages)
            if add_summary is not None:
                t_ns, summary = add_summary
                summary_channel = next((new_channel[c] for c, t in topic_of.items()
                                        if t == TOPIC_SUMMARY), None)
                if summary_channel is None:  # (the log's writer declares it at its start)
                    summary_channel = w.register_channel(
                        TOPIC_SUMMARY, "protobuf", register_schema(w, pb.LogSummary))
                w.add_message(summary_channel, log_time=t_ns, data=summary.SerializeToString(),
                              publish_time=t_ns, sequence=0)
                res.messages += 1
                res.summary_added = True
            w.finish()
        os.replace(partial, out_path)
    except OSError as exc:
        partial.unlink(missing_ok=True)
        raise LogError(f"{out_path}: cannot write: {exc.strerror or exc}; nothing was kept") \
            from None
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    return res


__all__ = ["recover", "Recovered", "REASON"]
