"""Hostile input at scale: ``touchdown bench fuzz [--files N]`` and the suite's fuzz test.

A deterministic corpus (seeded, generated here from tiny logs recorded on the spot) of damaged,
cut, crafted and hostile logs and scenario files is run through the commands a user runs on them
(``replay --verify``, ``export``, ``record``), in this process, each with a time bound (and, for a
campaign, the process's address space capped), and every outcome is classified:

    ok        exit 0, and what the command read is what the original held (or it said, plainly,
              that it read only part: "partial")
    diverged  exit 1 from verify naming a divergence (a changed number it can re-derive)
    refused   exit 2 with one line naming the file and key or field
    failed    exit 1 for a failure of the work (a full disk)
    silent    exit 0 but the content differs from the original's, unannounced
    traceback an exception escaped (exit 1 with a traceback, for a user)
    hang      over the time bound
    memory    MemoryError (over the address-space cap)
    broken    exit 0 from record, but the log it wrote does not verify or export valid JSON

Classes of logs: ``truncate``, ``bitflip``, ``overwrite``, ``garbage``, ``length`` (huge record
lengths), ``bomb`` (decompression bombs of every framing: zstd with and without a content size,
several frames, a huge window; "none" declaring more than it holds; lz4; millions of empty
records; a tick message of 100 MiB; a header's chunk declaring 200 MiB after the header, its
index listing no channel or the fleet's; a header's chunk ending in a fleet record of 150 MiB of
zeros), ``schema`` (wrong and random schemas), ``channel`` (unknown
channels, a channel re-declared with another topic), ``scenario_record`` (the log's own scenario
damaged: bad JSON, nesting 100,000 deep, huge integers, NaN and infinite ticks, keyframe
intervals of 2^31 - 1, altered tick counts), ``tick`` (a tick missing a field or with wrong
lengths), ``events`` (altered events and summary), ``index`` (an oversized chunk index),
``concat`` (two logs end to end). Classes of scenarios: ``scenario_file`` (a valid scenario with
one key set to a hostile value, or nested 1,000 tables deep, or with a 5,000-digit integer),
``set`` (hostile ``--set`` values).
"""
from __future__ import annotations

import contextlib
import io
import json
import random
import resource
import signal
import struct
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

MAGIC = b"\x89MCAP0\r\n"

LOG_CLASSES = ("truncate", "bitflip", "overwrite", "garbage", "length", "bomb", "schema", "channel",
               "scenario_record", "tick", "events", "index", "concat")
SCENARIO_CLASSES = ("scenario_file", "set")
OUTCOMES = ("ok", "partial", "diverged", "refused", "failed", "silent", "traceback", "hang",
            "memory", "broken")
#: the outcomes that are defects
BAD = ("silent", "traceback", "hang", "memory", "broken")


class Timeout(BaseException):
    """Raised by the alarm: a BaseException so that no ``except Exception`` in the code under test
    can swallow it."""


@dataclass
class Case:
    cls: str
    name: str
    command: str  # "verify" | "export" | "record"
    data: bytes = b""  # the file
    sets: tuple[str, ...] = ()
    original: bytes = b""  # the log it was made from (verify/export)


@dataclass
class Tally:
    counts: dict[str, dict[str, int]] = field(default_factory=dict)
    examples: dict[str, list[str]] = field(default_factory=dict)

    def add(self, cls: str, outcome: str, detail: str = "") -> None:
        self.counts.setdefault(cls, {o: 0 for o in OUTCOMES})[outcome] += 1
        if outcome in BAD:
            self.examples.setdefault(f"{cls}/{outcome}", []).append(detail)

    def bad(self) -> int:
        """Files whose outcome is a defect."""
        return sum(self.total(o) for o in BAD)

    def total(self, outcome: str) -> int:
        return sum(c[outcome] for c in self.counts.values())

    def table(self) -> str:
        cols = [o for o in OUTCOMES if self.total(o)] or ["ok"]
        lines = [f"{'class':<16}" + "".join(f"{c:>10}" for c in cols) + f"{'files':>8}"]
        for cls, c in self.counts.items():
            lines.append(f"{cls:<16}" + "".join(f"{c[o]:>10}" for o in cols)
                         + f"{sum(c.values()):>8}")
        lines.append(f"{'all':<16}" + "".join(f"{self.total(o):>10}" for o in cols)
                     + f"{sum(self.total(o) for o in OUTCOMES):>8}")
        return "\n".join(lines)


# -- MCAP bytes by hand (for what a writer would never write) ---------------------------------
def _s(text: str | bytes) -> bytes:
    b = text.encode() if isinstance(text, str) else text
    return struct.pack("<I", len(b)) + b


def _rec(opcode: int, body: bytes, length: int | None = None) -> bytes:
    return bytes([opcode]) + struct.pack("<Q", len(body) if length is None else length) + body


