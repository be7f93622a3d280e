"""Writing a run to an MCAP log (the format: logs.header).

Writing goes to ``OUT.mcap.partial`` and is renamed to ``OUT.mcap`` only once the footer is
written: a file under the final name is always a finished MCAP. A writer that is interrupted
(Ctrl-C) finishes what it has and marks the summary ``complete = false``.
"""
from __future__ import annotations

import collections
import itertools
import json
import os
import struct
import threading
import time
from pathlib import Path
from typing import Callable

import mcap.writer
import numpy as np
from mcap.opcode import Opcode
from mcap.records import ChunkIndex, MessageIndex
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import register_schema

from touchdown.logs.encode_block import MESSAGE_HEAD_BYTES, BlockEncoder
from touchdown.logs.encode_events import EventMessages, event_messages
from touchdown.logs.encode import chunk_level
from touchdown.logs.page_cache import DropWritten
from touchdown.logs.header import (KEYFRAME_ONLY, LOG_FORMAT_VERSION, TOPIC_COMMANDS, TOPIC_EVENTS,
                         TOPIC_FLEET, TOPIC_SCENARIO, TOPIC_SUMMARY, TOPIC_TICKS, ShipTable)
from touchdown.logs.header import CHUNK_BYTES_MAX, tick_bytes_bound  # noqa: F401 (the writer's)
from touchdown.proto import touchdown_pb2 as pb
from touchdown.sim import __version__ as PROJECT_VERSION
from touchdown.sim.fields import INPUTS
from touchdown.sim.world import Block

#: blocks waiting for a writer's thread, at most (a recording run flat out: the caller waits
#: for the writer, and a file's size, by which it rotates, is never far behind)
QUEUE_BLOCKS = 4
#: a live service's writers (logs.rotating, service.flightlog): at most this many bytes of
#: blocks (their records; 1.3 s of a 20,000-ship shard at 10 Hz, 488 bytes a ship-tick) and
#: LIVE_QUEUE_BLOCKS blocks wait, so that a writer's thread held up for a moment (it runs at a
#: lower priority than the tick, beside Redis and other workers) catches up later rather than
#: holding up the tick
QUEUE_BYTES = 128 << 20
LIVE_QUEUE_BLOCKS = 64

#: a Message record's head (opcode, length, channel, sequence, log and publish time), and a
#: Message Index record of one message (opcode, length, channel, bytes of its entries, time,
#: offset): the same layout
_MESSAGE_HEAD = struct.Struct("<BQHIQQ")
#: a zstd Chunk record's head (opcode, length, message start and end time, uncompressed size and
#: CRC, "zstd" as a prefixed string, the compressed records' length)
_CHUNK_HEAD = struct.Struct("<BQQQQII4sQ")


class _MessageIndex(MessageIndex):
    """The library's Message Index record, its entries packed by one struct call (the library
    makes two an entry: at a message a tick, a fifth of a small log's CPU). The same bytes."""

    def write(self, stream) -> None:
        stream.start_record(Opcode.MESSAGE_INDEX)
        stream.write2(self.channel_id)
        stream.write4(len(self.records) * 16)
        stream.write(struct.pack(f"<{2 * len(self.records)}Q",
                                 *itertools.chain.from_iterable(self.records)))
        stream.finish_record()


class _BlockQueue:
    """First in, first out, bounded by a count of items and by the bytes they hold (an item in
    the writer's hands counts until done()); always room for one. put() waits for room, and
    says how long it waited."""

    def __init__(self, max_items: int, max_bytes: int | None = None):
        self.max_items = max_items
        self.max_bytes = max_bytes
        self._items: collections.deque = collections.deque()
        self._bytes = 0
        self._in_hand = 0
        self._cv = threading.Condition()

    def _full(self, nbytes: int) -> bool:
        if not self._items and not self._bytes:
            return False  # room for one, whatever its size
        if len(self._items) >= self.max_items:
            return True
        return self.max_bytes is not None and self._bytes + nbytes > self.max_bytes

    def put(self, item, nbytes: int = 0) -> float:
        waited = 0.0
        with self._cv:
            if self._full(nbytes):
                t0 = time.perf_counter()
                while self._full(nbytes):
                    self._cv.wait()
                waited = time.perf_counter() - t0
            self._items.append((item, nbytes))
            self._bytes += nbytes
            self._cv.notify_all()
        return waited

    def get(self):
        with self._cv:
            while not self._items:
                self._cv.wait()
            item, self._in_hand = self._items.popleft()
            return item

    def done(self) -> None:
        with self._cv:
            self._bytes -= self._in_hand
            self._in_hand = 0
            self._cv.notify_all()


