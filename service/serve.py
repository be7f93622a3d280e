"""``touchdown serve``: a worker of the live service (SPEC.md section 5).

Each worker owns some of the service's shards (a ship's shard: service.commands.shard_of) and
steps each owned shard's World one tick per loop, at ``rate`` ticks per wall-clock second:

    leases (renew; take free shards up to a fair share; hand extra ones over)
    commands: each owned shard's consumer group -> parsed requests into its backlog
    admit each shard's requests for this tick (budgets; one command a tick per part of a ship)
    journal them (and ack their entries), all shards in one round trip; only then apply them
    step each shard -> its flight log (rotating MCAP files) -> its numbered entries
    Redis: publish the entries, the tick's results, hashes, telemetry; the checkpoint when due

A command is applied only once Redis holds it in the shard's journal, so whatever Redis holds is
a prefix of one history: the checkpoint, the journal after it, the events up to the shard's
recorded tick; and no worker (paused, cut off, or killed with its flight log on disk) ever applies
a command its successor applies again. A worker that takes a shard over (its owner died, or
handed it over) restores the checkpoint, re-steps the journal's requests at their ticks up to
that recorded tick (re-sent entries are dropped by the shard's mark), claims the commands its
predecessor read but never journaled, and goes on.

Every owner-only write is fenced by the shard's epoch (service.redis_io.FENCE): a worker whose
lease lapsed while nobody took the shard (Redis paused past it) takes it back and goes on, and
only a real new owner restores from the checkpoint. After each read a worker compares the entries
pending to it with those it holds: a read whose reply was lost (a time-out, a pipeline re-sent by
the client) is read again, and entries pending to a former owner are claimed.

While Redis is unreachable the worker keeps stepping and logging (the commands wait); it holds the
unsent entries (at most ``buffer_max``; the flight log always has them), says so on stderr, and
delivers them in order once Redis answers again. Back from an outage it compares what Redis holds
with what it wrote: what Redis lost (a failover's last writes, a restart without its data) it
writes again. Telemetry is a sample: the samples of an outage are dropped. A shard lost meanwhile
(its epoch passed to another worker) has its flight log closed with the last tick Redis holds of
it (``superseded_after_tick``).

A worker is three parts, each with one job: its leases (service.leases: the heartbeat and the
leases renewed on a thread of their own, the fair-share round), its shards' policy (this module's
``Worker``: everything above between the leases and Redis) and its reporter (service.report: the
stats line, the stats hash, Prometheus). Every Redis call is service.store's (``ShardStore``,
typed results); what travels between the parts is typed too (``JournalWrite``,
``JournalRecord``, ``ShardHeld``, ``PendingCheckpoint``, ``ShardStart``, service.shard's
``Entry``).
"""
from __future__ import annotations

import dataclasses
import gc
import json
import os
import signal
import socket
import sys
import threading
import time
from collections import Counter, deque
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from touchdown.service import redis_io as rio
from touchdown.service.commands import Rejected, Request, decode_entry, parse, shard_of
from touchdown.service.kinds import parts_of
from touchdown.logs.encode import ShipTables
from touchdown.logs.header import header_table
from touchdown.logs.shards import ShardTake
from touchdown.service.flightlog import ServiceLog, lower_priority
from touchdown.service.leases import Leases
from touchdown.service.memory import keep_freed_memory
from touchdown.service.phases import GcTimer, Phases, SlowTicks
from touchdown.service.report import Reporter
from touchdown.service.telemetry import TelemetryEncoder
from touchdown.service.shard import Limits, Shard, TickOut
from touchdown.service.store import (ERRORS, REFUSALS, UNREACHABLE, CheckpointWrite, Fence,
                                     JournalRecord, JournalWrite, ShardStore, ShardWrites,
                                     refusal_kind)
from touchdown.sim.errors import TouchdownError
from touchdown.sim.scenario import Scenario, parse as parse_doc
from touchdown.sim.timeline import Timeline
from touchdown.sim.world import World

#: Redis (or, on a cluster, the node of a slot, or the slot map) unreachable: ticking on
REDIS_ERRORS = UNREACHABLE


class ServeError(TouchdownError):
    """A user's mistake or a refused start (one line); the CLI exits 2."""


@dataclass(frozen=True)
class ServeConfig:
    url: str = "redis://127.0.0.1:6379/0"
    password: str | None = None  # from --redis-password-file (never printed)
    scenario: Scenario | None = None
    source: str = ""
    ticks: int | None = None  # stop after this many loops (None: when stopped)
    rate_hz: float | None = None  # ticks per wall-clock second; None: 1/dt; 0: flat out
    log_dir: Path = Path("flight")
    prefix: str = "galaxy"
    events_stream: str | None = None
    commands_stream: str | None = None
    shards: int = 4
    lease_s: float = 2.0
    checkpoint_every: int = 50  # ticks
    telemetry_hz: float = 1.0  # samples of each ship per simulated second (0: none)
    #: the telemetry stream's cap, in entries (each one shard's slice of one tick); None: what
    #: the service sends in TELEMETRY_KEEP_S simulated seconds (100 per shard at dt 0.1 s)
    telemetry_maxlen: int | None = None
    events_maxlen: int = 1_000_000  # the event stream, approximately (0: not trimmed)
    #: each shard's results stream (a tick's entry: what each command came to), approximately
    results_maxlen: int = 10_000
    buffer_max: int = 100_000  # unsent entries held while Redis is away
    #: a flight-log file's bound: at 104 bytes a ship-tick, a 20,000-ship shard fills 1 GiB in
    #: 50 s; a rotation costs that shard's tick 1.5-5 ms (its header made on the log's thread)
    log_max_bytes: int = 1 << 30
    #: a shard's flight-log folder, oldest files removed (0: all kept): two files of the default
    #: size, 8 GiB for the default four shards (at 3,000 ships, 3.4 MB/s, about 40 minutes)
    log_max_total_bytes: int = 2 << 30
    log_max_age_s: float = 0.0  # flight-log files older than this are removed (0: kept)
    log_min_free_bytes: int = 64 << 20  # the log pauses below this much free disk
    keyframe_every: int = 10
    #: the flight log's zstd level (logs.encode): a fast one, the log's largest cost at scale
    #: (zstd is about half of the writers' CPU, which shares the worker's core with the tick).
    #: -8: a quarter less CPU than -3 for 7% more bytes (a 12,500-ship shard's tick chunks:
    #: 0.69 against 0.87 ns a byte, ratio 2.57 against 2.76); the same ``zstd`` chunks
    log_zstd_level: int | None = -8
    #: the flight logs' written pages synced and dropped from the page cache every 8 MB
    #: (logs.page_cache): hours of logs do not fill the machine's memory, and the writes reuse
    #: pages already in use; False: left to the kernel (written back within ~30 s, cached)
    log_drop_cache: bool = True
    worker_id: str = ""
    max_shards: int | None = None  # at most this many shards (None: a fair share)
    read_count: int = 1000  # command entries read per shard per tick, at most
    max_commands_per_tick: int = 2000  # applied per shard per tick; the rest wait a tick
    max_spawns_per_tick: int = 200  # per shard per tick; the rest wait a tick
    max_command_bytes_per_tick: int = 4 << 20  # per shard per tick; the rest wait a tick
    limits: Limits = field(default_factory=Limits)
    stats_every_s: float = 5.0  # the stats line, the stats hash (its time-out is 3x this)
    metrics_port: int | None = None
    cluster: bool = False  # url is a node of a Redis Cluster (--redis-cluster)
    #: the flush's round trip on a thread of its own, its replies taken at the next loop's
    #: start (before any other Redis call of the loop): the loop does not wait for Redis
    #: between its ticks. False: the loop waits for the replies at the end of its tick.
    flush_behind: bool = True


