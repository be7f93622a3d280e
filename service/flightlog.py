"""A shard's flight log as the live service keeps it: rotating files (logs.rotating) that never
stop the ships, with retention.

- **Fail soft.** A write that fails (a full disk, a directory made read-only or removed, any
  OSError) pauses the log: the file in hand is left as it is on disk (a ``.partial`` without a
  footer: every command reads it up to its last whole chunk and says it read only part), one
  line says so, and the shard keeps stepping and publishing. Every ``retry_s`` the log tries to
  begin a new file at the tick in hand (its first record a keyframe: the ship's state then), and
  that file's header says where the gap was (``description``: ``resumed at tick T after a gap
  from tick A``). A directory that cannot be written at start is the same pause from tick 0.
- **A free-space guard.** Below ``min_free_bytes`` free on the log's file system the log pauses
  before the disk is full (nothing else on that disk runs out because of the logs), and resumes
  once there is twice that.
- **Retention.** After each new file, the shard's oldest finished files are removed while the
  shard's folder holds more than ``max_total_bytes`` or a file is older than ``max_age_s``
  (the file being written always stays).

The transition events come from the log's writer when it is writing, and are made the same way
(logs.encode_events.event_messages) when it is paused, so the event stream is the same either way.
"""
from __future__ import annotations

import os
import sys
import threading
import time
from pathlib import Path
from typing import Callable

from touchdown.logs.encode_events import EventMessages, event_messages
from touchdown.logs.rotating import RotatingLog
from touchdown.logs.shards import ShardTake
from touchdown.logs.writer import LIVE_QUEUE_BLOCKS, QUEUE_BYTES
from touchdown.sim.world import Block, World


class _Players:
    """What event_message needs of a log's ship table, from the world itself."""

    def __init__(self, world: World):
        self.players = dict(zip(world.ship_ids, world.params.ships.player_id))
        for sid, spec in world.known.items():
            self.players.setdefault(sid, spec.get("player_id") or "player-" + sid)

    @staticmethod
    def key(ship_id: str) -> str:
        return ship_id


def events_of(world: World, block: Block) -> EventMessages:
    """The block's transitions as the log would have returned them (logs.encode_events)."""
    if not block.events:
        return EventMessages([], [], world.params.body.name)
    return event_messages(_Players(world), world.params.body.name, world.params.sim.dt_s,
                          block.states, block.first_tick, block.events)


def _serialized(msgs: EventMessages) -> tuple[EventMessages, list[bytes]]:
    return msgs, msgs.datas


