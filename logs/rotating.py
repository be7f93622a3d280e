"""A flight log as rotating files of bounded size, each a log that verifies on its own.

:class:`RotatingLog` takes a world's blocks as a :class:`logs.writer.LogWriter` does (the
driver loop's ``log``: ``write_block``, ``close``, ``abandon``) and writes them to
``DIR/{prefix}-{first_tick:010d}.mcap``. Once the file being written is past ``max_bytes`` (the
bytes written to it, checked at block boundaries: a file overshoots by what its writer still
holds, at most its queue of blocks (LogWriter's ``queue``) and a chunk of ``max_bytes / 8``),
the file is closed at the end of the block in hand (summary ``complete``, reason ``rotated``)
and the next begins at that block's last tick T:

- its header is :func:`logs.header.world_header` of the world at T (the ships present then,
  their tables; ``start_tick = T``);
- its first tick record is the run's own record of T (the block's last row, as recorded in the
  file before: state, telemetry, the commands in force), written as a keyframe;
- what led to T (the joins and leaves at T, the commands applied in the step into T, the events of
  T) stays in the file before: everything in the new file is after its keyframe.

So the files overlap by one tick (T is the last tick of one file and the first of the next, the
same numbers in both) and each holds a whole fold: ``touchdown replay FILE --verify`` passes on
each alone. The world must be at the block's last tick when the block is handed in (as
``world.blocks`` leaves it: the driver loop's case); a block handed in later does not end a file
(the next one that is will).

A rotation costs the caller's thread no work a ship (session 36: 18-26 ms of a 20,000-ship
shard's tick before, 1-2 ms after with the fleet unchanged): the file before is finished (its
queued blocks, summary, footer, rename) on its writer's thread, and the new header made (its
ships' ids and tables, their cached JSON joined) and compressed on the new writer's; the new
file's first record is the block's own numbers, not a copy; and while the fleet is the one of
the file before's header, its ship table (and the events' encoded ids, logs.encode_events) is
the file before's. A file that cannot be finished is gone, and the next call says so; ``flush``
and ``close`` wait for those files too.
"""
from __future__ import annotations

import os
import threading
import time
from pathlib import Path
from typing import Callable

from touchdown.logs.encode import ShipTables
from touchdown.logs.encode_events import EventMessages
from touchdown.logs.header import ShipTable, world_record_later
from touchdown.logs.shards import ShardTake
from touchdown.logs.writer import QUEUE_BLOCKS, FinishedOrGone, LogWriter, Runner
from touchdown.sim.world import Block, World

#: the default bound on a file's size: 64 MiB
MAX_BYTES = 64 << 20