TELEMETRY_KEEP_S = 10.0  # what the telemetry stream keeps by default: about 1 kB a ship
#: the loop from which a worker's phases count as steady (Stats.phases_at_steady): 2 s at 10 Hz,
#: the warm-up ``bench serve`` leaves out
STEADY_LOOP = 20
GC_EVERY = 50  # loops between the full collections a worker runs between its ticks
STATS_KEPT = 100_000  # per-tick figures kept (about 3 hours at 10 Hz)
#: what a shard keeps after Redis confirmed it, to write it again if Redis loses it (a failover's
#: last writes, a restart from an older snapshot, or without its data): the last entries out,
#: and the journal's last records (their requests, at most)
RETAIN_ENTRIES = 20_000
RETAIN_REQUESTS = 100_000
ROUTED_KEY = "routed:"  # (_Owned.applied: a routed entry's id on the shared stream, apart)


@dataclass
class Stats:
    ticks: int = 0
    #: work time of each loop (no sleeping), the latest STATS_KEPT (per-tick figures are bounded)
    tick_s: deque = field(default_factory=lambda: deque(maxlen=STATS_KEPT))
    late: int = 0  # loops that began a whole period or more after their due time (never reset)
    #: how late each loop began (paced runs), the latest STATS_KEPT
    start_late_s: deque = field(default_factory=lambda: deque(maxlen=STATS_KEPT))
    entries_sent: int = 0
    entries_dropped: int = 0
    commands_read: int = 0
    takeovers: int = 0
    lag_s: float = 0.0  # how far behind its schedule the last loop began
    recent: deque = field(default_factory=lambda: deque(maxlen=STATS_KEPT))  # (time, seconds)
    #: where the loop's time goes: phase -> [wall seconds, the loop thread's CPU seconds]
    #: summed over every loop (service.phases.Phases)
    phases: dict = field(default_factory=dict)
    #: the process's CPU seconds (every thread) at the end of each loop, the latest STATS_KEPT
    cpu_s: deque = field(default_factory=lambda: deque(maxlen=STATS_KEPT))
    #: the loops that began a whole period late, the latest 100: what came before each (the
    #: loop before it, the work between loops, how late the wait woke: the CPU was elsewhere)
    late_starts: deque = field(default_factory=lambda: deque(maxlen=100))
    #: the loop thread's own CPU seconds at the end of each loop, the latest STATS_KEPT (beside
    #: ``cpu_s``: the other threads' share, the flight log's writers and the packer, is the rest)
    loop_cpu_s: deque = field(default_factory=lambda: deque(maxlen=STATS_KEPT))
    #: ``phases`` as they were at the end of loop STEADY_LOOP (a copy): the phases after the
    #: start (taking the shards, writing every ship's hash) are the sums less these
    phases_at_steady: dict = field(default_factory=dict)


@dataclass(frozen=True)
class PendingCheckpoint:
    """A shard's checkpoint taken at a flush (its records copied), packed on a thread and sent
    once packed and once the flight log has its tick on disk (no waiting on the log's thread in
    a tick: that was the slowest tick's time)."""

    packed: Future  # the blob (service.redis_io.checkpoint_later, on the packer thread)
    tick: int
    published: int  # entries the shard had emitted (the script refuses it until all are out)
    logged: threading.Event  # set once the flight log has written up to ``tick``
    gone: tuple  # ships that left before it: their specs and parameters are dropped

    def ready(self) -> bool:
        return self.logged.is_set() and self.packed.done()

    def write(self) -> CheckpointWrite:
        return CheckpointWrite(self.packed.result(), self.tick, self.published, self.gone)


@dataclass(frozen=True)
class ShardStart:
    """What a shard taken over starts from (Worker._shard_start): its world at the tick it
    starts at, the ships the autopilot flies, the entries emitted so far, every ship's spec as
    Redis holds them (ship id -> [join tick, table]), how (said in the log line), whether from a
    checkpoint (a take-over) or new; a new shard's specs and parameter records to write."""

    world: World
    autoland: list
    published: int
    specs: dict
    how: str
    from_checkpoint: bool
    fresh_specs: dict = field(default_factory=dict)
    fresh_params: dict = field(default_factory=dict)


@dataclass
class _Owned:
    shard: Shard
    fence: Fence  # this worker's epoch of the shard (every owner-only script checks it)
    unsent: deque = field(default_factory=deque)  # entries to publish (service.shard.Entry)
    specs: dict = field(default_factory=dict)  # ship id -> [join tick, table] JSON, to write
    params: dict = field(default_factory=dict)  # ship id -> its parameter record, to write
    hashes: dict = field(default_factory=dict)  # ship id -> fields or None, to write
    telemetry: list = field(default_factory=list)  # serialized samples to add
    results: deque = field(default_factory=deque)  # (tick, results JSON) to write
    tele: TelemetryEncoder = field(default_factory=TelemetryEncoder)
    backlog: deque = field(default_factory=deque)  # requests read, waiting for their tick
    waiting: Counter = field(default_factory=Counter)  # ship id -> its commands in the backlog
    inflight: set = field(default_factory=set)  # entry ids read and not yet acknowledged
    #: the start id of a re-read of this worker's own pending entries (after a Redis error, or
    #: more pending to it than it holds: a read whose reply was lost), or None
    reread: str | None = "0"
    #: journal writes whose reply never came (their ticks): each may be in Redis, with its
    #: entries acknowledged, though this worker did not apply them; the next write removes them
    unsure: list = field(default_factory=list)
    retired: list = field(default_factory=list)  # (tick, ship id) of ships that left
    read_count: int = 100  # entries asked for a tick: follows the byte budget (_adapt)
    #: a checkpoint taken, waiting to be packed and for the flight log to reach its tick
    checkpoint: PendingCheckpoint | None = None
    force_checkpoint: bool = False  # Redis lost the shard's writes: one as soon as it can
    #: the last tick of this shard Redis holds (its journal and its events): a shard lost to
    #: another worker goes on from there, and its flight log says so (superseded_after_tick)
    delivered: int = 0
    #: what Redis confirmed, kept to write it again if Redis loses it: the last entry number out,
    #: the entries out (the latest RETAIN_ENTRIES), the journal's latest records (at most
    #: RETAIN_REQUESTS requests) and their entry ids (an entry found pending again is not
    #: applied twice)
    confirmed_mark: int = -1
    journal_mark: int = -1  # the last tick this worker saw journaled (JOURNAL checks it)
    stale: set = field(default_factory=set)  # applied entries found pending again (acks lost)
    sent: deque = field(default_factory=lambda: deque(maxlen=RETAIN_ENTRIES))
    journaled: deque = field(default_factory=deque)  # JournalRecord(tick, requests)
    applied: dict = field(default_factory=dict)  # entry id -> the tick it was applied at
    step_s: float = 0.0  # the last step's wall time (seconds)
    joined: dict = field(default_factory=dict)  # ship id -> its join tick (its spec's)
    taken_at: float | None = None  # when its lease was taken (until its first tick after)


_SAYING = threading.Lock()


def _say_on_stderr(line: str) -> None:
    """One whole line on stderr: the lease thread, the reporter and the tick loop all say things,
    and print() writes a line and its newline separately, so two threads' lines could run into
    one (a JSON line followed by another on the same line: unreadable to a log shipper)."""
    with _SAYING:
        sys.stderr.write(line + "\n")
        sys.stderr.flush()