class ServiceLog:
    def __init__(self, directory: Path, world: Callable[[], World], say: Callable[[str], None],
                 *, prefix: str, keyframe_interval: int, max_bytes: int, name: str, source: str,
                 keyframe_phase: int = 0,
                 max_total_bytes: int = 0, max_age_s: float = 0.0, min_free_bytes: int = 0,
                 retry_s: float = 2.0, zstd_level: int | None = None,
                 first_bytes: int | None = None, tables=None, shard: ShardTake | None = None,
                 drop_cache: bool = True):
        self.directory = Path(directory)
        self._world = world
        self.say = say
        self.opts = dict(prefix=prefix, keyframe_interval=keyframe_interval, max_bytes=max_bytes,
                         name=name, source=source, open_ended=True, zstd_level=zstd_level,
                         keyframe_phase=keyframe_phase,
                         queue=(LIVE_QUEUE_BLOCKS, QUEUE_BYTES),  # a starved writer catches up
                         tables=tables,  # the headers' ship tables, some known (RotatingLog)
                         shard=shard,  # the shard's take, in every header (logs.shards)
                         drop_cache=drop_cache)  # written pages leave the page cache
        self._niced = None  # the writers' thread last given a lower priority (native id)
        # the first file's bound (the shards' files staggered: their rotations, each a header
        # of every ship's table and a keyframe, fall on different ticks)
        self.first_bytes = first_bytes
        self.max_total_bytes = max_total_bytes
        self.max_age_s = max_age_s
        self.min_free_bytes = min_free_bytes
        self.retry_s = retry_s
        self.log: RotatingLog | None = None
        self.paused_since: int | None = None  # the first tick not logged
        self.gaps: list[tuple[int, int]] = []  # (first tick not logged, tick logging resumed)
        self._next_try = 0.0
        self._next_space = 0.0
        self._closed = False
        self.removed_files = 0
        self._retained_at: tuple[int, int] | None = None  # (files, closing) at the last _retain

    # -- the sink ---------------------------------------------------------------------------
    def start(self) -> None:
        """Begin at the world's own tick (its first record a keyframe)."""
        self._begin(None)

    def write_block(self, block: Block) -> list:
        return self.write_block_serialized(block)[0]

    def write_block_serialized(self, block: Block) -> tuple[list, list[bytes]]:
        """write_block's event messages and each one's bytes (serialized once: the log's, or,
        while the log is paused, here)."""
        world = self._world()
        if self.log is None:
            if time.monotonic() >= self._next_try:
                self._begin(block.first_tick)
            return _serialized(events_of(world, block))
        if not self._space_ok():
            self._pause(block.first_tick, f"less than {self.min_free_bytes / 2**20:.0f} MiB free "
                                          f"on the log disk")
            return _serialized(events_of(world, block))
        files = len(self.log.files)
        try:
            msgs, datas = self.log.write_block_serialized(block)
        except OSError as exc:
            self._pause(block.first_tick, _oserror(exc))
            return _serialized(events_of(world, block))
        if len(self.log.files) != files:
            self.log.max_bytes = self.opts["max_bytes"]
        # retention again once a rotated file is finished, not only when the next begins: a
        # file still being finished (its writer behind) is kept and counted at what it holds
        # so far, and it grows after; its final size decides what older files must go
        seen = (len(self.log.files), len(self.log.closing_files))
        if seen != self._retained_at:
            self._retained_at = seen
            self._retain()
        thread = getattr(self.log.writer, "_thread", None)
        native = getattr(thread, "native_id", None)
        if native is not None and native != self._niced:  # a new writers' thread
            self._niced = native
            lower_priority(native)
        return msgs, datas

    def flush(self, wait: bool = True) -> threading.Event:
        if self.log is not None:
            try:
                return self.log.flush(wait)
            except OSError as exc:
                self._pause(self._world().tick, _oserror(exc))
        done = threading.Event()
        done.set()
        return done

    def close(self, complete: bool = True, reason: str = "",
              superseded_after_tick: int | None = None) -> None:
        """Finish the file in hand. ``superseded_after_tick``: the shard was lost (its lease
        passed to another worker) and Redis holds its run up to this tick only: the file's
        summary says so, and readers leave what follows it to the next owner's log."""
        if self._closed:
            return
        self._closed = True
        if self.log is not None:
            try:
                self.log.close(complete=complete, reason=reason,
                               superseded_after_tick=superseded_after_tick)
            except OSError as exc:
                self.say(f"flight log {self.directory}: not finished ({_oserror(exc)}); its last "
                         f"file is kept as far as it was written", "error")
            self.log = None

    @property
    def paused(self) -> bool:
        return self.log is None

    def waits(self) -> tuple[float, float]:
        """Wall seconds so far that writing blocks waited for the writer's thread (its queue
        full), and spent rotating files (of the file being written's RotatingLog)."""
        return (0.0, 0.0) if self.log is None else (self.log.waited_s, self.log.rotating_s)

    @property
    def files(self) -> list[Path]:
        return [] if self.log is None else list(self.log.files)

    # -- pausing and resuming -----------------------------------------------------------------
    def _begin(self, gap_from: int | None) -> None:
        world = self._world()
        self._next_try = time.monotonic() + self.retry_s
        if self.min_free_bytes and gap_from is not None and not self._space_ok(resume=True):
            return
        desc = "" if gap_from is None else (f"resumed at tick {world.tick} after a gap from "
                                            f"tick {gap_from} (the flight log was paused)")
        log = RotatingLog(self.directory, world, description=desc, **self.opts)
        try:
            log.write_block(world.first_block())
        except OSError as exc:
            try:
                log.abandon()
            except OSError:
                pass
            if self.paused_since is None:
                self.paused_since = world.tick
                self.say(f"flight log {self.directory}: cannot write ({_oserror(exc)}): the "
                         f"log is paused, the ships go on; trying again every "
                         f"{self.retry_s:g} s", "error")
            return
        if self.first_bytes and not self.gaps and self.paused_since is None:
            log.max_bytes = min(self.first_bytes, log.max_bytes)
        self.log = log
        if self.paused_since is not None:
            self.gaps.append((self.paused_since, world.tick))
            self.say(f"flight log {self.directory}: resumed at tick {world.tick} (ticks "
                     f"{self.paused_since}..{world.tick - 1} are not in the log)", "warning")
            self.paused_since = None
        self._retain()

    def _pause(self, tick: int, why: str) -> None:
        log, self.log = self.log, None
        if log is not None:
            _detach(log)
        self.paused_since = tick
        self._next_try = time.monotonic() + self.retry_s
        self.say(f"flight log {self.directory}: {why}: the log is paused at tick {tick} (the "
                 f"file in hand kept as far as written), the ships go on; trying again every "
                 f"{self.retry_s:g} s", "error")

    def _space_ok(self, resume: bool = False) -> bool:
        if not self.min_free_bytes:
            return True
        now = time.monotonic()
        if not resume and now < self._next_space:
            return True
        self._next_space = now + 1.0
        try:
            st = os.statvfs(self.directory if self.directory.exists() else
                            self.directory.parent)
        except OSError:
            return True  # the write itself will say what is wrong
        free = st.f_bavail * st.f_frsize
        return free >= self.min_free_bytes * (2 if resume else 1)

    def _retain(self) -> None:
        if not (self.max_total_bytes or self.max_age_s):
            return
        current = {p.name for p in self.files[-1:] + self.log.closing_files}
        current |= {name + ".partial" for name in current}
        try:
            found = []
            for p in self.directory.glob("*.mcap*"):
                st = p.stat()
                found.append((st.st_mtime, st.st_size, p))
        except OSError:
            return
        found.sort()
        total = sum(size for _m, size, _p in found)
        now = time.time()
        for mtime, size, p in found:
            if p.name in current:
                continue
            old = self.max_age_s and now - mtime > self.max_age_s
            big = self.max_total_bytes and total > self.max_total_bytes
            if not (old or big):
                break
            try:
                p.unlink()
                total -= size
                self.removed_files += 1
            except OSError:
                pass