def _header() -> bytes:
    return _rec(0x01, _s("") + _s("fuzz"))


def _schema(sid: int, name: str, data: bytes, encoding: str = "protobuf") -> bytes:
    return _rec(0x03, struct.pack("<H", sid) + _s(name) + _s(encoding) + _s(data))


def _channel(cid: int, sid: int, topic: str) -> bytes:
    return _rec(0x04, struct.pack("<HH", cid, sid) + _s(topic) + _s("protobuf")
                + struct.pack("<I", 0))


def _message(cid: int, t_ns: int, data: bytes, seq: int = 0) -> bytes:
    return _rec(0x05, struct.pack("<HIQQ", cid, seq, t_ns, t_ns) + data)


def _chunk(records: bytes, compression: str = "", compressed: bytes | None = None,
           uncompressed_size: int | None = None, crc: int = 0) -> bytes:
    data = records if compressed is None else compressed
    size = len(records) if uncompressed_size is None else uncompressed_size
    body = (struct.pack("<QQQI", 0, 0, size, crc) + _s(compression)
            + struct.pack("<Q", len(data)) + data)
    return _rec(0x06, body)


def _data_end() -> bytes:
    return _rec(0x0F, struct.pack("<I", 0))


def _footer(summary_start: int) -> bytes:
    return _rec(0x02, struct.pack("<QQI", summary_start, 0, 0))


def _chunk_index(offset: int, chunk: bytes, channels: tuple[int, ...] = ()) -> bytes:
    """The ChunkIndex of a chunk record placed at ``offset`` (its fields copied from the chunk),
    listing message indexes of ``channels`` (none: a reader takes it to hold any channel)."""
    (start, end, uncompressed) = struct.unpack_from("<QQQ", chunk, 9)
    (n,) = struct.unpack_from("<I", chunk, 9 + 28)
    compression = chunk[9 + 32:9 + 32 + n]
    (compressed,) = struct.unpack_from("<Q", chunk, 9 + 32 + n)
    listed = b"".join(struct.pack("<HQ", cid, offset + len(chunk)) for cid in channels)
    return _rec(0x08, struct.pack("<QQQQ", start, end, offset, len(chunk))
                + struct.pack("<I", len(listed)) + listed
                + struct.pack("<Q", 0) + _s(compression) + struct.pack("<QQ", compressed,
                                                                        uncompressed))


def _header_records(scenario_msg: bytes) -> bytes:
    """A log's first records, as a writer puts them in its first chunk: schemas, channels, the
    scenario record."""
    return (_schema(1, "touchdown.v1.ScenarioRecord", _proto_descriptor())
            + _schema(2, "touchdown.v1.TickBatch", _proto_descriptor())
            + _channel(1, 1, "/touchdown/scenario") + _channel(2, 2, "/touchdown/ticks")
            + _message(1, 0, scenario_msg))


def _crafted_log(scenario_msg: bytes, extra_chunk: bytes, framing: str,
                 first: bytes | None = None) -> bytes:
    """A log holding our scenario record (in a chunk of its own, or ``first``), then a crafted
    chunk, framed as a writer-killed file (``walked``: no footer), a finished file without a
    summary section (``unindexed``), a finished file whose summary indexes both chunks, each
    index listing no channel (``indexed``: a reader takes such a chunk to hold any), or one
    whose summary declares the scenario, tick and fleet channels and whose first chunk's index
    lists the scenario's and the fleet's, as a writer's first chunk holding a join does
    (``fleet-indexed``: the fleet's read reads it)."""
    first = _chunk(_header_records(scenario_msg)) if first is None else first
    body = MAGIC + _header()
    offsets = (len(body), len(body) + len(first))
    body += first + extra_chunk + _data_end()
    if framing == "walked":
        return body
    if framing == "unindexed":
        return body + _footer(0) + MAGIC
    if framing == "fleet-indexed":
        summary = (_schema(1, "touchdown.v1.ScenarioRecord", _proto_descriptor())
                   + _schema(2, "touchdown.v1.TickBatch", _proto_descriptor())
                   + _schema(3, "touchdown.v1.FleetChange", _proto_descriptor())
                   + _channel(1, 1, "/touchdown/scenario") + _channel(2, 2, "/touchdown/ticks")
                   + _channel(3, 3, "/touchdown/fleet")
                   + _chunk_index(offsets[0], first, (1, 3))
                   + _chunk_index(offsets[1], extra_chunk, (2,)))
    else:
        summary = _chunk_index(offsets[0], first) + _chunk_index(offsets[1], extra_chunk)
    return body + summary + _footer(len(body)) + MAGIC