class Worker:
    """One worker of the live service: its shards' policy (module docstring), with its
    ``leases`` (service.leases.Leases) and its ``reporter`` (service.report.Reporter)."""

    def __init__(self, cfg: ServeConfig, say: Callable[[str], None] | None = None):
        self.cfg = cfg
        self.id = cfg.worker_id or f"{socket.gethostname()}-{os.getpid()}"
        self.say = say or _say_on_stderr
        self.where = rio.redact(cfg.url)
        self.keys = rio.Keys(cfg.prefix, cfg.events_stream, cfg.commands_stream, cfg.cluster)
        self.owned: dict[int, _Owned] = {}
        self.stats = Stats()
        self.phase = Phases(self.stats.phases)
        self.slow = SlowTicks(self.stats.phases)
        self._pack_pool: ThreadPoolExecutor | None = None
        self._flush_pool: ThreadPoolExecutor | None = None
        #: the flush sent on the flush thread whose replies are not taken yet (flush_behind)
        self._flushing: Future | None = None
        #: a shard taken or written back this loop: its flush (every ship's hash, megabytes)
        #: is waited for in this loop, not carried into the next tick
        self._whole_shards = False
        self.stop = threading.Event()
        self.redis_up = True
        self._down_since = 0.0
        self._next_try = 0.0
        self._said: dict[str, float] = {}
        self._refused: str | None = None  # the kind of refusal going on, if any
        self._loop_refused = False
        self._gone: set[int] = set()  # shards whose state Redis lost (their epoch gone)
        self._suspect: set[int] = set()  # shards whose last writes Redis may have lost
        self._said_gone: set[int] = set()
        self._collected = 0  # the loop of the last full collection (_collect)
        #: the service scenario's resolved ship tables by id() (_header_tables), made once
        self._scenario_tables: dict | None = None
        self.last_figures: dict = {}
        flag = "--redis-cluster" if cfg.cluster else "--redis"
        try:
            self.store = ShardStore(cfg.url, cfg.password, self.keys, self.id, cfg.cluster)
        except ValueError as exc:
            raise ServeError(f"{flag} {self.where}: {exc}") from None
        except (*ERRORS, OSError) as exc:  # a RedisCluster asks for the slot map at once
            text = self._text(exc)
            if "Cluster mode is not enabled" in text:  # what redis-py says for both
                text += (" (a Redis that is not a cluster, or an ACL user without "
                         "+cluster|slots +command)")
            raise ServeError(f"{flag} {self.where}: {text}") from None
        try:
            self.store.ping()
            self.scenario, self.scenario_json = self._agree_on_config()
            for k in range(cfg.shards):
                self.store.ensure_group(k)
        except (*ERRORS, ValueError, OSError) as exc:
            raise ServeError(f"redis {self.where}: {self._text(exc)}") from None
        self.scene = self.scenario.scene
        self.dt_s = self.scenario.params.sim.dt_s
        self.body = self.scenario.params.body.name
        period = 1.0 / (cfg.telemetry_hz * self.dt_s) if cfg.telemetry_hz > 0 else 0
        self.telemetry_every = max(1, int(round(period))) if period else 0
        self.telemetry_maxlen = telemetry_maxlen(cfg, self.dt_s)
        # the worker's three parts: its leases, its shards' policy (this class: reading,
        # admitting, journaling, stepping, flushing, taking over, writing back what Redis lost)
        # and its reporter
        self.leases = Leases(self, ServeError)
        self.reporter = Reporter(self, cfg.metrics_port, ServeError)

    # -- saying things -----------------------------------------------------------------------
    def log(self, msg: str, level: str = "info", **figures) -> None:
        """One JSON line on stderr: time, level, worker, msg (and any figures)."""
        line = {"time": time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime()) +
                f".{int(time.time() * 1000) % 1000:03d}Z", "level": level, "worker": self.id,
                "msg": msg, **figures}
        self.say(json.dumps(line))

    def log_every(self, kind: str, msg: str, level: str = "warning", every_s: float = 10.0
                  ) -> None:
        """Say ``msg`` at most once every ``every_s`` for one kind of trouble."""
        now = time.monotonic()
        if now >= self._said.get(kind, 0.0):
            self._said[kind] = now + every_s
            self.log(msg, level)

    def _text(self, exc: BaseException) -> str:
        text = f"{type(exc).__name__}: {exc}" if not str(exc) else str(exc)
        # (redis-py names a pipeline's failed command with its arguments: a whole script)
        text = text.split(" of pipeline caused error: ", 1)[-1]
        return rio.scrub(text, self.cfg.password, rio.password_of(self.cfg.url))

    # -- start ---------------------------------------------------------------------------------
    def _agree_on_config(self) -> tuple[Scenario, str]:
        """Every worker of a service shares its shard count and its scenario: the first to
        start writes them; a later one given others is refused."""
        cfg = self.cfg
        mine = json.dumps(cfg.scenario.resolved, sort_keys=True) if cfg.scenario else ""
        shards, doc_json = self.store.agree_on_config(cfg.shards, mine)
        where = f"{self.where} {self.keys.config}"
        if shards != cfg.shards:
            raise ServeError(f"{where}: the service runs {shards} shards, not {cfg.shards} "
                             f"(--shards must agree)")
        if cfg.scenario is not None and doc_json != mine:
            raise ServeError(f"{where}: the service runs another scenario than {cfg.source} "
                             f"(start with the same scenario, or without --scenario)")
        if not doc_json:
            return default_scenario(), ""
        return parse_doc(json.loads(doc_json), "service"), doc_json

    # -- the loop ------------------------------------------------------------------------------
    def warm(self) -> None:
        """Compile (or load from the cache) every kernel a tick runs, before taking any lease:
        a worker that cannot step a shard yet does not take one (service.warm)."""
        from touchdown.service import warm
        seconds = warm.warm(self.scene, self.dt_s, self.body)
        self.log(f"compiled code ready in {seconds:.1f} s (kernels in {warm.where()}): taking "
                 f"shards")

    def run(self) -> Stats:
        cfg = self.cfg
        keep_freed_memory()  # each tick's blocks in pages already the process's (service.memory)
        self.warm()
        rate = (1.0 / self.dt_s) if cfg.rate_hz is None else cfg.rate_hz
        period = 1.0 / rate if rate > 0 else 0.0
        due = time.monotonic()
        loops = 0
        self.leases.start()
        gc_timer = self._gc_timer = GcTimer(self.phase)
        gc_timer.install()
        thresholds = gc.get_threshold()
        # no full collection in the middle of a tick: they are run between ticks (_collect)
        gc.set_threshold(thresholds[0], thresholds[1], 1 << 30)
        dt = between = 0.0
        try:
            while not self.stop.is_set() and (cfg.ticks is None or loops < cfg.ticks):
                if period:
                    now = time.monotonic()
                    woke_late = 0.0
                    if now < due:
                        self.stop.wait(due - now)
                        if self.stop.is_set():
                            break
                        now = time.monotonic()
                        woke_late = now - due
                    behind = now - due
                    self.stats.lag_s = max(0.0, behind)
                    self.stats.start_late_s.append(max(0.0, behind))
                    if behind > period:
                        self.stats.late_starts.append({
                            "loop": loops, "behind_s": round(behind, 4),
                            "previous_tick_s": round(dt, 4), "between_s": round(between, 4),
                            "woke_late_s": round(woke_late, 4)})
                    if behind > 1.0:
                        # far behind (a stall): every period it held up counts as a late tick
                        # (the count is never reset), and the schedule starts again
                        self.stats.late += int(behind // period)
                        due = now
                    elif behind > period:
                        self.stats.late += 1
                    due += period
                self.slow.start()
                t0 = time.perf_counter()
                self.loop_once()
                dt = time.perf_counter() - t0
                self.slow.end(loops, dt)
                self.stats.tick_s.append(dt)
                self.stats.cpu_s.append(time.process_time())
                self.stats.loop_cpu_s.append(time.thread_time())
                self.stats.recent.append((time.monotonic(), dt))
                self.reporter.tick_took(dt)
                loops += 1
                self.stats.ticks = loops
                if loops == STEADY_LOOP:
                    self.stats.phases_at_steady = {k: list(v) for k, v in
                                                   self.stats.phases.items()}
                if self.reporter.due():
                    self.reporter.report()
                if loops % GC_EVERY == 0 or loops - self._collected >= 4 * GC_EVERY:
                    self._collect(loops, due - time.monotonic() if period else 0.0, period)
                between = time.perf_counter() - t0 - dt
        finally:
            gc.set_threshold(*thresholds)
            gc_timer.remove()
            self.shutdown()
        return self.stats

    def _collect(self, loops: int, slack_s: float, period: float) -> None:
        """A full collection between ticks, when half a period is left before the next (or at
        the latest every 4 x GC_EVERY loops), then what survived it frozen (gc.freeze: out of
        the next collections' way; reference counting still frees it). Python's own full
        collections struck in whichever tick they fell, for tens of milliseconds."""
        if period and slack_s < period / 2 and loops - self._collected < 4 * GC_EVERY:
            return
        self._collected = loops
        self._gc_timer.remove()  # (not a pause in a tick: a phase of its own)
        try:
            with self.phase("gc_between_ticks"):
                gc.collect()
                gc.freeze()
        finally:
            self._gc_timer.install()

    def loop_once(self) -> None:
        if self._flushing is not None:  # the last loop's flush: its replies first
            with self.phase("redis_io"):
                self._redis(self._flush_taken, clears=True)
        now = time.monotonic()
        self._loop_refused = False
        if not self.redis_up and now >= self._next_try:
            self._reconnect()
        lost = self.leases.take_lost()
        for k in sorted(lost & set(self.owned)):
            self._lose(k, "its lease passed to another worker")
        self._gone |= self.leases.take_gone()
        if self._gone and self.redis_up:
            gone, self._gone = self._gone, set()
            for k in sorted(gone & set(self.owned)):
                self._redis(self._restore, k)
        if self._suspect and self.redis_up:
            suspect, self._suspect = self._suspect, set()
            self._redis(self._reconcile, suspect)
        ph = self.phase
        if self.redis_up and now >= self.leases.next_round:
            with ph("leases"):
                self._redis(self.leases.round)
            self.leases.next_round = now + self.cfg.lease_s / 4
        if self.redis_up:
            with ph("read"):
                self._redis(self._read_commands)
                if 0 in self.owned and not self.cfg.cluster:  # no router on a cluster
                    self._redis(self._route)
        plans = {k: self._admit(o) for k, o in self.owned.items()}
        confirmed: set[int] = set()
        if any(plans.values()):
            with ph("journal"):
                if self.redis_up:
                    self._redis(self._journal, plans, confirmed)
        for k in sorted(self.owned):
            o = self.owned[k]
            requests = plans.get(k, [])
            if requests and k not in confirmed:
                self._put_back(o, requests)  # not journaled: applied at a later tick
                requests = []
            self._step(o, requests)
        if self.redis_up:
            with ph("flush"):
                if self.cfg.flush_behind and not self._whole_shards:
                    self._redis(self._flush_send)
                else:
                    self._redis(self._flush, clears=True)
        self._whole_shards = False

    def _admit(self, o: _Owned) -> list:
        """The backlog's requests for this tick, in order, within the tick's budget of
        commands, spawns and bytes; the rest wait for the next tick. A ship takes at most one
        command a tick for each part of it a command sets (its throttle, its RCS, its hold; a
        spawn, a retire or an autoland the whole ship): a command that would change what an
        earlier command of the same tick set waits for the next tick, and so do the ship's later
        commands (in order), so every command is in force for at least one tick and is in the
        flight log at its own tick. Other ships' commands go past it."""
        cfg = self.cfg
        out, keep, used, closed = [], [], {}, set()
        spawns, size = 0, 0
        while o.backlog and len(out) < cfg.max_commands_per_tick:
            req = o.backlog[0]
            is_spawn = isinstance(req, Request) and req.cmd == "spawn"
            if is_spawn and spawns >= cfg.max_spawns_per_tick:
                break
            if out and size + req.size > cfg.max_command_bytes_per_tick:
                break
            o.backlog.popleft()
            sid = req.ship_id
            parts = parts_of(req)
            if sid in closed or (parts & used.get(sid, frozenset())):
                closed.add(sid)
                keep.append(req)
                continue
            if parts:
                used[sid] = used.get(sid, frozenset()) | parts
            out.append(req)
            spawns += is_spawn
            size += req.size
            if isinstance(req, Request):
                o.waiting[sid] -= 1
                if o.waiting[sid] <= 0:
                    del o.waiting[sid]
        o.backlog.extendleft(reversed(keep))
        return out

    def _put_back(self, o: _Owned, requests: list) -> None:
        """Requests admitted but not journaled (Redis away or refusing): first in line again."""
        o.backlog.extendleft(reversed(requests))
        for req in requests:
            if isinstance(req, Request):
                o.waiting[req.ship_id] += 1

    def _journal(self, plans: dict, confirmed: set) -> None:
        """JOURNAL each shard's requests of this tick before the tick applies them, in one round
        trip: only what Redis holds is applied, so no worker (paused, cut off, or killed with its
        flight log on disk) ever applies a command its successor applies again. A write whose
        reply never came is ``unsure``: the shard's next write removes it if it is there."""
        writes, before = [], {}
        for k in sorted(plans):
            if plans[k] and k in self.owned:
                o = self.owned[k]
                writes.append(JournalWrite(k, o.fence, o.shard.tick, plans[k], list(o.unsure),
                                           o.journal_mark))
                before[k] = list(o.unsure)
                o.unsure.append(o.shard.tick)  # until Redis says what it did
        for j in self.store.journal(writes):
            o = self.owned[j.k]
            if j.refused is not None:  # refused: nothing written (the XADD comes first)
                o.unsure = before[j.k]
                self._refusal(j.refused)
                continue
            if j.code == 1:
                o.unsure = []
                confirmed.add(j.k)
                tick, requests = o.shard.tick, plans[j.k]
                o.journal_mark = tick
                o.inflight.difference_update(r.entry_id for r in requests)
                self._journaled(o, tick, requests)
                o.delivered = max(o.delivered, tick + 1)
            elif j.code == -3:
                self._gone.add(j.k)
            elif j.code == -5:  # Redis lost journal records: written again first
                o.unsure = before[j.k]
                self._suspect.add(j.k)
            elif j.code == -4:
                self.log(f"shard {j.k}: its journal holds a tick after {o.shard.tick}: another "
                         f"history; dropping the shard", "error")
                self._lose(j.k, "its journal went on without it")
            else:
                self._lose(j.k, "its lease passed to another worker")

    def _step(self, o: _Owned, requests: list) -> None:
        sh = o.shard
        tick = sh.tick
        t0 = time.perf_counter()
        out = sh.step(requests, self.phase)
        o.step_s = time.perf_counter() - t0
        if o.taken_at is not None:
            self.log(f"shard {sh.index}: first tick {time.monotonic() - o.taken_at:.3f} s after "
                     f"its lease was taken")
            o.taken_at = None
        if out.results:
            o.results.append((tick, out.results))
        with self.phase("take"):
            self._take(o, out)
        every = self.telemetry_every
        if every and sh.world.state.n:
            with self.phase("telemetry"):
                # a rolling slice: each ship once per period, the work spread over its ticks
                offset = sh.tick % every
                if offset < sh.world.state.n and out.blocks:
                    b = out.blocks[-1]
                    o.telemetry.append(o.tele.encode(b.states[-1], b.outputs[-1], b.ship_ids,
                                                     b.last_tick, self.dt_s, sh.index, offset,
                                                     every))
                    del o.telemetry[:-4 * every]  # a sample: only the latest wait for Redis

    def _take(self, o: _Owned, out: TickOut) -> None:
        o.unsent.extend(out.entries)
        o.hashes.update(out.hashes)
        world = o.shard.world
        for block in out.blocks:
            for sp in block.spawned:
                o.joined[sp.ship_id] = block.first_tick
                o.specs[sp.ship_id] = json.dumps([block.first_tick, sp.spec], sort_keys=True)
                i = world.row(sp.ship_id)
                if i is not None:
                    o.params[sp.ship_id] = world.params.ships.rows[i].tobytes()
            for r in block.retired:
                o.retired.append((block.first_tick, r.ship_id))
                o.specs.pop(r.ship_id, None)
                o.params.pop(r.ship_id, None)
        held = sum(len(x.unsent) for x in self.owned.values())
        while held > self.cfg.buffer_max and o.unsent:
            o.unsent.popleft()
            held -= 1
            self.stats.entries_dropped += 1
            if self.stats.entries_dropped in (1, 1000, 100_000):
                self.log(f"event buffer full ({self.cfg.buffer_max:,}): dropped "
                         f"{self.stats.entries_dropped:,} entries so far (the flight logs "
                         f"have them)", "error")

    # -- Redis, each step guarded ------------------------------------------------------------
    def _redis(self, fn, *args, clears: bool = False):
        """Run ``fn``. If Redis is unreachable, mark it down (the loop goes on); if it refuses
        (out of memory, a missing permission, read-only, ...), say so at most every few
        seconds and go on holding what is unsent. Returns None on either. ``clears``: a
        success means the refusal is over (the writes went through)."""
        try:
            result = fn(*args)
            if clears and self._refused is not None and not self._loop_refused:
                self.log(f"redis {self.where} accepts writes again ({self._refused} is over): "
                         f"delivering what was held")
                self._refused = None
            return result
        except REDIS_ERRORS as exc:
            if self.redis_up:
                self.redis_up = False
                self._down_since = time.monotonic()
                self.log(f"redis {self.where} unreachable ({type(exc).__name__}): ticking on; "
                         f"holding events (the flight logs have them) until it answers",
                         "error")
            self._next_try = time.monotonic() + 0.25
        except ERRORS as exc:
            self._refusal(exc)
        self._reread_all()
        return None

    def _refusal(self, exc: BaseException) -> None:
        """Redis refused a write (OOM, NOPERM, READONLY, ...): said at most every 10 s."""
        text = self._text(exc)
        kind = refusal_kind(exc, text)
        self._loop_refused = True
        self._refused = REFUSALS.get(kind, kind)
        self.log_every(f"refused:{kind}",
                       f"redis {self.where} refused: {kind} {text} ({self._refused}): "
                       f"ticking on; holding events and commands until it accepts them "
                       f"(the flight logs have every tick)", "error")

    def _reread_all(self) -> None:
        """After any error a read's reply may have been lost, leaving its entries pending to
        this worker: read them again (those already in hand are skipped)."""
        for o in self.owned.values():
            o.reread = "0"
        self._route_from = "0"

    def _reconnect(self) -> None:
        try:
            self.store.ping_all()  # (on a cluster every master: a node's slots are down with it)
        except ERRORS:
            self._next_try = time.monotonic() + 0.25
            return
        self.redis_up = True
        held = sum(len(o.unsent) for o in self.owned.values())
        self.log(f"redis back after {time.monotonic() - self._down_since:.1f} s: delivering "
                 f"{held:,} held entries")
        self.leases.next_round = 0.0
        # the other workers' leases lapsed too: each takes its own shards back first (RENEW,
        # or its next script) before any worker takes another's
        self.leases.take_after = time.monotonic() + self.cfg.lease_s
        self._redis(self._reconcile)

    def _read_commands(self) -> None:
        """Each owned shard's new entries (and, after an error, its own pending ones) into its
        backlog. A shard with a full backlog reads nothing (the stream holds the rest). After
        each read: more entries pending to this worker than it holds (a read's reply lost: a
        re-sent pipeline, a time-out) are read again from id 0; entries pending to another
        consumer of a shard this worker owns (read by an owner that lost it) are claimed."""
        if not self.owned:
            return
        plan = []
        for k in sorted(self.owned):
            o = self.owned[k]
            room = self.cfg.max_commands_per_tick * 2 - len(o.backlog)
            if room <= 0:
                continue
            start = o.reread if o.reread is not None else ">"
            plan.append((k, start, max(1, min(o.read_count, room))))
        if not plan:
            return
        for rd in self.store.read(plan):
            k, start, entries = rd.k, rd.start, rd.entries
            o = self.owned.get(k)
            if o is None or rd.nogroup:  # (a lost group is made again: Redis restarted empty)
                continue
            if rd.error is not None:
                raise rd.error
            if start != ">":
                o.reread = entries[-1][0].decode() if entries else None
            o.read_count = self._adapt(o.read_count, entries)
            for entry_id, raw in entries:
                self._enqueue(k, o, entry_id.decode(), raw)
            # (checked after a read of new entries: a re-read in pages does not loop on them)
            if start == ">" and rd.mine > len(o.inflight) + len(o.stale):
                o.reread = "0"
            if rd.others:
                for eid, raw in self.store.claim(k):
                    self._enqueue(k, o, eid, raw)

    def _enqueue(self, k: int, o: _Owned, eid: str, raw: dict | None) -> None:
        """An entry read (or claimed) into shard k's backlog, unless it is in hand already or was
        applied (Redis lost its acknowledgement: it is written again with its journal). A ship
        with ``max_commands_per_ship`` commands waiting has further ones rejected."""
        if raw is None or eid in o.inflight:
            return
        origin = (raw.get(rio.ROUTED.encode()) or b"").decode("ascii", "replace")
        if eid in o.applied or (origin and ROUTED_KEY + origin in o.applied):
            # applied, and pending again (Redis lost its acknowledgement), or routed again (a
            # rollback lost the route's acknowledgement): acknowledged once the journal that
            # holds it is in Redis again
            o.stale.add(eid)
            self._suspect.add(k)
            return
        o.inflight.add(eid)
        req = self._parse(k, eid, raw)
        limit = self.cfg.limits.max_commands_per_ship
        if isinstance(req, Request):
            if limit and o.waiting[req.ship_id] >= limit:
                req = Rejected(eid, req.ship_id, f"{req.cmd}: {limit} commands for ship "
                               f"{req.ship_id!r} are already waiting for their ticks (the "
                               f"per-ship rate)", req.cmd, req.player_id, req.size, req.origin)
            else:
                o.waiting[req.ship_id] += 1
        o.backlog.append(req)
        self.stats.commands_read += 1

    def _adapt(self, count: int, entries: list) -> int:
        """The next read's entry count: a read costs a tick at most the byte budget (commands
        of 64 KiB are read 64 at a time), and up to ``read_count`` entries of small ones."""
        if len(entries) < count:
            return count
        size = sum(len(f) + len(v) for _id, raw in entries for f, v in (raw or {}).items())
        budget = self.cfg.max_command_bytes_per_tick
        if size > budget:
            return max(1, count // 2)
        if size < budget // 4:
            return min(self.cfg.read_count, count * 2)
        return count

    def _parse(self, k: int, eid: str, raw: dict) -> Request | Rejected:
        fields = decode_entry(raw)
        origin = fields.pop(rio.ROUTED, "")[:40]
        req = dataclasses.replace(parse(eid, fields), origin=origin)
        if req.ship_id and shard_of(req.ship_id, self.cfg.shards) != k:
            right = shard_of(req.ship_id, self.cfg.shards)
            return Rejected(eid, req.ship_id, f"sent to shard {k}'s stream, but ship "
                            f"{req.ship_id!r} belongs to shard {right} (shard_of)",
                            getattr(req, "cmd", ""), req.player_id, req.size, origin)
        return req

    def _route(self) -> None:
        """The owner of shard 0 moves the shared command stream's entries (SPEC.md section 5's
        ``P:commands``) to their shards' streams: its own pending ones (a read whose reply was
        lost) and new ones, each read; those pending to another router (that lost shard 0)
        claimed."""
        count = getattr(self, "_route_count", 100)
        got = self.store.read_router(count)
        if got is None:  # its group lost (Redis restarted without its data): made again
            return
        entries, others = got
        if others:
            self.store.claim_router()
        self._route_count = self._adapt(count, entries)
        if not entries:
            return
        moves = []
        for entry_id, raw in entries:
            raw = raw or {}
            sid = raw.get(b"ship_id", b"").decode("utf-8", "surrogateescape")
            moves.append((entry_id, shard_of(sid, self.cfg.shards), raw))
        self.store.route(moves, self.cfg.shards)

    def _flush(self) -> None:
        """In one round trip: each shard's entries, results, hashes, specs and telemetry, and
        its checkpoint when due. A shard whose epoch is another worker's is dropped; one whose
        state Redis lost is written back (next loop); what Redis refused stays held."""
        writes = [self._writes(k) for k in sorted(self.owned)]
        self._flushed(self.store.flush(writes, self.cfg.events_maxlen, self.telemetry_maxlen,
                                       self.phase, self.cfg.results_maxlen))

    def _flush_send(self) -> None:
        """_flush's writes, their round trip on the flush thread (``flush_behind``): nothing of
        the shards changes until _flush_taken has its replies at the next loop's start (the
        writes refer to the shards' hashes, specs and telemetry, which only a step adds to)."""
        writes = [self._writes(k) for k in sorted(self.owned)]
        if self._flush_pool is None:
            self._flush_pool = ThreadPoolExecutor(1, thread_name_prefix="touchdown-flush")
        self._flushing = self._flush_pool.submit(
            self.store.flush, writes, self.cfg.events_maxlen, self.telemetry_maxlen, None,
            self.cfg.results_maxlen)

    def _flush_taken(self) -> None:
        """The replies of the flush _flush_send sent (its errors raised here, for _redis)."""
        flushing, self._flushing = self._flushing, None
        self._flushed(flushing.result())

    def _flushed(self, result) -> None:
        """What a flush's replies say: entries out, checkpoints written, shards lost or gone."""
        lost: set[int] = set()
        for k, f in result.shards.items():
            o = self.owned[k]
            for _ in range(f.out):
                o.sent.append(o.unsent.popleft())
            if f.out:
                o.confirmed_mark = o.sent[-1].number
            for _ in range(min(f.results, len(o.results))):
                o.results.popleft()
            self.stats.entries_sent += f.added
            if f.tick is not None:
                o.delivered = max(o.delivered, f.tick)
            if f.checkpointed:
                self._checkpointed(o, o.checkpoint.tick, set(o.checkpoint.gone))
                o.checkpoint = None
            if f.lost:
                lost.add(k)
            if f.gone:
                self._gone.add(k)
            if f.behind:
                self._suspect.add(k)
        if result.unreachable is not None:
            raise result.unreachable  # _redis: Redis is away; what was not written stays held
        for k in sorted(set(self.owned) - lost):
            if result.shards[k].refused is None:  # (what was refused stays, for the next)
                o = self.owned[k]
                o.hashes, o.specs, o.params, o.telemetry = {}, {}, {}, []
        for k in sorted(lost):
            self._lose(k, "its lease passed to another worker")
        if result.refused is not None:
            raise result.refused  # said once by _redis; what failed stays held

    def _checkpointed(self, o: _Owned, tick: int, gone: set) -> None:
        """A checkpoint of ``tick`` is in Redis: the ships that left before it are forgotten."""
        o.retired = [(t, sid) for t, sid in o.retired if sid not in gone]
        for sid in gone:
            o.joined.pop(sid, None)

    @staticmethod
    def _journaled(o: _Owned, tick: int, requests: list) -> None:
        """A tick's requests Redis holds in the journal: kept (the latest RETAIN_REQUESTS) to
        write again if Redis loses them; their ids (and a routed one's id on the shared stream)
        known as applied."""
        o.journaled.append(JournalRecord(tick, requests))
        for r in requests:
            o.applied[r.entry_id] = tick
            if r.origin:  # (ids repeat across streams: a routed one's is kept apart)
                o.applied[ROUTED_KEY + r.origin] = tick
        while len(o.applied) > 2 * RETAIN_REQUESTS and len(o.journaled) > 1:
            _t, old = o.journaled.popleft()
            for r in old:
                o.applied.pop(r.entry_id, None)
                o.applied.pop(ROUTED_KEY + r.origin, None)

    def _writes(self, k: int) -> ShardWrites:
        """Shard k's writes for this flush; its checkpoint taken when due (the records copied
        now, packed on a thread) and sent once packed and once the log has its tick on disk
        (no waiting on the log's thread here: that was the slowest tick's time)."""
        o = self.owned[k]
        sh = o.shard
        if (self._checkpoint_due(k, sh.tick) or o.force_checkpoint) and o.checkpoint is None:
            o.force_checkpoint = False
            gone = [sid for t, sid in o.retired if t <= sh.tick]
            with self.phase("checkpoint"):  # the records copied; packed on a thread
                pack = rio.checkpoint_later(k, self.cfg.shards, sh.world, sh.autoland,
                                            sh.published)
                o.checkpoint = PendingCheckpoint(self._packer().submit(pack), sh.tick,
                                                 sh.published, sh.log.flush(wait=False),
                                                 tuple(gone))
        cp = o.checkpoint.write() if o.checkpoint is not None and o.checkpoint.ready() else None
        return ShardWrites(k, sh.tick, list(o.unsent), o.hashes, o.specs, o.params,
                           o.telemetry, cp, o.fence, list(o.results), o.confirmed_mark)

    def _packer(self) -> ThreadPoolExecutor:
        """The thread that packs checkpoints (zstd; off the tick)."""
        if self._pack_pool is None:
            self._pack_pool = ThreadPoolExecutor(
                1, thread_name_prefix="touchdown-checkpoint",
                initializer=lambda: lower_priority(threading.get_native_id()))
        return self._pack_pool

    def _checkpoint_due(self, k: int, tick: int) -> bool:
        return checkpoint_due(k, tick, self.cfg.checkpoint_every, self.cfg.shards)

    def _checkpoint(self, k: int) -> int:
        """Shard k's checkpoint now (refused by the script unless every entry it counts is
        out): 1 written, -1 the lease lost, -2 refused, -3 the shard's state gone."""
        o = self.owned[k]
        sh = o.shard
        sh.log.flush()  # the log holds every tick up to the checkpoint before Redis does
        published = sh.published
        blob = rio.checkpoint_blob(k, self.cfg.shards, sh.world, sh.autoland, published)
        gone = [sid for t, sid in o.retired if t <= sh.tick]
        ok = self.store.checkpoint(k, o.fence, CheckpointWrite(blob, sh.tick, published,
                                                               tuple(gone)))
        if ok == 1:
            self._checkpointed(o, sh.tick, set(gone))
        return ok

    # -- shards: leases, taking over, handing over --------------------------------------------
    def _new_world(self, k: int) -> World:
        if not self.scenario_json:
            return World.empty(self.scene)
        return shard_world(self.scenario, k, self.cfg.shards)

    def _take_over(self, k: int, fence: Fence) -> None:
        """Own shard k: from its checkpoint and journal if it has them, else new (the
        scenario's ships of this shard)."""
        store = self.store
        start = self._shard_start(k)
        world = start.world
        # everything read from Redis first: a failure here leaves nothing half made
        tail = store.journal_since(k, world.tick)
        journal = tail.requests
        recorded = store.recorded_tick(k)
        last = max([recorded] + [t + 1 for t in journal])
        # what the last owner read but never journaled is new: this worker applies it next
        claimed, acks = [], []
        for eid, raw in store.claim(k):
            if eid in tail.ids:
                acks.append(eid)
                continue
            claimed.append((eid, raw))
        if acks:
            store.ack(k, acks)
        store.write_tables(k, start.fresh_specs, start.fresh_params)
        if k == 0 and not self.cfg.cluster:
            self._route_from = "0"
            store.claim_router()
        shard = self._open_shard(k, start, fence)
        o = _Owned(shard, fence)
        o.joined = {sid: int(v[0]) for sid, v in start.specs.items()}
        o.hashes.update(shard.hashes_of(np.arange(world.state.n), world.tick))
        self._whole_shards = True
        # the journal's requests, at their ticks, up to the last tick whose entries are out:
        # the same entries, with the same numbers, as the last owner's (dropped by the mark)
        caught = 0
        while shard.tick < last:
            requests = journal.get(shard.tick, [])
            if requests:  # (kept as this worker's own journal writes are: Redis may lose them)
                self._journaled(o, shard.tick, requests)
            self._take(o, shard.step(requests))
            caught += 1
        o.telemetry.clear()  # (specs and parameters are written again: a spawn journaled by
        # an owner that died before writing them would otherwise have none)
        o.results.clear()  # (the re-stepped ticks' results are in Redis already)
        for eid, raw in claimed:
            self._enqueue(k, o, eid, raw)
        o.reread = "0"
        o.delivered = shard.tick  # what Redis holds: this worker goes on from here
        o.journal_mark = max(journal, default=-1)
        store.began(k, fence, shard.tick)
        self.owned[k] = o
        if start.from_checkpoint:
            self.stats.takeovers += 1
        self.log(f"shard {k}: taken ({start.how}; {world.state.n} ships; re-stepped {caught} "
                 f"ticks to tick {shard.tick}; {len(claimed)} unjournaled commands claimed)")

    def _shard_start(self, k: int) -> ShardStart:
        """What shard k starts from: its checkpoint (ServeError if this worker cannot read it),
        or, without one, the scenario's ships of the shard (their specs and parameter records
        to write)."""
        store = self.store
        store.ensure_group(k)
        stored = store.load(k)
        specs_json = stored.specs
        if stored.blob is None:
            world = self._new_world(k)
            return ShardStart(
                world, [], 0, specs_json, "new", False,
                {sid: json.dumps([-1, spec], sort_keys=True) for sid, spec in world.known.items()},
                {sid: world.params.ships.rows[i].tobytes() for i, sid in enumerate(world.ship_ids)})
        try:
            cp, state, inputs = rio.read_checkpoint(stored.blob)
            ships = rio.ship_params(cp, store.params(k, list(cp.ship_ids)))
        except ValueError as exc:
            raise ServeError(f"{self.keys.shard(k, 'checkpoint')}: {exc}") from None
        # the ships known at the checkpoint's tick: those that joined after it are the
        # journal's spawns, re-applied by the take-over (not "taken")
        known = {sid: spec for sid, (tick, spec) in specs_json.items() if tick <= state.tick}
        for sid in cp.ship_ids:
            if sid not in known and sid in specs_json:
                known[sid] = specs_json[sid][1]
        world = World.restore(self.scene, ships, state, inputs, known)
        world.timeline = self._new_world(k).timeline.from_tick(state.tick)
        return ShardStart(world, list(cp.autoland), int(cp.published), specs_json,
                          f"from its checkpoint at tick {state.tick}", True)

    def _open_shard(self, k: int, start: ShardStart, fence: Fence) -> Shard:
        """Shard k's Shard from ``start``, with its flight log started (the file's first record:
        the state it starts at; every file's header names the take, ``fence``: logs.shards)."""
        cfg = self.cfg
        shard = Shard(k, start.world, None, self.body, dict.fromkeys(start.autoland),
                      start.published, limits=cfg.limits,
                      streams=(self.keys.shard_commands(k), self.keys.commands))
        shard.log = ServiceLog(
            cfg.log_dir / f"shard-{k:03d}", lambda: shard.world, self.log,
            prefix=self.id, keyframe_interval=cfg.keyframe_every,
            keyframe_phase=shard_phase(k, cfg.keyframe_every, cfg.shards),
            max_bytes=cfg.log_max_bytes, name=self.scenario.name,
            source=cfg.source or "serve", max_total_bytes=cfg.log_max_total_bytes,
            max_age_s=cfg.log_max_age_s, min_free_bytes=cfg.log_min_free_bytes,
            zstd_level=cfg.log_zstd_level, drop_cache=cfg.log_drop_cache,
            first_bytes=cfg.log_max_bytes * (k + 1) // cfg.shards,
            tables=self._header_tables(start.world),
            shard=ShardTake(k, fence.epoch, fence.taken_us) if fence.taken_us else None)
        shard.log.start()
        return shard

    def _header_tables(self, world: World) -> ShipTables:
        """The flight log's header tables of the world's ships that are the service scenario's
        own (World.of keeps its resolved tables in ``known``: the same objects), made from them
        (logs.header.header_table), not resolved again: the first header of a 12,500-ship shard
        resolved every ship (0.3 s each, in the loop that takes the shards). Ships known
        otherwise (spawned, restored from Redis) are resolved by the header as before."""
        if self._scenario_tables is None:
            self._scenario_tables = {id(t): t for t in self.scenario.resolved.get("ships", ())}
        own = self._scenario_tables
        tables = ShipTables()
        for sid in world.ship_ids:
            t = world.known.get(sid)
            if t is not None and own.get(id(t)) is t:
                tables[sid] = header_table(t)
        return tables

    def _hand_over(self, k: int) -> None:
        """Give shard k up cleanly: flushed, checkpointed, its log closed, its lease freed.
        Its backlog (read, not applied) stays pending in its group for the next owner."""
        o = self.owned[k]
        if o.unsent or o.results or o.unsure or self._checkpoint(k) != 1:
            return  # try again at the next lease round
        self.leases.release(k, o.fence)
        o.shard.log.close(complete=True, reason="handed over")
        self.reporter.keep_counts(o)
        del self.owned[k]
        self.log(f"shard {k}: handed over at tick {o.shard.tick}")

    def _lose(self, k: int, why: str) -> None:
        o = self.owned.pop(k, None)
        self.leases.forget(k)
        if o is None:
            return
        self.reporter.keep_counts(o)
        # where the new owner went on from: what Redis held when it took the shard, which is
        # less than what this worker delivered if Redis lost writes (a failover, an old
        # snapshot) before the new owner took it
        # (without a ``began`` of the current epoch (not written yet: it is re-stepping; or a
        # rollback lost it) what Redis holds, which after an old snapshot is less than this
        # worker delivered: chaos run of 2026-11-27, shard 0 superseded after 439 where its
        # successor began at 419, a command counted twice)
        try:
            o.delivered = min(o.delivered, self.store.successor_start(k, o.fence.epoch))
        except ERRORS:
            pass
        # the ticks after the last one Redis holds were never published: the next owner goes
        # on from that tick, and may apply what this worker applied since at other ticks
        o.shard.log.close(complete=True, reason="lost", superseded_after_tick=o.delivered)
        self.log(f"shard {k}: lost at tick {o.shard.tick} ({why}); its flight log superseded "
                 f"after tick {o.delivered} (the last Redis holds); {len(o.unsent)} unsent "
                 f"entries left to its new owner, which re-derives them", "warning")

    # -- when Redis lost what it held ------------------------------------------------------------
    def _reconcile(self, shards: set | None = None) -> None:
        """What Redis holds of each owned shard (or of ``shards``: those a script or a read
        found behind) against what this worker wrote. A shard whose epoch is gone (Redis
        restarted empty) is written back whole (_restore); one whose last writes Redis lost (a
        failover to a replica that had not received them, an append-only file fsynced every
        second, a restart from an older snapshot) has them written again (_rewrite); one with
        another epoch is another worker's now. Then the entries found pending again though
        applied (their acknowledgements lost with the journal, now written again) are
        acknowledged."""
        ks = sorted(set(self.owned) if shards is None else set(shards) & set(self.owned))
        held = self.store.state(ks)
        for k, h in held.items():
            o = self.owned.get(k)
            if o is None:
                continue
            if h.epoch is None:
                self._restore(k)
            elif h.epoch != o.fence.epoch:
                self._lose(k, "another worker took it while Redis was away")
            elif h.mark < o.confirmed_mark or h.journal_tick < o.journal_mark:
                self._rewrite(k, h.mark, h.journal_tick)
        for k in ks:
            o = self.owned.get(k)
            if o is not None and o.stale:
                self.store.ack(k, sorted(o.stale))
                o.stale.clear()

    def _rewrite(self, k: int, mark: int, journal_tick: int) -> None:
        """Redis lost shard k's last writes: the journal's records after ``journal_tick`` and the
        entries after ``mark`` written again (each at its own id or number: nothing twice), every
        ship's hash, and a checkpoint as soon as it can."""
        o = self.owned[k]
        records = [r for r in o.journaled if r.tick > journal_tick]
        code = self.store.rejournal(k, o.fence, records)
        if code == -1:
            self._lose(k, "another worker took it while Redis was away")
            return
        if code == -3:
            self._restore(k)
            return
        again = [e for e in o.sent if e.number > mark]
        gap = bool(again) and again[0].number > mark + 1 or (not again and o.confirmed_mark > mark)
        o.unsent.extendleft(reversed(again))
        o.sent = deque((e for e in o.sent if e.number <= mark), maxlen=RETAIN_ENTRIES)
        o.confirmed_mark = mark
        specs, params = self._tables(o)
        o.specs.update(specs)
        o.params.update(params)
        o.journal_mark = min(o.journal_mark, journal_tick) if not records else o.journal_mark
        o.hashes.update(o.shard.hashes_of(np.arange(o.shard.world.state.n), o.shard.tick))
        self._whole_shards = True
        o.force_checkpoint = True
        self.log(f"shard {k}: redis lost its last writes (its journal at tick {journal_tick}, "
                 f"its events at number {mark}): writing them again ({len(records)} journal "
                 f"records, {len(again)} entries{', a gap before them' if gap else ''}) and a "
                 f"checkpoint", "error")

    @staticmethod
    def _tables(o: _Owned) -> tuple[dict, dict]:
        """Every present ship's spec ([join tick, table] JSON) and parameter record, as the
        take-over reads them (to write again what Redis lost)."""
        world = o.shard.world
        specs = {sid: json.dumps([o.joined.get(sid, -1), world.known.get(sid, {})],
                                 sort_keys=True) for sid in world.ship_ids}
        params = {sid: world.params.ships.rows[i].tobytes()
                  for i, sid in enumerate(world.ship_ids)}
        return specs, params

    def _restore(self, k: int) -> None:
        """Redis lost shard k's state (restarted empty, or without its data): said once at
        error level, and what this worker holds written back: the shard's epoch, lease, marks,
        its ships' specs, parameters and hashes, the service's config and the group, a
        checkpoint of the tick in hand, and the entries it kept (re-sent to the new stream). If
        another worker took the shard meanwhile (it started the shard anew), the shard is
        dropped, and the line says its ships are lost."""
        o = self.owned.get(k)
        if o is None:
            return
        sh = o.shard
        store = self.store
        store.agree_on_config(self.cfg.shards, self.scenario_json)
        store.ensure_group(k)
        again = list(o.sent)
        first = again[0].number if again else (o.unsent[0].number if o.unsent else sh.published)
        world = sh.world
        specs, params = self._tables(o)
        hashes = sh.hashes_of(np.arange(world.state.n), sh.tick)
        got = store.restore(k, o.fence, first - 1, o.delivered, specs, params, hashes)
        if got != 1:
            self.log(f"shard {k}: redis lost its state and another worker has taken it anew "
                     f"meanwhile: this worker's {world.state.n} ships at tick {sh.tick} are "
                     f"not written back (its flight log has them)", "error")
            self._lose(k, "another worker took it while Redis was empty")
            return
        o.unsent.extendleft(reversed(again))
        o.sent.clear()
        o.confirmed_mark = first - 1
        o.journal_mark = -1
        o.journaled.clear()
        o.applied.clear()
        o.stale.clear()
        o.unsure = []
        o.checkpoint = None
        o.reread = "0"
        # a checkpoint as soon as every entry it counts is out (its script refuses it before)
        o.force_checkpoint = True
        if k not in self._said_gone:
            self._said_gone.add(k)
            self.log(f"shard {k}: redis lost its state (restarted empty?): wrote back what this "
                     f"worker holds ({world.state.n} ships at tick {sh.tick}: their specs, "
                     f"parameters and hashes, then a checkpoint; the events from number "
                     f"{first} sent again, those before it are gone with Redis)", "error")

    # -- figures (the reporter's) --------------------------------------------------------------
    def figures(self) -> dict:
        """What the stats line, the stats hash and the metrics say (service.report)."""
        return self.reporter.figures()

    # -- stop ----------------------------------------------------------------------------------
    def shutdown(self, flush_s: float = 5.0) -> None:
        """Finish: deliver what is held (for up to ``flush_s``), checkpoint every shard, free
        the leases, close the flight logs."""
        end = time.monotonic() + flush_s
        if self._flushing is not None:
            self._redis(self._flush_taken, clears=True)
        while self.owned and time.monotonic() < end:
            if not self.redis_up:
                self._reconnect()
                if not self.redis_up:
                    time.sleep(0.1)
                    continue
            done = self._redis(self._final_flush)
            if done:
                break
            time.sleep(0.05)
        self.leases.stop()
        for k in sorted(self.owned):
            o = self.owned[k]
            o.shard.log.close(complete=True, reason="stopped")
        held = sum(len(o.unsent) for o in self.owned.values())
        if held:
            self.log(f"stopped with {held:,} entries undelivered (Redis unreachable or "
                     f"refusing); the flight logs have them", "error")
        self.last_figures = self.figures()
        self.owned.clear()
        self.store.leave()
        self.store.close()
        self.reporter.close()
        if self._pack_pool is not None:
            self._pack_pool.shutdown(wait=False)
        if self._flush_pool is not None:
            self._flush_pool.shutdown(wait=False)

    def _final_flush(self) -> bool:
        self._flush()
        for k in sorted(self.owned):
            o = self.owned[k]
            if o.unsent or o.results:
                return False
            if self._checkpoint(k) == 1:
                self.leases.release(k, o.fence)
        return True


def shard_phase(k: int, every: int, shards: int) -> int:
    """The tick (mod ``every``) of shard k's work done every ``every`` ticks (its checkpoint,
    its flight log's keyframes): -k * every / shards mod every, the shards staggered across the
    period, so that no tick does two shards' while there are no more shards than ticks in it."""
    return -(k * every // shards) % every


def checkpoint_due(k: int, tick: int, every: int, shards: int) -> bool:
    """Shard k's checkpoint is due at ``tick``: every ``every`` ticks, staggered (shard_phase)."""
    return tick % every == shard_phase(k, every, shards)


def telemetry_maxlen(cfg: ServeConfig, dt_s: float) -> int:
    """The telemetry stream's cap in entries: ``cfg.telemetry_maxlen``, or by default what the
    shards send in TELEMETRY_KEEP_S simulated seconds (one entry a shard a tick): with 1 Hz
    samples of about 100 bytes a ship, about 1 kB a ship (10 MB per 10,000 ships), whatever the
    fleet and the shard count."""
    if cfg.telemetry_maxlen is not None:
        return cfg.telemetry_maxlen
    return max(1, int(round(TELEMETRY_KEEP_S / dt_s)) * cfg.shards)


def default_scenario() -> Scenario:
    """The scene of a service started without a scenario: the built-in ``bounce`` scene (the
    Moon, flat ground), its ship left out."""
    import touchdown.scenarios as builtin
    from touchdown.sim.scenario import parse_text
    return parse_text(builtin.text("bounce"), "bounce")


def shard_world(scn: Scenario, k: int, shards: int) -> World:
    """The world of shard k at tick 0: the scenario's ships whose shard is k (with their joins,
    leaves and commands); none for a service started without a scenario."""
    world = World.of(scn)
    mine = {sid for sid in world.known if shard_of(sid, shards) == k}
    keep = np.array([sid in mine for sid in world.ship_ids], dtype=bool)
    t = world.timeline
    return world.select(keep, Timeline.of([s for s in t.spawns if s.ship_id in mine],
                                          [r for r in t.retires if r.ship_id in mine],
                                          [c for c in t.commands if c.ship_id in mine]),
                        {sid: spec for sid, spec in world.known.items() if sid in mine})


def install_stop(worker: Worker) -> None:
    """SIGTERM and Ctrl-C: finish the tick in hand, then stop cleanly."""
    if threading.current_thread() is not threading.main_thread():
        return

    def on_signal(signum, frame):
        worker.stop.set()
    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