class _Job:
    """A LogWriter's drain run on a :class:`Runner`'s thread: what the writer asks of its thread
    (is_alive, join, native_id)."""

    def __init__(self, runner: "Runner"):
        self._runner = runner
        self.done = threading.Event()

    def is_alive(self) -> bool:
        return not self.done.is_set()

    def join(self, timeout: float | None = None) -> None:
        self.done.wait(timeout)

    @property
    def native_id(self) -> int | None:
        return self._runner.native_id


class Runner:
    """One thread that runs the drains of a rotating log's writers one after the other (each
    file's after the file before is finished): a rotation starts no thread (Thread.start waits
    for the new thread to run, 8-18 ms of the caller's tick beside a busy writer on one core),
    and the files' writes stay in order. ``stop()`` ends the thread once every drain given is
    done."""

    def __init__(self, name: str = "touchdown-log"):
        self._jobs: collections.deque = collections.deque()
        self._cv = threading.Condition()
        self._stopped = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()
        self.native_id = self._thread.native_id

    def run(self, fn: Callable[[], None]) -> _Job:
        job = _Job(self)
        with self._cv:
            if self._stopped:
                raise ValueError("a stopped Runner")
            self._jobs.append((fn, job))
            self._cv.notify_all()
        return job

    def _run(self) -> None:
        while True:
            with self._cv:
                while not self._jobs and not self._stopped:
                    self._cv.wait()
                if not self._jobs:
                    return
                fn, job = self._jobs.popleft()
            try:
                fn()
            except BaseException:  # noqa: BLE001 - (a drain keeps its own errors; the next runs)
                import traceback
                traceback.print_exc()
            finally:
                job.done.set()

    def stop(self) -> None:
        with self._cv:
            self._stopped = True
            self._cv.notify_all()


class FinishedOrGone:
    """A log writer as a context manager: closed when the block ends, marked incomplete on
    Ctrl-C, abandoned (nothing kept) on any other error. Needs ``close`` and ``abandon``."""

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        elif issubclass(exc_type, KeyboardInterrupt):
            self.close(complete=False, reason="interrupted")
        else:
            self.abandon()