# -- the corpus ---------------------------------------------------------------------------------
#: the seed logs: (name, built-in scenario, its duration in s, keyframe every N ticks)
SEEDS = (("bounce", "bounce", 0.15, 1), ("fleet", "fleet", 0.1, 1), ("keyframes", "bounce", 0.2, 2))


def seed_logs(main, workdir: Path) -> dict[str, bytes]:
    """Tiny logs recorded by this version through ``main`` (the command line's root command): a
    bounce (4 ticks), a fleet (3 ticks), a bounce with keyframes every 2 ticks."""
    out = {}
    for name, scene, duration, every in SEEDS:
        path = workdir / f"{name}.mcap"
        code, _, err = invoke(main, ["record", scene, "--set", f"duration={duration}",
                                     "--keyframe-every", str(every), "-o", str(path)])
        if code != 0:
            raise RuntimeError(f"seed log {name}: {err}")
        out[name] = path.read_bytes()
    return out


def seed_logs_recorded(workdir: Path) -> dict[str, bytes]:
    """:func:`seed_logs` through the library (service.driver.record, what ``touchdown record``
    runs) rather than the command line: for the atheris harness, which must not import cli.py."""
    from touchdown import scenarios
    from touchdown.service.driver import record
    from touchdown.sim.scenario import parse_text
    out = {}
    for name, scene, duration, every in SEEDS:
        path = workdir / f"{name}.mcap"
        record(parse_text(scenarios.text(scene), scene, {"duration": duration}), path, scene,
               keyframe_interval=every)
        out[name] = path.read_bytes()
    return out


def _records_of(data: bytes) -> list[tuple[int, int, int]]:
    """(offset, opcode, length) of the top-level records of a well-formed log."""
    out, i = [], len(MAGIC)
    while i + 9 <= len(data) - len(MAGIC):
        op = data[i]
        (length,) = struct.unpack_from("<Q", data, i + 1)
        out.append((i, op, length))
        i += 9 + length
    return out


def _proto_descriptor() -> bytes:
    """Our .proto as a FileDescriptorSet (what a protobuf schema record holds)."""
    from google.protobuf import descriptor_pb2

    from touchdown.proto import touchdown_pb2 as pb
    fds = descriptor_pb2.FileDescriptorSet()
    pb.DESCRIPTOR.CopyToProto(fds.file.add())
    return fds.SerializeToString()


def _scenario_msg_of(log: bytes) -> bytes:
    from touchdown.logs.reader import LogReader
    with tempfile.NamedTemporaryFile(suffix=".mcap") as f:
        f.write(log)
        f.flush()
        with LogReader(f.name) as r:
            return r.scenario.SerializeToString()


def bombs(seed: bytes) -> list[tuple[str, bytes]]:
    """Decompression bombs and work bombs of every framing, as small files."""
    import zstandard

    scn = _scenario_msg_of(seed)
    out = []
    zeros = bytes(64 << 20)  # 64 MiB of zeros: a few KB compressed
    with_size = zstandard.ZstdCompressor(level=3).compress(zeros)
    no_size = zstandard.ZstdCompressor(level=3, write_content_size=False).compress(zeros)
    multi = b"".join(zstandard.ZstdCompressor(level=3).compress(bytes(8 << 20)) for _ in range(8))
    big_window = zstandard.ZstdCompressor(
        compression_params=zstandard.ZstdCompressionParameters(window_log=31)).compress(b"x" * 1000)
    for tag in ("walked", "unindexed", "indexed"):
        for name, comp, declared in (("zstd-claims-1000", with_size, 1000),
                                     ("zstd-claims-true", with_size, len(zeros)),
                                     ("zstd-no-content-size", no_size, 1000),
                                     ("zstd-eight-frames", multi, 1000),
                                     ("zstd-window-2GiB", big_window, 1000),
                                     ("zstd-claims-2^62", with_size, 1 << 62)):
            out.append((f"{name}-{tag}", _crafted_log(scn, _chunk(zeros[:0], "zstd", comp,
                                                                  declared), tag)))
        out.append((f"none-claims-more-{tag}", _crafted_log(scn, _chunk(b"\x00" * 100, "",
                                                                        None, 1 << 40), tag)))
        out.append((f"lz4-{tag}", _crafted_log(scn, _chunk(b"", "lz4", b"\x04\x22\x4d\x18" + bytes(64),
                                                           1000), tag)))
        # millions of empty records: 20 MiB of opcode-0, length-0 records (9 bytes each)
        empty = zstandard.ZstdCompressor(level=3).compress(bytes(20 << 20))
        out.append((f"empty-records-{tag}", _crafted_log(scn, _chunk(b"", "zstd", empty, 20 << 20),
                                                          tag)))
        # one tick message of 100 MiB whose one-byte fields all have their high bit set
        from touchdown.logs.codec import varint
        tick = b"\x22" + varint(100 << 20) + b"\x81" * (100 << 20)
        rec = _message(2, 0, tick)
        comp = zstandard.ZstdCompressor(level=3).compress(rec)
        out.append((f"tick-100MiB-{tag}", _crafted_log(scn, _chunk(b"", "zstd", comp, len(rec)),
                                                        tag)))
        # the header's own chunk declaring 200 MiB after it (sound: its size and CRC true)
        out.append((f"header-200MiB-{tag}", _crafted_log(scn, _chunk(b""), tag,
                                                          first=header_chunk(scn, 200 << 20))))
    for tag in ("fleet-indexed", "walked", "unindexed", "indexed"):
        if tag == "fleet-indexed":  # its index lists the fleet's channel: the fleet's read reads it
            out.append((f"header-200MiB-{tag}", header_bomb_of(scn, tag, 200)))
        # the header's chunk ending in a fleet record of 150 MiB of zeros (within the bound of
        # a fleet record, what a header may hold): not one, from its first byte
        out.append((f"fleet-record-150MiB-{tag}", _crafted_log(
            scn, _chunk(b""), tag, first=header_chunk(scn, 150 << 20, fleet=True))))
        # ending in a message of 150 MiB of zeros on the commands' channel (a tick's commands
        # may run past the fleet's bound: checked field by field as they are inflated)
        out.append((f"header-commands-150MiB-{tag}", _crafted_log(
            scn, _chunk(b""), tag, first=header_chunk(scn, 150 << 20, commands=True))))
    return out