class RotatingLog(FinishedOrGone):
    """Write a world's blocks to rotating files in ``directory`` (created if missing).

    ``world``: the World whose blocks are written, or a function returning it (a world that is
    replaced, e.g. rebuilt from a checkpoint). ``name``: the logs' scenario name (default: the
    scene's); ``open_ended``: the run has no set end (a live service: each file's end is its
    summary's last tick); ``keyframe_phase``: each file's keyframes after its first fall on ticks
    = phase (mod ``keyframe_interval``); ``queue``: each writer's (LogWriter's); ``tables``: the
    headers' cache of the ships' tables (logs.encode.ShipTables), given some already. The first block
    must be the world's own tick (``world.first_block()``, which the driver loop writes first);
    the first file starts there.

    ``files``: every file's final path, in order; the last is being written (as
    ``PATH.partial``) until :meth:`close`.
    """

    def __init__(self, directory: str | os.PathLike, world: World | Callable[[], World],
                 prefix: str = "flight", keyframe_interval: int = 1, max_bytes: int = MAX_BYTES,
                 name: str | None = None, source: str = "", open_ended: bool = False,
                 description: str = "", chunk_size: int | None = None,
                 flush_every_ticks: int = 200, zstd_level: int | None = None,
                 keyframe_phase: int = 0, queue: tuple[int, int | None] = (QUEUE_BLOCKS, None),
                 tables: ShipTables | None = None, shard: ShardTake | None = None,
                 drop_cache: bool = False):
        if max_bytes <= 0:
            raise ValueError(f"max_bytes must be > 0, got {max_bytes}")
        if not prefix or "/" in prefix or os.sep in prefix:
            raise ValueError(f"prefix {prefix!r}: a file name's start, not a path")
        self.directory = Path(directory)
        self.prefix = prefix
        self._world = world if callable(world) else (lambda: world)
        self.keyframe_interval = max(1, keyframe_interval)
        self.keyframe_phase = keyframe_phase
        self.queue = queue
        self.max_bytes = max_bytes
        self.name = name
        self.source = source
        self.open_ended = open_ended
        self.description = description
        self.shard = shard  # a live service's shard and its take, in every file's header
        # chunks well under the bound, so that a file's size on disk follows what it holds
        self.chunk_size = chunk_size or max(4096, min(1 << 20, max_bytes // 8))
        self.flush_every_ticks = flush_every_ticks
        self.zstd_level = zstd_level
        self.drop_cache = drop_cache  # (LogWriter's: a live service's files, logs.page_cache)
        self.files: list[Path] = []
        self.writer: LogWriter | None = None
        # ship id -> its resolved table (world_header), and its JSON
        # (``tables``: some given, as logs.header.header_table makes them)
        self._tables: dict[str, dict] = ShipTables() if tables is None else tables
        self.event_count = 0
        self._closed = False
        #: files closed by a rotation, being finished on their writers' threads
        self._closing: list[LogWriter] = []
        #: wall seconds write_block spent waiting for a writer's queue, and in rotations
        self.waited_s = 0.0
        self.rotating_s = 0.0
        #: the thread that runs every file's writer, one after the other (made with the first)
        self.runner: Runner | None = None
        #: (ship ids, player ids, the ShipTable made of them) of the last file begun
        self._ships: tuple | None = None

    # -- the sink --------------------------------------------------------------------------------
    def write_block(self, block: Block) -> EventMessages:
        """Append a block (as LogWriter.write_block: returns its events as messages); then, if
        the file is past ``max_bytes`` and the world is at the block's last tick, close it and
        begin the next at that tick."""
        return self.write_block_serialized(block)[0]

    def write_block_serialized(self, block: Block
                               ) -> tuple[EventMessages, list[bytes]]:
        """write_block, with each event message's bytes (LogWriter.write_block_serialized)."""
        if self._closed:
            raise ValueError("write_block on a closed RotatingLog")
        self._reap()
        if self.writer is None:
            world = self._world()
            if block.first_tick != world.tick or len(block) != 1:
                raise ValueError(f"the first block of a rotating log must be the world's own tick "
                                 f"{world.tick} (world.first_block()), not ticks "
                                 f"{block.first_tick}..{block.last_tick}")
            self._open(world, block)
            return [], []
        writer = self.writer
        waited = writer.waited_s
        msgs, datas = writer.write_block_serialized(block)
        self.waited_s += writer.waited_s - waited
        self.event_count += len(msgs)
        if writer.size >= self.max_bytes and block.last_tick > writer.header.start_tick:
            world = self._world()
            if world.tick == block.last_tick and tuple(world.ship_ids) == tuple(block.ship_ids):
                t0 = time.perf_counter()
                self._rotate(world, block)
                self.rotating_s += time.perf_counter() - t0
        return msgs, datas

    def flush(self, wait: bool = True) -> "threading.Event | AllSet":
        """Every block written so far in the files (LogWriter.flush, and the files a rotation
        closed finished under their names). ``wait=False``: returns at once what is set once
        it is so."""
        self._reap(wait=wait)
        events = [w.finished for w in self._closing]
        if self.writer is not None and not self._closed:
            events.append(self.writer.flush(wait))
        return AllSet(events)

    def _reap(self, wait: bool = False) -> None:
        """Forget the rotated files whose writers have finished them (all of them, waiting,
        with ``wait``); a file that could not be finished is gone, and its error is raised."""
        while self._closing and (wait or self._closing[0].finished.is_set()):
            old = self._closing.pop(0)
            try:
                old.finish()
            except BaseException:
                self.files.remove(old.path)
                raise

    @property
    def closing_files(self) -> list[Path]:
        """The rotated files still being finished (as ``PATH.partial``)."""
        return [w.path for w in self._closing]

    def close(self, complete: bool = True, reason: str = "",
              superseded_after_tick: int | None = None) -> None:
        """Finish the file being written (summary ``complete`` with ``reason``: "" the run's end,
        "stopped" a live run stopped, "handed over" or "lost" a live run going on elsewhere,
        "interrupted"; replay.verify.REASONS; ``superseded_after_tick``: LogSummary's). Safe to
        call twice."""
        if self._closed:
            return
        self._closed = True
        try:
            if self.writer is not None:
                try:
                    self.writer.close(complete=complete, reason=reason,
                                      superseded_after_tick=superseded_after_tick)
                except BaseException:  # the file is gone (LogWriter.close removes it)
                    self.files.pop()
                    raise
        finally:
            try:
                self._reap(wait=True)
            finally:
                self._stop_runner()

    def _stop_runner(self) -> None:
        """The writers' thread ends once every file given to it is done."""
        if self.runner is not None:
            self.runner.stop()

    def abandon(self) -> None:
        """Drop the file being written (no half-written file); the finished ones stay."""
        if self._closed:
            return
        self._closed = True
        try:
            if self.writer is not None:
                self.writer.abandon()
                self.files.pop()
            try:
                self._reap(wait=True)
            except OSError:
                pass  # that file is gone; abandoning says nothing more
        finally:
            self._stop_runner()

    @property
    def last_tick(self) -> int:
        return -1 if self.writer is None else self.writer.last_tick

    # -- files -----------------------------------------------------------------------------------
    def _open(self, world: World, first: Block) -> None:
        """Begin a file at ``world``'s tick with ``first`` (that tick's record) as its keyframe."""
        # (the ships' tables, ids and JSON made on the writer's thread: world_record_later)
        header, record = world_record_later(
            world, self.name or world.scene.doc.get("name", self.prefix), self.source,
            self.keyframe_interval, self.open_ended, self.description, tables=self._tables,
            keyframe_phase=self.keyframe_phase)
        if self.shard is not None:
            self.shard.stamp(header)
        path = self._path(world.tick)
        self.directory.mkdir(parents=True, exist_ok=True)
        if self.runner is None:
            self.runner = Runner()
        ships = self._ship_table(world)
        writer = LogWriter(path, header, chunk_size=self.chunk_size,
                           flush_every_ticks=self.flush_every_ticks,
                           zstd_level=self.zstd_level, record=record,
                           queue=self.queue, runner=self.runner, ships=ships,
                           drop_cache=self.drop_cache)
        try:
            writer.write_block(first)
        except BaseException:
            writer.abandon()
            raise
        self.writer = writer
        self.files.append(path)

    def _ship_table(self, world: World) -> ShipTable:
        """The header's ships from the world's own lists (the header holds the same strings):
        the file before's table again while the fleet is the one of its header, with no ship
        joined since (the same table: the same keys, and the events' encoded ids, which
        logs.encode_events keeps by table, are not made again: 10-25 ms of the first tick
        with events of a new file at 20,000 ships). The file before's writer takes no more
        blocks, so the table is the new file's alone."""
        ids, players = world.ship_ids, world.params.ships.player_id
        last = self._ships
        if last is not None and last[0] is ids and last[1] is players \
                and len(last[2]) == len(ids):
            return last[2]
        ships = ShipTable(ids, players)
        self._ships = (ids, players, ships)
        return ships

    def _rotate(self, world: World, block: Block) -> None:
        """Close the file at ``block``'s last tick T and begin the next with T's record."""
        k = len(block) - 1
        # T's record as the block holds it (a block's arrays are never written once made:
        # copying them was 5-6 ms of the tick at 20,000 ships)
        keyframe = Block(block.last_tick, block.states[k:], block.outputs[k:],
                         block.inputs[k:], [], block.ship_ids)
        old, self.writer = self.writer, None
        # finished on its own thread after its queued blocks (a wait of up to 100 ms on the
        # caller's tick at 20,000 ships); the next call hears if it failed (_reap)
        old.close(complete=True, reason="rotated", wait=False)
        self._closing.append(old)
        self._open(world, keyframe)

    def _path(self, tick: int) -> Path:
        """``{prefix}-{tick:010d}.mcap``; never an existing file's name (a run resumed at the
        same tick gets ``-1``, ``-2``, ...)."""
        stem = f"{self.prefix}-{tick:010d}"
        path = self.directory / f"{stem}.mcap"
        n = 0
        while path.exists() or path.with_name(path.name + ".partial").exists():
            n += 1
            path = self.directory / f"{stem}-{n}.mcap"
        return path


class AllSet:
    """Set once each of its events is (a threading.Event's is_set and wait)."""

    def __init__(self, events):
        self.events = list(events)

    def is_set(self) -> bool:
        return all(e.is_set() for e in self.events)

    def wait(self, timeout: float | None = None) -> bool:
        return all(e.wait(timeout) for e in self.events)


__all__ = ["AllSet", "RotatingLog", "MAX_BYTES"]