class LogWriter(FinishedOrGone):
    """Write a run to an MCAP file. A context manager; ``close()`` is safe to call twice.

    A thread of the writer's own encodes each block of ticks (compiled, without the GIL), adds
    the messages to the MCAP file and compresses its chunks (zstd releases the GIL), so the next
    block is stepped meanwhile. The queue between them holds at most ``queue`` = (blocks, bytes
    of blocks or None): QUEUE_BLOCKS blocks by default. An error on the writer's thread (a full
    disk) is raised by the next call from the caller (write, close)."""

    def __init__(self, path: str | os.PathLike, header: pb.ScenarioRecord,
                 chunk_size: int = 1 << 20, flush_every_ticks: int = 200,
                 zstd_level: int | None = None,
                 queue: tuple[int, int | None] = (QUEUE_BLOCKS, None),
                 runner: Runner | None = None, ships: ShipTable | None = None,
                 drop_cache: bool = False, record: Callable[[], bytes] | None = None):
        self.path = Path(path)
        # (``drop_cache``: what is written leaves the page cache a step behind, synced first:
        # a live service's logs, logs.page_cache)
        self._drop = DropWritten() if drop_cache else None
        # (``record``: the whole header's bytes, made on the writer's thread: logs.header.
        # world_record_later, ``header`` without its ships, their ids, tables and JSON)
        self._record = record
        self.partial = self.path.with_name(self.path.name + ".partial")
        self.header = header
        # (``ships``: the header's, made by the caller from its own lists: reading 12,500 ids
        # back out of the header's repeated fields took milliseconds of a rotation)
        self.ships = ships if ships is not None else ShipTable(header.ship_ids,
                                                               header.player_ids)
        self._keys_of: tuple[tuple[str, ...], np.ndarray] = ((), np.zeros(0, np.int64))
        self._dt_ns = int(round(header.dt_s * 1e9))
        keyframe_interval = max(1, header.keyframe_interval)
        self._flush_every = flush_every_ticks
        self._chunk_size = chunk_size
        self._zstd_level = zstd_level  # the chunks' (None: logs.encode.DEFAULT_ZSTD_LEVEL)
        chunk_level(zstd_level)  # (the header's chunk is compressed on this thread)
        self._stream = open(self.partial, "wb")
        try:
            # CRCs of every chunk, of the summary and of the data section (its Data End record):
            # a changed byte anywhere in the file, the metadata record's included, is found
            self._mcap = Writer(self._stream, chunk_size=chunk_size, compression=CompressionType.ZSTD,
                                enable_crcs=True, enable_data_crcs=True)
            self._mcap.start(profile="", library=f"touchdown {PROJECT_VERSION}")
            self._channels = {}
            for topic, cls in ((TOPIC_SCENARIO, pb.ScenarioRecord), (TOPIC_TICKS, pb.TickBatch),
                               (TOPIC_EVENTS, pb.TransitionEvent), (TOPIC_SUMMARY, pb.LogSummary),
                               (TOPIC_FLEET, pb.FleetChange), (TOPIC_COMMANDS, pb.CommandBatch)):
                schema_id = register_schema(self._mcap, cls)
                self._channels[topic] = self._mcap.register_channel(topic, "protobuf", schema_id)
            self._seq = {t: 0 for t in self._channels}
            self._mcap.add_metadata("touchdown", {
                "project_version": PROJECT_VERSION, "log_format_version": str(LOG_FORMAT_VERSION),
                "scenario": header.name, "integrator": header.integrator,
                "dt_s": repr(header.dt_s)})
            self.keyframe_interval = keyframe_interval
            self._encoder = BlockEncoder(header.dt_s, KEYFRAME_ONLY, keyframe_interval,
                                         keyframe_phase=header.keyframe_phase)
            self._size = self._stream.tell()
        except BaseException:  # nothing half-written: no .partial without a writer
            self._discard()
            raise
        self.last_tick = -1
        self.event_count = 0
        self._closed = False
        self._queue = _BlockQueue(*queue)
        self._error: BaseException | None = None
        self._abort = False
        #: set once the file is finished under its final name, or gone (close)
        self.finished = threading.Event()
        #: the file holds its first tick record (a keyframe), handed to the operating system
        self.holds_a_tick = False
        #: seconds write_block waited for room in the queue (the writer's thread behind)
        self.waited_s = 0.0
        if runner is None:
            self._thread = threading.Thread(target=self._drain, name="touchdown-log",
                                            daemon=True)
            self._thread.start()
        else:  # (a rotating log's: its files' drains on one thread, in order)
            self._thread = runner.run(self._drain)

    def _drain(self) -> None:
        """The writer's thread: the header (a live service's: every ship's table, megabytes to
        compress), then every queued block's messages, until the end marker, or the summary
        that finishes the file (close(wait=False))."""
        chunk_level(self._zstd_level)
        try:
            data = (self.header.SerializeToString() if self._record is None else
                    self._record())
            self._put(TOPIC_SCENARIO, int(self.header.start_tick), data)
            self._size = self._stream.tell()
        except BaseException as exc:  # noqa: BLE001 - handed to the caller's thread
            self._error = exc
        while True:
            item = self._queue.get()
            try:
                if self._take(item):
                    return
            finally:
                self._queue.done()

    def _take(self, item) -> bool:
        """One item of the queue, on the writer's thread; True: the thread's last."""
        if item is None:
            return True
        if isinstance(item, pb.LogSummary):
            self._finish_here(item)
            return True
        if isinstance(item, threading.Event):  # flush(): all before it is written
            try:
                if self._error is None and not self._abort:
                    self._mcap.flush()  # ends the chunk being filled
                    self._stream.flush()
            except BaseException as exc:  # noqa: BLE001 - handed to the caller's thread
                self._error = exc
            item.set()
            return False
        if self._error is None and not self._abort:  # else dropped: the caller hears of it
            try:
                block, keys, first_keyframe, events, inputs = item
                heads = (self._channels[TOPIC_TICKS], self._seq[TOPIC_TICKS], self._dt_ns)
                data, offsets = self._encoder.encode(block.first_tick, block.states,
                                                     block.outputs, block.inputs, keys,
                                                     first_keyframe=first_keyframe,
                                                     heads=heads)
                self._write_encoded(block.first_tick, data, offsets, events, inputs)
                if first_keyframe:  # on disk at once: a file begun is never one without a tick
                    self._mcap.flush()
                    self._stream.flush()
                    self.holds_a_tick = True
                if self._drop is not None:
                    self._drop.written(self._stream)
                self._size = self._stream.tell()
            except BaseException as exc:  # noqa: BLE001 - handed to the caller's thread
                self._error = exc
        return False

    def _write_encoded(self, first_tick: int, data: np.ndarray, offsets: np.ndarray,
                       events: dict[int, list[bytes]], inputs: list[tuple[str, int, bytes]]
                       ) -> None:
        """A block's ticks, each ``data[offsets[k]:offsets[k + 1]]`` a whole Message record
        (BlockEncoder's ``heads``), with its events, joins, leaves and commands. The ticks go in
        runs: a run ends at a tick with events, at a flush, and before a tick with inputs."""
        # joins, leaves and commands each just before its tick's record: the file's messages in
        # log-time order (a reader that streams it, Foxglove's among them, need not sort them)
        n = offsets.shape[0] - 1
        last_tick = first_tick + n - 1
        every = self._flush_every
        ends = {t for t in events if first_tick <= t < last_tick}
        ends.update(t - 1 for _, t, _ in inputs if first_tick < t <= last_tick)
        if every:
            ends.update(range(first_tick + (-first_tick) % every, last_tick, every))
        big = n and offsets[1] - offsets[0] - MESSAGE_HEAD_BYTES >= self._chunk_size
        if big:  # (a tick over the chunk size: a chunk of its own)
            ends.add(first_tick)
        ends.add(last_tick)
        j = 0
        k = 0
        for last in sorted(ends):
            while j < len(inputs) and inputs[j][1] <= first_tick + k:
                self._put(*inputs[j])
                j += 1
            end = last - first_tick + 1
            if k == 0 and big:
                self._put_chunk(TOPIC_TICKS, first_tick, data, int(offsets[0]), int(offsets[1]))
            else:
                self._put_ticks(first_tick, data, offsets, k, end)
            got = events.get(last)
            if got:
                self._put_all(TOPIC_EVENTS, last, got)
            if every and last % every == 0:
                self._mcap.flush()  # bounds what a killed writer loses
            k = end
        for rest in inputs[j:]:  # (none: a block's inputs are at its ticks)
            self._put(*rest)

    def _put_ticks(self, first_tick: int, data: np.ndarray, offsets: np.ndarray, k0: int,
                   k1: int) -> None:
        """Ticks ``first_tick + k0 .. + k1 - 1`` as consecutive messages, each
        ``data[offsets[k]:offsets[k + 1]]`` its whole Message record, head and all (the
        encoder's): what _put does for each, the same bytes, the run's records added to the
        chunk as they lie (a log of a few ships is a message a tick, and its messages one by
        one were most of its CPU)."""
        w = self._mcap
        builder = w._Writer__chunk_builder
        if builder is None:  # (not as this writer makes them: unchunked)
            view = memoryview(data)
            for k in range(k0, k1):
                self._put(TOPIC_TICKS, first_tick + k,
                          view[offsets[k] + MESSAGE_HEAD_BYTES:offsets[k + 1]])
            return
        channel = self._channels[TOPIC_TICKS]
        dt_ns = self._dt_ns
        a = k0
        while a < k1:
            buf = builder.record_writer._buffer
            at = buf.tell()
            # the library ends a chunk after the message that takes it past the chunk size:
            # ticks a..b-1 go in, b-1 the first whose record ends past ``limit`` (if any)
            limit = int(offsets[a]) + self._chunk_size - at
            fit = int(np.searchsorted(offsets[a + 1:k1 + 1], limit, side="right"))
            over = fit < k1 - a
            b = a + fit + 1 if over else k1
            m = b - a
            t0_ns = (first_tick + a) * dt_ns
            entries = self._counted(builder, channel, t0_ns, (first_tick + b - 1) * dt_ns, m)
            entries.extend(zip(range(t0_ns, t0_ns + m * dt_ns, dt_ns),
                               (offsets[a:b] + (at - int(offsets[a]))).tolist()))
            self._seq[TOPIC_TICKS] += m
            buf.write(data[offsets[a]:offsets[b]])
            if over:
                w._Writer__finalize_chunk()
            a = b

    def _check(self) -> None:
        if self._error is not None:
            exc, self._error = self._error, None
            raise exc

    def _stop_thread(self) -> None:
        if self._thread.is_alive():
            self._queue.put(None)
            self._thread.join()

    def _put(self, topic: str, tick: int, data: bytes) -> None:
        """One message: what the library's ``add_message`` does, the same bytes, statistics,
        chunk index and chunk breaks, without its per-field packing (a Message object, five
        struct calls and two seeks a message). A small tick record (a few ships) is a message
        a tick, and the library's path was nine tenths of such a log's CPU: 10 us a tick."""
        t_ns = tick * self._dt_ns
        channel = self._channels[topic]
        seq = self._seq[topic]
        self._seq[topic] = seq + 1
        w = self._mcap
        builder = w._Writer__chunk_builder
        if builder is None:  # (not as this writer makes them: unchunked)
            w.add_message(channel, log_time=t_ns, data=data, publish_time=t_ns, sequence=seq)
            return
        buf = builder.record_writer._buffer
        self._counted(builder, channel, t_ns, t_ns, 1).append((t_ns, buf.tell()))
        buf.write(_MESSAGE_HEAD.pack(0x05, 22 + len(data), channel, seq, t_ns, t_ns))
        buf.write(data)
        if buf.tell() > self._chunk_size:
            w._Writer__finalize_chunk()

    def _put_all(self, topic: str, tick: int, datas: list[bytes]) -> None:
        """:meth:`_put` of each of ``datas`` (a tick's events), in order: the same bytes,
        statistics, index entries and chunk breaks (a chunk ends after the message that takes
        its buffer past the chunk size), the messages up to each break counted and written at
        once (a message at a time was ~2 us of the writer's thread an event: 13,000 events in
        a second of 10,000 landers touching down)."""
        w = self._mcap
        if w._Writer__chunk_builder is None:
            for data in datas:
                self._put(topic, tick, data)
            return
        t_ns = tick * self._dt_ns
        channel = self._channels[topic]
        pack = _MESSAGE_HEAD.pack
        a, n = 0, len(datas)
        while a < n:
            builder = w._Writer__chunk_builder
            buf = builder.record_writer._buffer
            at = buf.tell()
            seq = self._seq[topic]
            records, where = [], []
            b = a
            while b < n:  # up to and with the message that takes the chunk past its size
                data = datas[b]
                head = pack(0x05, 22 + len(data), channel, seq + b - a, t_ns, t_ns)
                records += (head, data)
                where.append((t_ns, at))
                at += len(head) + len(data)
                b += 1
                if at > self._chunk_size:
                    break
            self._seq[topic] = seq + b - a
            self._counted(builder, channel, t_ns, t_ns, b - a).extend(where)
            buf.write(b"".join(records))
            if at > self._chunk_size:
                w._Writer__finalize_chunk()
            a = b

    def _counted_in_file(self, channel: int, t0_ns: int, t1_ns: int, m: int) -> None:
        """The file's statistics for ``m`` more messages on ``channel``, log times ``t0_ns`` to
        ``t1_ns`` in order, as the library's add_message keeps them."""
        stats = self._mcap._Writer__statistics
        stats.message_start_time = t0_ns if stats.message_count == 0 else min(
            t0_ns, stats.message_start_time)
        stats.message_end_time = max(t1_ns, stats.message_end_time)
        stats.channel_message_counts[channel] += m
        stats.message_count += m

    def _counted(self, builder, channel: int, t0_ns: int, t1_ns: int, m: int) -> list:
        """The library's bookkeeping for ``m`` messages on ``channel`` going into the chunk being
        filled, log times ``t0_ns`` to ``t1_ns`` in order: the file's statistics, the chunk's
        times and count. Returns the chunk's index entries for the channel, for the caller to
        add (time, offset) to."""
        self._counted_in_file(channel, t0_ns, t1_ns, m)
        builder.message_start_time = t0_ns if builder.num_messages == 0 else min(
            builder.message_start_time, t0_ns)
        builder.message_end_time = max(builder.message_end_time, t1_ns)
        builder.num_messages += m
        index = builder.message_indices.get(channel)
        if index is None:
            index = builder.message_indices[channel] = _MessageIndex(channel_id=channel,
                                                                     records=[])
        return index.records

    def _put_chunk(self, topic: str, tick: int, data: np.ndarray, start: int, end: int) -> None:
        """The Message record ``data[start:end]`` (the encoder's head, then the tick record) as
        a chunk of its own (a tick record over the chunk
        size: the library would have closed the chunk right after it), compressed and checked
        where it lies: the library copies each message into its chunk's buffer, the buffer
        again, and the compressed chunk into a record, megabytes a tick at scale, each copy
        holding the GIL the tick waits for. The chunk, its message index and the summary's entries are
        those the library writes for a chunk of one message (the same compression, level and
        CRCs): every MCAP reader reads it as any other. The messages before it are a chunk of
        their own, first, so the file stays in log-time order."""
        w = self._mcap
        builder = w._Writer__chunk_builder
        if (not w._Writer__enable_crcs or builder is None
                or (builder.num_messages == 0 and builder.count)):
            # (not as this writer makes them: schemas or channels waiting without a message)
            self._put(topic, tick, memoryview(data)[start + MESSAGE_HEAD_BYTES:end])
            return
        w._Writer__finalize_chunk()
        w._Writer__flush()
        channel = self._channels[topic]
        t_ns = tick * self._dt_ns
        self._seq[topic] += 1
        record = memoryview(data)[start:end]
        size = end - start
        crc32 = mcap.writer.zlib.crc32  # (logs.encode's: zlib-ng's)
        crc = crc32(record)
        packed = mcap.writer.zstandard.compress(record)  # (logs.encode's: the writer's level)
        chunk_head = _CHUNK_HEAD.pack(0x06, 44 + len(packed), t_ns, t_ns, size, crc, 4, b"zstd",
                                      len(packed))
        index = _MESSAGE_HEAD.pack(0x07, 22, channel, 16, t_ns, 0)
        stream = self._stream
        chunk_at = stream.tell()
        stream.write(chunk_head)
        stream.write(packed)
        stream.write(index)
        if w._Writer__enable_data_crcs:
            w._Writer__data_section_crc = crc32(index, crc32(packed, crc32(
                chunk_head, w._Writer__data_section_crc)))
        self._counted_in_file(channel, t_ns, t_ns, 1)
        w._Writer__statistics.chunk_count += 1
        w._Writer__chunk_indices.append(ChunkIndex(
            message_start_time=t_ns, message_end_time=t_ns, chunk_start_offset=chunk_at,
            chunk_length=len(chunk_head) + len(packed),
            message_index_offsets={channel: chunk_at + len(chunk_head) + len(packed)},
            message_index_length=len(index), compression="zstd", compressed_size=len(packed),
            uncompressed_size=size))

    def write_block(self, block: Block) -> EventMessages:
        """Append a block of ticks (sim.world.Block): its joins and leaves, its commands, its
        ticks and its events. Returns the events as messages (for publishing elsewhere too: a
        sequence of TransitionEvent, each parsed from the log's bytes when first read).
        (write_block_serialized: the same, with each message's bytes as the log holds them.)"""
        return self.write_block_serialized(block)[0]

    def write_block_serialized(self, block: Block) -> tuple[EventMessages, list[bytes]]:
        """write_block, returning the events as messages and each one's serialized bytes (the
        same bytes the log holds: an event stream's entry carries them without serializing
        the message again).

        The first block is the record of the header's ``start_tick`` with the header's ships (a
        run's tick 0: ``world.first_block()``; later, a keyframe of the fleet as it is then), and
        is written as a keyframe; each next block follows the last."""
        self._check()
        expected = int(self.header.start_tick) if self.last_tick < 0 else self.last_tick + 1
        if block.first_tick != expected:
            raise ValueError(f"{self.path}: a block of ticks {block.first_tick}.."
                             f"{block.last_tick} where the log's next tick is {expected}")
        if self.last_tick < 0 and (len(block) != 1 or list(block.ship_ids) != self.ships.ids
                                   or block.spawned or block.retired or block.commands
                                   or block.events):
            raise ValueError(f"{self.path}: the first block must be the one tick {expected} with "
                             f"the header's ships and nothing that led to it (no joins, leaves, "
                             f"commands or events): world.first_block()")
        inputs = self._inputs(block)
        if self._keys_of[0] is not block.ship_ids:  # the same tuple while the fleet is the same
            self._keys_of = (block.ship_ids, self.ships.keys(block.ship_ids))
        # the events' bytes written at once, compiled (logs.encode_events: protobuf's objects
        # cost ~11 us an event); their messages made only if asked for
        msgs = event_messages(self.ships, self.header.body, self.header.dt_s, block.states,
                              block.first_tick, block.events, keys=self._keys_of[1])
        datas = msgs.datas
        events: dict[int, list[bytes]] = {}
        if len(block) == 1 and datas:  # (a big fleet's block is one tick: its events are that
            # tick's, sim.world.Block)
            events[block.first_tick] = list(datas)
        else:
            for ev, data in zip(block.events, datas):
                events.setdefault(ev.tick, []).append(data)
        # encoded on the writer's thread (compiled, without the GIL): off the caller's tick
        item = (block, self._keys_of[1], self.last_tick < 0, events, inputs)
        self.waited_s += self._queue.put(item, block.states.nbytes + block.outputs.nbytes
                                         + block.inputs.nbytes)
        self.event_count += len(msgs)
        self.last_tick = block.last_tick
        return msgs, datas

    def _inputs(self, block: Block) -> list[tuple[str, int, bytes]]:
        """The block's joins, leaves and commands as FleetChange and CommandBatch messages."""
        out = []
        if block.spawned or block.retired:
            change = pb.FleetChange(tick=block.first_tick)
            for r in block.retired:
                change.left_ship_key.append(self.ships.key(r.ship_id))
                change.left_ship_id.append(r.ship_id)
            for sp in block.spawned:
                key = self.ships.add(block.first_tick, sp.spec)
                change.joined.add(ship_key=key, ship_id=sp.ship_id,
                                  player_id=self.ships.players[key],
                                  spec_json=json.dumps(sp.spec, sort_keys=True))
            out.append((TOPIC_FLEET, block.first_tick, change.SerializeToString()))
        batch = None
        for c in block.commands:
            if batch is None or batch.tick != c.tick:
                if batch is not None:
                    out.append((TOPIC_COMMANDS, batch.tick, batch.SerializeToString()))
                batch = pb.CommandBatch(tick=c.tick)
            batch.commands.add(tick=c.tick, ship_id=c.ship_id,
                               **{f.name: list(x) if f.per_ship > 1 else x
                                  for f, x in zip(INPUTS, c.inputs)})
        if batch is not None:
            out.append((TOPIC_COMMANDS, batch.tick, batch.SerializeToString()))
        return out

    def close(self, complete: bool = True, reason: str = "",
              superseded_after_tick: int | None = None, wait: bool = True) -> None:
        """Write the summary and the MCAP footer, then move the file to its final name. If that
        fails (a full disk), the partial file is removed and the error raised: a file is either
        finished under its final name or gone. ``superseded_after_tick``: a live shard lost to
        another worker, the last tick of it that was published (LogSummary). ``wait=False``:
        the writer's thread does it after the blocks queued (a rotation: not on the caller's
        tick); ``finished`` is set once done, and finish() raises what failed."""
        if self._closed:
            return
        self._closed = True
        last = max(self.last_tick, int(self.header.start_tick))
        summary = pb.LogSummary(last_tick=last, complete=complete, reason=reason,
                                event_count=self.event_count,
                                superseded_after_tick=superseded_after_tick)
        if not wait:  # finished on the writer's thread; finish() says how it went
            self._queue.put(summary)
            return
        try:
            self._stop_thread()
            self._check()
            self._finish_file(summary)
        except BaseException:
            self._abort = True
            self._stop_thread()
            self._discard()
            raise
        finally:
            self.finished.set()

    def _finish_file(self, summary: pb.LogSummary) -> None:
        self._put(TOPIC_SUMMARY, summary.last_tick, summary.SerializeToString())
        self._mcap.finish()
        self._stream.close()
        os.replace(self.partial, self.path)

    def _finish_here(self, summary: pb.LogSummary) -> None:
        """close(wait=False), on the writer's thread: the file finished, or gone and the error
        kept for finish()."""
        try:
            if self._error is not None:
                raise self._error
            self._finish_file(summary)
        except BaseException as exc:  # noqa: BLE001 - handed to the caller's thread
            self._error = exc
            try:
                self._discard()
            except OSError:
                pass  # (a read-only folder keeps the partial file; the error above says why)
        finally:
            self.finished.set()

    def finish(self) -> None:
        """Wait for a close(wait=False) to be done; raises what failed (the file is gone)."""
        self.finished.wait()
        self._thread.join()
        self._check()

    def flush(self, wait: bool = True) -> threading.Event:
        """Every block written so far into the file (its chunk ended, the file's buffer handed
        to the operating system): a reader of the partial file, or one that recovers it after
        the writer is killed, finds every tick up to the last one written. Waits for it, or
        (``wait=False``) returns at once with an Event set once it is so."""
        self._check()
        done = threading.Event()
        if self._closed:
            done.set()
            return done
        self._queue.put(done)
        if wait:
            done.wait()
            self._check()
        return done

    @property
    def size(self) -> int:
        """Bytes written to the file so far (the blocks still queued for the writer's thread,
        and the chunk it is filling, are not in it yet)."""
        # as the writer's thread last saw it: asking the file here (tell()) would wait for
        # that thread's write to finish (the buffer's lock): 7 ms a tick in a 12,500-ship service
        return self._size

    def abandon(self) -> None:
        """Drop the partial file (an error before anything worth keeping)."""
        if not self._closed:
            self._closed = True
            self._abort = True
            self._stop_thread()
            self._discard()
            self.finished.set()

    def _discard(self) -> None:
        # closing flushes the buffer, which fails again on a full disk: the file goes regardless
        try:
            self._stream.close()
        except OSError:
            pass
        self.partial.unlink(missing_ok=True)


__all__ = ["LogWriter", "FinishedOrGone", "Runner", "QUEUE_BLOCKS", "QUEUE_BYTES", "LIVE_QUEUE_BLOCKS",
           "CHUNK_BYTES_MAX", "tick_bytes_bound"]