def header_chunk(scenario_msg: bytes, after: int = 0, rng: random.Random | None = None,
                 fleet: bool = False, commands: bool = False) -> bytes:
    """A zstd chunk holding a log's header records (:func:`_header_records`) and then one record
    of an unknown opcode (0x80: readers skip it) of ``after`` bytes: zeros (a few kB compressed,
    compressed a MiB at a time), or with ``rng`` random bytes (zstd stores them as they are: a
    byte flipped there changes a byte of the records, not the frame). ``fleet``: that record is
    a message on the fleet's channel (declared before it, id 3) holding those bytes;
    ``commands``: on the commands' channel (id 6: the fleet does not bound a tick's commands).
    Its size and CRC are true: the chunk is sound, only big."""
    import zlib

    import zstandard
    if fleet or commands:
        cid, topic = (6, "/touchdown/commands") if commands else (3, "/touchdown/fleet")
        records = (_header_records(scenario_msg) + _channel(cid, 2, topic)
                   + _rec(0x05, struct.pack("<HIQQ", cid, 0, 0, 0), 22 + after))
    else:
        records = _header_records(scenario_msg) + _rec(0x80, b"", after)
    comp = zstandard.ZstdCompressor(level=3).compressobj()
    out = [comp.compress(records)]
    crc = zlib.crc32(records)
    left = after
    while left:
        n = min(left, 1 << 20)
        piece = bytes(n) if rng is None else rng.randbytes(n)
        crc = zlib.crc32(piece, crc)
        out.append(comp.compress(piece))
        left -= n
    out.append(comp.flush())
    return _chunk(b"", "zstd", b"".join(out), len(records) + after, crc)


def header_bomb(seed: bytes, framing: str, mib: int = 200) -> bytes:
    """A log (of ``framing``: _crafted_log's) whose first chunk, the one holding its header,
    holds ``mib`` MiB of zeros after it (:func:`header_chunk`; about 30 kB on disk)."""
    return header_bomb_of(_scenario_msg_of(seed), framing, mib)


def header_bomb_of(scenario_msg: bytes, framing: str, mib: int = 200) -> bytes:
    """:func:`header_bomb` of a scenario record (its bytes)."""
    return _crafted_log(scenario_msg, _chunk(b""), framing,
                        first=header_chunk(scenario_msg, mib << 20))