#: how much less CPU priority the threads that work off the tick get (the flight log's writer,
#: the checkpoint packer): on a worker given one core, the loop's thread then runs first and
#: they take the time it leaves (``nice`` is per thread on Linux)
BACKGROUND_NICE = 10


def lower_priority(native_id: int | None, by: int = BACKGROUND_NICE) -> None:
    """Give thread ``native_id`` (``threading.Thread.native_id``) a lower CPU priority; nothing
    where the system does not have per-thread priorities."""
    if not native_id or not hasattr(os, "setpriority") or not sys.platform.startswith("linux"):
        return
    try:
        os.setpriority(os.PRIO_PROCESS, native_id,
                       min(19, os.getpriority(os.PRIO_PROCESS, native_id) + by))
    except OSError:
        pass


def _detach(log: RotatingLog) -> None:
    """Stop a rotating log whose disk failed, leaving its file as written (no footer): a
    closing would try to write again, and an abandon would delete what is there. A file that
    holds no tick (its header, written on the writer's thread, failed) is removed."""
    w = log.writer
    log._closed = True
    if log.runner is not None:
        log.runner.stop()  # (ends once the drains given to it are done)
    if w is None:
        return
    w._closed = True
    w._abort = True
    try:
        w._stop_thread()
    except Exception:  # noqa: BLE001  (the thread's own error: the disk's, said already)
        pass
    try:
        w._stream.close()
    except OSError:
        pass
    if not w.holds_a_tick:
        try:
            w.partial.unlink(missing_ok=True)
        except OSError:
            pass


def _oserror(exc: OSError) -> str:
    name = os.strerror(exc.errno) if exc.errno else type(exc).__name__
    where = f" ({exc.filename})" if getattr(exc, "filename", None) else ""
    return f"{name}{where}"