def log_cases(seeds: dict[str, bytes], n: int, rng: random.Random) -> list[Case]:
    """About n cases spread over the log classes (bombs are all included once)."""
    from touchdown.proto import touchdown_pb2 as pb

    names = sorted(seeds)
    every_bomb = bombs(seeds["bounce"])
    per = max(1, -(-(n - 2 * len(every_bomb)) // (len(LOG_CLASSES) - 1)))  # bombs: two commands
    cases: list[Case] = []

    def add(cls, name, data, original, command=None):
        cases.append(Case(cls, name, command or rng.choice(("verify", "verify", "export")), data,
                          original=original))

    for k in range(per):
        src = seeds[names[k % len(names)]]
        cut = rng.randrange(len(MAGIC), len(src))
        add("truncate", f"truncate@{cut}", src[:cut], src)
        flipped = bytearray(src)
        for _ in range(rng.randint(1, 8)):
            i = rng.randrange(len(src))
            flipped[i] ^= 1 << rng.randrange(8)
        add("bitflip", f"bitflip{k}", bytes(flipped), src)
        over = bytearray(src)
        i = rng.randrange(len(src))
        span = rng.randint(1, 64)
        over[i:i + span] = bytes(rng.randrange(256) for _ in range(span))
        add("overwrite", f"overwrite@{i}+{span}", bytes(over), src)
        junk = bytes(rng.randrange(256) for _ in range(rng.randint(0, 4096)))
        add("garbage", f"garbage{k}", [junk, MAGIC + junk, MAGIC + junk + MAGIC][k % 3], src)
        recs = _records_of(src)
        off, op, _ = recs[rng.randrange(len(recs))]
        longer = bytearray(src)
        struct.pack_into("<Q", longer, off + 1, rng.choice((1 << 31, 1 << 40, (1 << 64) - 1,
                                                            len(src) * 2)))
        add("length", f"length@{off}(op{op})", bytes(longer), src)
        add("schema", f"schema{k}", _mutate_schema(src, rng), src)
        add("channel", f"channel{k}", _mutate_channel(src, rng, k), src)
        add("scenario_record", f"scenario{k}", _mutate_scenario_record(src, rng, k, pb), src)
        add("tick", f"tick{k}", _mutate_tick(src, rng, k, pb), src)
        add("events", f"events{k}", _mutate_events(src, rng, k, pb), src)
        add("index", f"index{k}", _mutate_index(src, rng), src)
        other = seeds[names[(k + 1) % len(names)]]
        add("concat", f"concat{k}", [src + other, src + src[len(MAGIC):], src + b"\x00" * 100][k % 3],
            src)
    for name, data in every_bomb:
        add("bomb", name, data, seeds["bounce"], "verify")
        add("bomb", name, data, seeds["bounce"], "export")
    return cases


def rewrite_log(src: bytes, edit, schema=None) -> bytes:
    """A log rewritten through the mcap writer with each message passed through ``edit(topic, data)
    -> list of (topic, data)`` and each schema through ``schema(record) -> (name, encoding,
    data)`` (default: as it was); channels as they were."""
    from mcap.reader import make_reader
    from mcap.writer import CompressionType, Writer

    out = io.BytesIO()
    w = Writer(out, compression=CompressionType.ZSTD, enable_crcs=True)
    w.start()
    schemas, channels = {}, {}
    for sch, channel, message in make_reader(io.BytesIO(src)).iter_messages():
        if sch.id not in schemas:
            name, encoding, data = (sch.name, sch.encoding, sch.data) if schema is None else schema(sch)
            schemas[sch.id] = w.register_schema(name, encoding, data)
        for topic, data in edit(channel.topic, message.data):
            if topic not in channels:
                channels[topic] = w.register_channel(topic, "protobuf", schemas[sch.id])
            w.add_message(channels[topic], message.log_time, data, message.publish_time)
    w.finish()
    return out.getvalue()


def _mutate_schema(src: bytes, rng: random.Random) -> bytes:
    def schema(sch):
        data = rng.choice((b"", bytes(rng.randrange(256) for _ in range(64)), sch.data[:10]))
        name = rng.choice((sch.name, "touchdown.v1.Nope", "", "x" * 300))
        return name, rng.choice(("protobuf", "json", "")), data
    return rewrite_log(src, lambda topic, data: [(topic, data)], schema)


def _mutate_channel(src: bytes, rng: random.Random, k: int) -> bytes:
    from mcap.reader import make_reader
    from mcap.writer import CompressionType, Writer

    out = io.BytesIO()
    w = Writer(out, compression=CompressionType.ZSTD, enable_crcs=True)
    w.start()
    ids, chans = {}, {}
    moved = False
    for schema, channel, message in make_reader(io.BytesIO(src)).iter_messages():
        if schema.id not in ids:
            ids[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
        topic = channel.topic
        if k % 3 == 0 and topic == "/touchdown/ticks" and rng.random() < 0.5:
            topic = "/touchdown/events"  # a tick on the events channel
        elif k % 3 == 1 and topic == "/touchdown/events":
            topic = "/elsewhere"  # an unknown topic
        if topic not in chans:
            chans[topic] = w.register_channel(topic, "protobuf", ids[schema.id])
        w.add_message(chans[topic], message.log_time, message.data, message.publish_time)
        if k % 3 == 2 and topic == "/touchdown/ticks" and message.log_time > 0 and not moved:
            # the ticks' channel id declared again, inside the chunk, with another topic (the
            # stock writer cannot be asked to do this: write the record into its chunk)
            from mcap.records import Channel
            w._Writer__chunk_builder.add_channel(Channel(
                id=chans[topic], topic="/elsewhere", message_encoding="protobuf",
                schema_id=ids[schema.id], metadata={}))
            moved = True
    w.finish()
    return out.getvalue()


def _mutate_scenario_record(src: bytes, rng: random.Random, k: int, pb) -> bytes:
    def edit(topic, data):
        if topic != "/touchdown/scenario":
            return [(topic, data)]
        rec = pb.ScenarioRecord.FromString(data)
        doc = json.loads(rec.resolved_json)
        choice = k % 9
        if choice == 0:
            rec.resolved_json = "[" * 100_000 + "]" * 100_000
        elif choice == 1:  # a 5,000-digit integer, as text (Python won't build it from a string)
            doc["ships"][0]["mass"] = 123456.0
            rec.resolved_json = json.dumps(doc).replace("123456.0", "9" * 5000)
        elif choice == 2:
            doc["ships"][0]["mass"] = 10 ** 400
            rec.resolved_json = json.dumps(doc)
        elif choice == 3:
            rec.dt_s = rng.choice((float("nan"), float("inf"), 1e300, 0.0, -1.0))
        elif choice == 4:
            rec.keyframe_interval = (1 << 31) - 1
        elif choice == 5:
            rec.n_ticks = rng.choice((0, 1, (1 << 63), 10 ** 12))
        elif choice == 6:
            doc["sim"]["dt"] = rng.choice((1e-308, 1e300))
            rec.resolved_json = json.dumps(doc)
        elif choice == 7:
            doc["sim"]["max_substep"] = 1e-300
            rec.resolved_json = json.dumps(doc)
        else:
            rec.resolved_json = rec.resolved_json[: rng.randrange(len(rec.resolved_json))]
        return [(topic, rec.SerializeToString())]
    return rewrite_log(src, edit)


def _mutate_tick(src: bytes, rng: random.Random, k: int, pb) -> bytes:
    from touchdown.logs.codec import encode_tick
    from touchdown.logs.decode import decode_tick

    target = rng.randrange(4)

    def edit(topic, data):
        if topic != "/touchdown/ticks":
            return [(topic, data)]
        tick, t_s, count, arrays = decode_tick(data)
        if tick != target:
            return [(topic, data)]
        names = sorted(arrays)
        name = names[rng.randrange(len(names))]
        if k % 4 == 0:
            del arrays[name]
        elif k % 4 == 1:
            arrays[name] = arrays[name][:-1]
        elif k % 4 == 2:
            count = rng.choice((0, count + 1, 1 << 30))
        elif arrays[name].dtype.kind == "f":
            arrays[name] = arrays[name].copy()
            arrays[name][0] = rng.choice((float("nan"), float("inf"), 1e308, -1.0))
        else:
            arrays[name] = arrays[name].copy()
            arrays[name][0] = rng.choice((5, 99, 127))
        return [(topic, encode_tick(tick, t_s, count, arrays))]
    return rewrite_log(src, edit)


def _mutate_events(src: bytes, rng: random.Random, k: int, pb) -> bytes:
    def edit(topic, data):
        if topic == "/touchdown/events":
            ev = pb.TransitionEvent.FromString(data)
            field = k % 4
            if field == 0:
                ev.tick += 1
            elif field == 1:
                ev.to_state = (ev.to_state + 1) % 5
            elif field == 2:
                ev.ship_id = "someone-else"
            else:
                return []  # an event dropped
            return [(topic, ev.SerializeToString())]
        if topic == "/touchdown/summary":
            s = pb.LogSummary.FromString(data)
            s.last_tick += rng.choice((1, -1 if s.last_tick else 1, 1000))
            s.event_count += 1
            return [(topic, s.SerializeToString())]
        return [(topic, data)]
    return rewrite_log(src, edit)


def _mutate_index(src: bytes, rng: random.Random) -> bytes:
    """An oversized or misplaced chunk index in the summary."""
    data = bytearray(src)
    for off, op, length in _records_of(src):
        if op == 0x08:  # ChunkIndex: message_start_time, end_time, chunk_start_offset, length...
            field = rng.randrange(4)
            struct.pack_into("<Q", data, off + 9 + 8 * field,
                             rng.choice((1 << 40, len(src) * 3, 0, (1 << 64) - 1)))
            break
    return bytes(data)


def scenario_keys() -> tuple[str, ...]:
    """Every key a scenario may set, from the parser's own tables (so a new key is fuzzed too)."""
    from touchdown.sim import scenario as S
    tables = (("", S.TOP), ("sim.", S.SIM), ("contact.", S.CONTACT), ("body.", S.BODY),
              ("body.terrain.", S.TERRAIN), ("body.terrain.bumps[0].", S.BUMP),
              ("controller.", S.CONTROLLER), ("ships[0].", S.SHIP), ("ships[0].initial.", S.INITIAL),
              ("ships[0].inputs[0].", S.INPUT))
    return tuple(prefix + key for prefix, table in tables for key in table) + ("ships[0].inputs",)


def scenario_cases(n: int, rng: random.Random) -> list[Case]:
    from touchdown import scenarios
    # the bounce, short, with a bump in the ground and a command, so that every key is there
    base = (scenarios.text("bounce").replace("duration = 30.0", "duration = 0.2")
            .replace('name = "Luna"', 'name = "Luna"\n[[body.terrain.bumps]]\nradius = 50.0\n'
                                      'height = 1.0\neast = 300.0')
            + "\n[[ships.inputs]]\nt = 0.1\nthrottle = 0.5\n")
    keys = scenario_keys()
    values = ("1e308", "-1e308", "1e-308", "0", "-1", "nan", "inf", "-inf", "1e300",
              "'x'", "[1, 2]", "true", "{a = 1}", "9" * 400, "9" * 5000, "[1e308, 1, 1]",
              "[{t = 1e308, throttle = 1.0}]", "[{t = 0.1, rcs = [1e308, 0, 0]}]", "1e-300")
    cases = []
    for k in range(n):
        if k % 2 == 0:
            sets = tuple(f"{rng.choice(keys)}={rng.choice(values)}"
                         for _ in range(rng.randint(1, 2)))
            cases.append(Case("set", f"set:{' '.join(sets)}"[:120], "record", base.encode(), sets))
            continue
        kind = k % 10
        if kind == 1:
            text = base + f"\n[{'a.' * 999}a]\nb = 1\n"  # a table nested 1,000 deep
        elif kind == 3:
            text = base.replace("vertical_speed = -20.0", "vertical_speed = " + "9" * 5000)
        elif kind == 5:
            text = "x = " + "[" * 1000 + "]" * 1000 + "\n" + base
        elif kind == 7:
            text = base.replace("[ships.initial]", "[ships.initial]\n" + rng.choice(
                ("mass = 1", "altitude = -1e308", "state = 'tipped'", "tilt_deg = 1e308")))
        else:
            key, value = rng.choice(keys), rng.choice(values)
            text = base + f"\n# {key}\n"
            sets = (f"{key}={value}",)
            cases.append(Case("scenario_file", f"file+set:{key}={value[:20]}", "record",
                              text.encode(), sets))
            continue
        cases.append(Case("scenario_file", f"file{kind}", "record", text.encode()))
    return cases


# -- running ------------------------------------------------------------------------------------
def invoke(main, argv: list[str]) -> tuple[int | str, str, str]:
    """Run the click command in this process: (exit code or the escaped exception's name, stdout,
    stderr)."""
    import click

    out, err = io.StringIO(), io.StringIO()
    code: int | str = 0
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            main.main(argv, standalone_mode=False, prog_name="touchdown")
        except click.exceptions.Exit as exc:
            code = exc.exit_code
        except click.ClickException as exc:
            exc.show()
            code = exc.exit_code
        except click.exceptions.Abort:
            code = 1
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
        except (Timeout, MemoryError):
            raise
        except Exception as exc:  # noqa: BLE001 - escaped: what this harness counts
            code = f"{type(exc).__name__}: {str(exc)[:120]}"
    return code, out.getvalue(), err.getvalue()


def _content(path: str) -> tuple | None:
    """What a log holds, as today's reader reads it (None if it cannot)."""
    from touchdown.logs import LogError
    from touchdown.logs.header import TOPIC_EVENTS, TOPIC_SCENARIO, TOPIC_SUMMARY, TOPIC_TICKS
    from touchdown.logs.reader import LogReader
    try:
        with LogReader(path) as r:
            msgs = {t: [] for t in (TOPIC_SCENARIO, TOPIC_TICKS, TOPIC_EVENTS, TOPIC_SUMMARY)}
            for topic, _t, data in r.messages(set(msgs)):
                msgs[topic].append(data)
            return tuple(tuple(v) for v in msgs.values()), r.status.complete
    except LogError:
        return None


def run_case(main, case: Case, workdir: Path, seconds: float) -> tuple[str, str]:
    """(outcome, detail) of one case through ``main`` (the command line's root command), within
    ``seconds``."""
    path = workdir / "case.mcap"
    out_path = workdir / "out"
    for p in workdir.iterdir():
        if p.name != "case.mcap":
            p.unlink()

    def alarm(signum, frame):
        raise Timeout()

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        if case.command == "record":
            path = workdir / "case.toml"
            path.write_bytes(case.data)
            argv = ["record", str(path), "-o", str(out_path) + ".mcap"]
            for s in case.sets:
                argv += ["--set", s]
        else:
            path.write_bytes(case.data)
            argv = (["replay", str(path), "--verify"] if case.command == "verify"
                    else ["export", str(path), "-o", str(out_path) + ".jsonl"])
        code, stdout, stderr = invoke(main, argv)
        return _judge(main, case, code, stdout, stderr, path, out_path)
    except Timeout:
        return "hang", case.name
    except MemoryError:
        return "memory", case.name
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, old)


def _judge(main, case: Case, code, stdout: str, stderr: str, path: Path, out_path: Path
           ) -> tuple[str, str]:
    if isinstance(code, str):
        return "traceback", f"{case.name}: {code}"
    text = stdout + stderr
    if code == 2:
        lines = stderr.strip().splitlines()
        return ("refused", "") if len(lines) == 1 else ("traceback", f"{case.name}: {lines[-1:]}")
    if case.command == "record":
        if code != 0:
            return ("failed", "") if code == 1 else ("traceback", f"{case.name}: exit {code}")
        log = str(out_path) + ".mcap"
        vcode, _, verr = invoke(main, ["replay", log, "--verify"])
        ecode, eout, _ = invoke(main, ["export", log])
        bad_json = any(tok in eout for tok in ("NaN", "Infinity"))
        if vcode != 0 or ecode != 0 or bad_json:
            return "broken", f"{case.name}: verify {vcode} export {ecode} nan/inf {bad_json}"
        return "ok", ""
    if code == 1:
        return ("diverged", "") if "DIVERGED" in text else ("failed", "")
    if code != 0:
        return "traceback", f"{case.name}: exit {code}"
    partial_said = any(w in text for w in ("recovered", "partial", "only part", "ends without"))
    if case.command == "export":
        # export renders what the file holds (only verify can tell an altered log from its
        # original): every line valid JSON, and a file read only in part said so
        try:
            for line in (out_path.parent / (out_path.name + ".jsonl")).read_text().splitlines():
                json.loads(line, parse_constant=_no_constant)
        except (OSError, ValueError) as exc:
            return "silent", f"{case.name}: exit 0 but the export is not JSON lines ({exc})"
        got = _content(str(path))
        if got is None:
            return "silent", f"{case.name}: exit 0 but unreadable afterwards"
        if got[1]:
            return "ok", ""
        return ("partial", "") if partial_said else (
            "silent", f"{case.name}: exit 0, read only part, nothing said")
    # verify, exit 0: what it checked must be what the original held, or it must say it checked
    # only part
    got, orig = _content(str(path)), None
    with tempfile.NamedTemporaryFile(suffix=".mcap") as f:
        f.write(case.original)
        f.flush()
        orig = _content(f.name)
    if got is None or orig is None:
        return "silent", f"{case.name}: exit 0 but unreadable afterwards"
    (got_msgs, complete) = got
    if got_msgs == orig[0] and complete:
        return "ok", ""
    if partial_said:
        return "partial", ""
    return "silent", f"{case.name}: exit 0, content differs, nothing said"


def _no_constant(name: str):
    raise ValueError(f"{name} is not JSON")


def campaign(main, files: int, seed: int = 20261123, seconds: float = 20.0,
             classes: set[str] | None = None, progress=None) -> Tally:
    """Generate ``files`` cases and run each through ``main``, the command line's root command
    (cli.main: passed in, so that this module does not import the command line that runs it)."""
    rng = random.Random(seed)
    tally = Tally()
    with tempfile.TemporaryDirectory() as d:
        work = Path(d)
        seeds = seed_logs(main, work)
        n_logs = int(files * 0.8)
        cases = log_cases(seeds, n_logs, rng) + scenario_cases(files - n_logs, rng)
        if classes:
            cases = [c for c in cases if c.cls in classes]
        run_dir = work / "run"
        run_dir.mkdir()
        for i, case in enumerate(cases):
            outcome, detail = run_case(main, case, run_dir, seconds)
            tally.add(case.cls, outcome, detail)
            if progress:
                progress(i + 1, len(cases))
    return tally


def cap_memory(gib: float) -> None:
    limit = int(gib * (1 << 30))
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))


def main(command, files: int = 2000, seconds: float = 20.0, memory_gib: float = 1.5,
         as_json: bool = False, seed: int = 20261123) -> Tally:
    """Run a campaign in this process (its address space capped) and print the counts."""
    from touchdown.bench.speed import machine
    cap_memory(memory_gib)
    t0 = time.perf_counter()
    tally = campaign(command, files, seed=seed, seconds=seconds)
    took = time.perf_counter() - t0
    if as_json:
        print(json.dumps({"counts": tally.counts, "examples": tally.examples, "seconds": took}))
        return tally
    print(f"machine: {machine()}")
    print(f"{sum(sum(c.values()) for c in tally.counts.values())} files in {took:.1f} s "
          f"({seconds:g} s per file and {memory_gib:g} GiB of address space at most; seed {seed})")
    print(tally.table())
    for key, ex in sorted(tally.examples.items()):
        print(f"  {key}: {len(ex)}, e.g. {ex[0]}")
    print(f"defects (silent, traceback, hang, memory, broken): {tally.bad()}")
    return tally

