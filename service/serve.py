"""``touchdown serve``: a worker of the live service (SPEC.md section 5).

Each worker owns some of the service's shards (a ship's shard: service.commands.shard_of) and
steps each owned shard's World one tick per loop, at ``rate`` ticks per wall-clock second:

    leases (renew; take free shards up to a fair share; hand extra ones over)
    commands: each owned shard's consumer group -> parsed requests, applied at this tick
    step each shard -> its flight log (rotating MCAP files) -> its numbered entries
    Redis: journal the requests (and ack them) -> publish the entries -> hashes, telemetry
    every ``checkpoint_every`` ticks: the shard's checkpoint

Redis is written in that order, and a shard's entries are published only once its requests are
journaled, so whatever Redis holds is a prefix of one history: the checkpoint, the journal after
it, the events up to the shard's recorded tick. A worker that takes a shard over (its owner died,
or handed it over) restores the checkpoint, re-steps the journal's requests at their ticks up to
that recorded tick (re-sent entries are dropped by the shard's mark), claims the commands its
predecessor read but never journaled, and goes on.

While Redis is unreachable the worker keeps stepping and logging; it holds the unsent entries (at
most ``buffer_max``; the flight log always has them) and the requests to journal, says so on
stderr, and delivers them in order once Redis answers again. Telemetry is a sample: the samples
of an outage are dropped.
"""
from __future__ import annotations

import json
import math
import os
import signal
import socket
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import redis

from logs.rotating import RotatingLog
from service import redis_io as rio
from service.commands import Rejected, Request, decode_entry, from_json, parse, shard_of
from service.shard import Shard, TickOut
from sim.scenario import Scenario, Scene, parse as parse_doc
from sim.timeline import Timeline
from sim.world import World

REDIS_ERRORS = (redis.exceptions.ConnectionError, redis.exceptions.TimeoutError)


class ServeError(Exception):
    """A user's mistake or a refused start (one line); the CLI exits 2."""


@dataclass(frozen=True)
class ServeConfig:
    url: str = "redis://127.0.0.1:6379/0"
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
    checkpoint_every: int = 20  # ticks
    telemetry_hz: float = 1.0  # samples of each ship per simulated second (0: none)
    telemetry_maxlen: int = 10_000
    buffer_max: int = 100_000  # unsent entries held while Redis is away
    log_max_bytes: int = 64 << 20
    keyframe_every: int = 10
    worker_id: str = ""
    max_shards: int | None = None  # at most this many shards (None: a fair share)
    read_count: int = 1000  # command entries read per shard per tick, at most


@dataclass
class Stats:
    ticks: int = 0
    tick_s: list = field(default_factory=list)  # work time of each loop (no sleeping)
    late: int = 0  # loops that began a whole period or more after their due time
    start_late_s: list = field(default_factory=list)  # how late each loop began (paced runs)
    entries_sent: int = 0
    entries_dropped: int = 0
    commands_read: int = 0
    takeovers: int = 0


@dataclass
class _Owned:
    shard: Shard
    journal: deque = field(default_factory=deque)  # (tick, [requests], [entry ids]) to write
    unsent: deque = field(default_factory=deque)  # (number, fields) to publish
    specs: dict = field(default_factory=dict)  # ship id -> JSON, to write
    hashes: dict = field(default_factory=dict)  # ship id -> fields or None, to write
    telemetry: list = field(default_factory=list)  # serialized samples to add
    #: what a former owner read and never journaled: (requests, entry ids), for the next tick
    claimed: tuple = ((), ())
    #: a checkpoint taken, waiting for the flight log to reach its tick: (blob, tick, published,
    #: the log's flush Event)
    checkpoint: tuple | None = None


class Worker:
    def __init__(self, cfg: ServeConfig, say: Callable[[str], None] | None = None):
        self.cfg = cfg
        self.say = say or (lambda line: print(f"touchdown serve: {line}", file=sys.stderr,
                                              flush=True))
        self.id = cfg.worker_id or f"{socket.gethostname()}-{os.getpid()}"
        self.keys = rio.Keys(cfg.prefix, cfg.events_stream, cfg.commands_stream)
        self.owned: dict[int, _Owned] = {}
        self.stats = Stats()
        self.stop = threading.Event()
        self.redis_up = True
        self._down_since = 0.0
        self._next_try = 0.0
        self._next_lease = 0.0
        self._started = time.monotonic()
        self.r = rio.connect(cfg.url)
        try:
            self.r.ping()
        except (redis.exceptions.RedisError, ValueError) as exc:
            raise ServeError(f"redis {cfg.url}: {exc}") from None
        self._scripts = {name: self.r.register_script(getattr(rio, name))
                         for name in ("PUBLISH", "JOURNAL", "CHECKPOINT", "RENEW", "RELEASE")}
        self.scenario, self.scenario_json = self._agree_on_config()
        self.scene = self.scenario.scene
        self.dt_s = self.scenario.params.sim.dt_s
        self.body = self.scenario.params.body.name
        period = 1.0 / (cfg.telemetry_hz * self.dt_s) if cfg.telemetry_hz > 0 else 0
        self.telemetry_every = max(1, int(round(period))) if period else 0

    # -- start ---------------------------------------------------------------------------------
    def _agree_on_config(self) -> tuple[Scenario, str]:
        """Every worker of a service shares its shard count and its scenario: the first to
        start writes them; a later one given others is refused."""
        cfg = self.cfg
        mine = json.dumps(cfg.scenario.resolved, sort_keys=True) if cfg.scenario else ""
        self.r.hsetnx(self.keys.config, "shards", cfg.shards)
        self.r.hsetnx(self.keys.config, "scenario_json", mine)
        stored = self.r.hgetall(self.keys.config)
        shards = int(stored[b"shards"])
        doc_json = stored[b"scenario_json"].decode()
        where = f"{cfg.url} {self.keys.config}"
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
    def run(self) -> Stats:
        cfg = self.cfg
        rate = (1.0 / self.dt_s) if cfg.rate_hz is None else cfg.rate_hz
        period = 1.0 / rate if rate > 0 else 0.0
        due = time.monotonic()
        loops = 0
        try:
            while not self.stop.is_set() and (cfg.ticks is None or loops < cfg.ticks):
                if period:
                    now = time.monotonic()
                    if now < due:
                        self.stop.wait(due - now)
                        if self.stop.is_set():
                            break
                    elif now - due > 1.0:  # far behind (a pause): start the schedule again
                        due = now
                    if now > due + period:
                        self.stats.late += 1
                    self.stats.start_late_s.append(max(0.0, now - due))
                    due += period
                t0 = time.perf_counter()
                self.loop_once()
                self.stats.tick_s.append(time.perf_counter() - t0)
                loops += 1
                self.stats.ticks = loops
        finally:
            self.shutdown()
        return self.stats

    def loop_once(self) -> None:
        now = time.monotonic()
        if not self.redis_up and now >= self._next_try:
            self._reconnect()
        if self.redis_up and now >= self._next_lease:
            self._redis(self._leases)
            self._next_lease = now + self.cfg.lease_s / 4
        fresh = self._redis(self._read_commands) if self.redis_up else None
        for k in sorted(self.owned):
            o = self.owned[k]
            reqs, ids = (fresh or {}).get(k, ((), ()))
            self._step(o, [*o.claimed[0], *reqs], [*o.claimed[1], *ids])
            o.claimed = ((), ())
        if self.redis_up:
            self._redis(self._flush)

    def _step(self, o: _Owned, requests: list, ids: list) -> None:
        sh = o.shard
        if ids:
            o.journal.append((sh.tick, requests, ids))
        out = sh.step(requests)
        self._take(o, out)
        every = self.telemetry_every
        if every and sh.world.state.n:
            # a rolling slice: each ship once per period, the work spread over its ticks
            rows = np.arange(sh.tick % every, sh.world.state.n, every)
            if rows.size and out.blocks:
                o.telemetry.append(sh.telemetry(out.blocks[-1], rows, self.dt_s, sh.index)
                                   .SerializeToString())
                del o.telemetry[:-4 * every]  # a sample: only the latest wait for Redis

    def _take(self, o: _Owned, out: TickOut) -> None:
        o.unsent.extend(out.entries)
        o.hashes.update(out.hashes)
        for block in out.blocks:
            for sp in block.spawned:
                o.specs[sp.ship_id] = json.dumps(sp.spec, sort_keys=True)
        held = sum(len(x.unsent) for x in self.owned.values())
        while held > self.cfg.buffer_max and o.unsent:
            o.unsent.popleft()
            held -= 1
            self.stats.entries_dropped += 1
            if self.stats.entries_dropped in (1, 1000, 100_000):
                self.say(f"event buffer full ({self.cfg.buffer_max:,}): dropped "
                         f"{self.stats.entries_dropped:,} entries so far (the flight logs "
                         f"have them)")

    # -- Redis, each step guarded ------------------------------------------------------------
    def _redis(self, fn, *args):
        """Run ``fn``; if Redis is unreachable, mark it down (the loop goes on) and return None."""
        try:
            return fn(*args)
        except REDIS_ERRORS as exc:
            if self.redis_up:
                self.redis_up = False
                self._down_since = time.monotonic()
                self.say(f"redis {self.cfg.url} unreachable ({type(exc).__name__}): ticking on; "
                         f"holding events (the flight logs have them) until it answers")
            self._next_try = time.monotonic() + 0.25
            return None

    def _reconnect(self) -> None:
        try:
            self.r.ping()
        except REDIS_ERRORS:
            self._next_try = time.monotonic() + 0.25
            return
        self.redis_up = True
        held = sum(len(o.unsent) for o in self.owned.values())
        self.say(f"redis back after {time.monotonic() - self._down_since:.1f} s: delivering "
                 f"{held:,} held entries")
        self._next_lease = 0.0

    def _read_commands(self) -> dict[int, tuple[list, list]]:
        """New entries of each owned shard's group: (requests for its ships, every entry id)."""
        if not self.owned:
            return {}
        pipe = self.r.pipeline(transaction=False)
        order = sorted(self.owned)
        for k in order:
            pipe.xreadgroup(rio.Keys.group(k), self.id, {self.keys.commands: ">"},
                            count=self.cfg.read_count)
        replies = pipe.execute(raise_on_error=False)
        out = {}
        for k, reply in zip(order, replies):
            if isinstance(reply, redis.exceptions.ResponseError):
                if "NOGROUP" in str(reply):  # Redis lost it (restarted without its data)
                    self._ensure_group(k)
                    continue
                raise reply
            if isinstance(reply, Exception):
                raise reply
            reqs, ids = [], []
            for _stream, entries in reply or []:
                for entry_id, raw in entries:
                    eid = entry_id.decode()
                    ids.append(eid)
                    req = parse(eid, decode_entry(raw))
                    if shard_of(req.ship_id, self.cfg.shards) == k:
                        reqs.append(req)
            if ids:
                out[k] = (reqs, ids)
                self.stats.commands_read += len(ids)
        return out

    def _ensure_group(self, k: int) -> None:
        try:
            self.r.xgroup_create(self.keys.commands, rio.Keys.group(k), id="0", mkstream=True)
        except redis.exceptions.ResponseError as exc:
            if "BUSYGROUP" not in str(exc):
                raise

    def _flush(self) -> None:
        """Journal (rare: only ticks that had commands), then in one round trip: each shard's
        entries, hashes, specs and telemetry, and its checkpoint when due."""
        lost: set[int] = set()
        for k in sorted(self.owned):
            o = self.owned[k]
            while o.journal:
                tick, reqs, ids = o.journal[0]
                payload = json.dumps([r.as_json() for r in reqs]) if reqs else ""
                ok = self._scripts["JOURNAL"](
                    keys=[self.keys.shard(k, "owner"), self.keys.shard(k, "journal"),
                          self.keys.commands],
                    args=[self.id, rio.Keys.group(k), f"{tick}-1", payload, *ids])
                if ok == -1:
                    lost.add(k)
                    break
                o.journal.popleft()
        pipe = self.r.pipeline(transaction=False)
        plan: list[tuple[str, int, int]] = []
        for k in sorted(set(self.owned) - lost):
            o = self.owned[k]
            sh = o.shard
            entries = list(o.unsent)
            chunks = [entries[i:i + 500] for i in range(0, len(entries), 500)] or [[]]
            for c, chunk in enumerate(chunks):  # the shard's tick goes with its last entries
                self._scripts["PUBLISH"](
                    keys=[self.keys.shard(k, "owner"), self.keys.shard(k, "published"),
                          self.keys.events, self.keys.shard(k, "tick")],
                    args=[self.id, sh.tick if c == len(chunks) - 1 else -1, 0,
                          *rio.flat_entries(chunk)], client=pipe)
                plan.append(("publish", k, len(chunk)))
            for sid, fields in o.hashes.items():
                if fields is None:
                    pipe.delete(self.keys.ship(sid))
                else:
                    pipe.hset(self.keys.ship(sid), mapping=fields)
                plan.append(("hash", k, 0))
            if o.specs:
                pipe.hset(self.keys.shard(k, "specs"), mapping=o.specs)
                plan.append(("specs", k, 0))
            for sample in o.telemetry:
                pipe.xadd(self.keys.telemetry, {"tick": str(sh.tick), "shard": str(k),
                                                "proto": sample},
                          maxlen=self.cfg.telemetry_maxlen, approximate=True)
                plan.append(("telemetry", k, 0))
            if self._checkpoint_due(k, sh.tick) and o.checkpoint is None:
                # taken now, sent once the log has this tick on disk (no waiting on the log's
                # thread here: that was the slowest tick's time)
                o.checkpoint = (rio.checkpoint_blob(k, self.cfg.shards, sh.world,
                                                    self.scenario_json, sh.autoland,
                                                    sh.published),
                                sh.tick, sh.published, sh.log.flush(wait=False))
            if o.checkpoint is not None and o.checkpoint[3].is_set():
                blob, tick, published, _ = o.checkpoint
                self._scripts["CHECKPOINT"](
                    keys=self._checkpoint_keys(k), args=[self.id, blob, tick, published],
                    client=pipe)
                plan.append(("checkpoint", k, 0))
        if not plan:
            return
        replies = pipe.execute(raise_on_error=False)
        for (what, k, n), reply in zip(plan, replies):
            if isinstance(reply, REDIS_ERRORS):
                raise reply
            if isinstance(reply, Exception):
                self.say(f"shard {k}: redis refused a {what}: {str(reply).splitlines()[0]}")
                continue
            if reply == -1 and what in ("publish", "checkpoint"):
                lost.add(k)
            elif what == "checkpoint" and reply == 1:
                self.owned[k].checkpoint = None
            elif what == "publish" and k not in lost:
                o = self.owned[k]
                for _ in range(n):
                    o.unsent.popleft()
                self.stats.entries_sent += reply
        for k in sorted(set(self.owned) - lost):
            o = self.owned[k]
            o.hashes, o.specs, o.telemetry = {}, {}, []
        for k in sorted(lost):
            self._lose(k, "its lease passed to another worker")

    def _checkpoint_due(self, k: int, tick: int) -> bool:
        """Every ``checkpoint_every`` ticks, the shards staggered across that period (the work
        of a tick stays even)."""
        every = self.cfg.checkpoint_every
        return (tick + k * every // self.cfg.shards) % every == 0

    def _checkpoint(self, k: int, client=None) -> int:
        """Shard k's checkpoint (refused by the script unless every entry it counts is out)."""
        o = self.owned[k]
        sh = o.shard
        sh.log.flush()  # the log holds every tick up to the checkpoint before Redis does
        blob = rio.checkpoint_blob(k, self.cfg.shards, sh.world, self.scenario_json,
                                   sh.autoland, sh.published)
        return self._scripts["CHECKPOINT"](keys=self._checkpoint_keys(k),
                                           args=[self.id, blob, sh.tick, sh.published],
                                           client=client)

    def _checkpoint_keys(self, k: int) -> list[str]:
        return [self.keys.shard(k, w) for w in ("owner", "checkpoint", "journal", "published")]

    # -- shards: leases, taking over, handing over --------------------------------------------
    def _new_world(self, k: int) -> World:
        if not self.scenario_json:
            return World.empty(self.scene)
        return shard_world(self.scenario, k, self.cfg.shards)

    def _leases(self) -> None:
        cfg = self.cfg
        lease_ms = int(cfg.lease_s * 1000)
        server_s = _server_time(self.r)
        pipe = self.r.pipeline(transaction=False)
        pipe.zadd(self.keys.workers, {self.id: server_s + cfg.lease_s})
        pipe.zremrangebyscore(self.keys.workers, "-inf", server_s)
        pipe.zcard(self.keys.workers)
        live = pipe.execute()[2]
        if self.owned:
            order = sorted(self.owned)
            kept = self._scripts["RENEW"](keys=[self.keys.shard(k, "owner") for k in order],
                                          args=[self.id, lease_ms])
            for k, ok in zip(order, kept):
                if not ok and not self.r.set(self.keys.shard(k, "owner"), self.id, nx=True,
                                             px=lease_ms):
                    self._lose(k, "its lease passed to another worker while Redis was away")
        share = math.ceil(cfg.shards / max(1, live))
        if cfg.max_shards is not None:
            share = min(share, cfg.max_shards)
        if len(self.owned) > share and time.monotonic() - self._started > cfg.lease_s:
            self._hand_over(max(self.owned))
        for k in range(cfg.shards):
            if len(self.owned) >= share:
                break
            if k not in self.owned and self.r.set(self.keys.shard(k, "owner"), self.id, nx=True,
                                                  px=lease_ms):
                self._take_over(k)

    def _take_over(self, k: int) -> None:
        """Own shard k: from its checkpoint and journal if it has them, else new (the
        scenario's ships of this shard)."""
        self._ensure_group(k)
        keys = self.keys
        blob = self.r.get(keys.shard(k, "checkpoint"))
        if blob is None:
            world, autoland, published = self._new_world(k), [], 0
            specs = {sid: json.dumps(spec, sort_keys=True) for sid, spec in world.known.items()}
            if specs:
                self.r.hset(keys.shard(k, "specs"), mapping=specs)
            how = "new"
        else:
            try:
                cp, ships, state, inputs = rio.read_checkpoint(blob)
            except ValueError as exc:
                raise ServeError(f"{keys.shard(k, 'checkpoint')}: {exc}") from None
            known = {sid.decode(): json.loads(v)
                     for sid, v in self.r.hgetall(keys.shard(k, "specs")).items()}
            world = World.restore(self.scene, ships, state, inputs, known)
            world.timeline = self._new_world(k).timeline.from_tick(state.tick)
            autoland, published = list(cp.autoland), int(cp.published)
            how = f"from its checkpoint at tick {state.tick}"
        # everything read from Redis first: a failure here leaves nothing half made
        journal: dict[int, list] = {}
        journaled: set[str] = set()
        for _id, fields in self.r.xrange(keys.shard(k, "journal"), f"{world.tick}-0", "+"):
            tick = int(_id.decode().split("-")[0])
            reqs = [from_json(d) for d in json.loads(fields[b"requests"])]
            journal[tick] = reqs
            journaled.update(r.entry_id for r in reqs)
        last = int(self.r.get(keys.shard(k, "tick")) or -1)
        last = max([last] + [t + 1 for t in journal])
        # what the last owner read but never journaled is new: this worker applies it next
        reqs, ids, acks = [], [], []
        for eid, raw in self._claim(k):
            if eid in journaled:
                acks.append(eid)
                continue
            ids.append(eid)
            req = parse(eid, decode_entry(raw))
            if shard_of(req.ship_id, self.cfg.shards) == k:
                reqs.append(req)
        if acks:
            self.r.xack(keys.commands, rio.Keys.group(k), *acks)
        log = RotatingLog(self.cfg.log_dir / f"shard-{k:03d}", world, prefix=self.id,
                          keyframe_interval=self.cfg.keyframe_every,
                          max_bytes=self.cfg.log_max_bytes, name=self.scenario.name,
                          source=self.cfg.source or "serve", open_ended=True)
        log.write_block(world.first_block())  # the file's first record: the state it starts at
        shard = Shard(k, world, log, self.body, dict.fromkeys(autoland), published)
        o = _Owned(shard)
        o.hashes.update(shard.hashes_of(np.arange(world.state.n), world.tick))
        # the journal's requests, at their ticks, up to the last tick whose entries are out:
        # the same entries, with the same numbers, as the last owner's (dropped by the mark)
        caught = 0
        while shard.tick < last:
            self._take(o, shard.step(journal.get(shard.tick, [])))
            caught += 1
        o.telemetry.clear()
        o.claimed = (reqs, ids)
        self.owned[k] = o
        if blob is not None:
            self.stats.takeovers += 1
        self.say(f"shard {k}: taken ({how}; {world.state.n} ships; re-stepped {caught} "
                 f"ticks to tick {shard.tick})")

    def _claim(self, k: int) -> list:
        """Every pending entry of shard k's group (read by a former owner), now this worker's."""
        out, start = [], "0-0"
        for _ in range(10_000):  # a bound: at most 10,000 pages of 1,000
            reply = self.r.xautoclaim(self.keys.commands, rio.Keys.group(k), self.id, 0,
                                      start_id=start, count=1000)
            start, entries = reply[0], reply[1]
            out += [(e[0].decode(), e[1]) for e in entries if e[1] is not None]
            if start in (b"0-0", "0-0"):
                break
        return out

    def _hand_over(self, k: int) -> None:
        """Give shard k up cleanly: flushed, checkpointed, its log closed, its lease freed."""
        o = self.owned[k]
        if o.journal or o.unsent or self._checkpoint(k) != 1:
            return  # try again at the next lease round
        self._scripts["RELEASE"](keys=[self.keys.shard(k, "owner")], args=[self.id])
        o.shard.log.close(complete=True, reason="handed over")
        del self.owned[k]
        self.say(f"shard {k}: handed over at tick {o.shard.tick}")

    def _lose(self, k: int, why: str) -> None:
        o = self.owned.pop(k, None)
        if o is None:
            return
        o.shard.log.close(complete=True, reason="lost")
        self.say(f"shard {k}: lost at tick {o.shard.tick} ({why}); {len(o.unsent)} unsent "
                 f"entries left to its new owner, which re-derives them")

    # -- stop ----------------------------------------------------------------------------------
    def shutdown(self, flush_s: float = 5.0) -> None:
        """Finish: deliver what is held (for up to ``flush_s``), checkpoint every shard, free
        the leases, close the flight logs."""
        end = time.monotonic() + flush_s
        while self.owned and time.monotonic() < end:
            if not self.redis_up:
                self._reconnect()
                if not self.redis_up:
                    time.sleep(0.1)
                    continue
            done = self._redis(self._final_flush)
            if done:
                break
        for k in sorted(self.owned):
            o = self.owned[k]
            o.shard.log.close(complete=True, reason="stopped")
        held = sum(len(o.unsent) for o in self.owned.values())
        if held:
            self.say(f"stopped with {held:,} entries undelivered (Redis unreachable); the "
                     f"flight logs have them")
        self.owned.clear()
        try:
            self.r.zrem(self.keys.workers, self.id)
            self.r.close()
        except REDIS_ERRORS:
            pass

    def _final_flush(self) -> bool:
        self._flush()
        for k in sorted(self.owned):
            o = self.owned[k]
            if o.journal or o.unsent:
                return False
            if self._checkpoint(k) == 1:
                self._scripts["RELEASE"](keys=[self.keys.shard(k, "owner")], args=[self.id])
        return True


def _server_time(r: redis.Redis) -> float:
    s, us = r.time()
    return s + us * 1e-6


def default_scenario() -> Scenario:
    """The scene of a service started without a scenario: the built-in ``bounce`` scene (the
    Moon, flat ground), its ship left out."""
    import scenarios as builtin
    from sim.scenario import parse_text
    return parse_text(builtin.text("bounce"), "bounce")


def shard_world(scn: Scenario, k: int, shards: int) -> World:
    """The world of shard k at tick 0: the scenario's ships whose shard is k (with their joins,
    leaves and commands); none for a service started without a scenario."""
    world = World.of(scn)
    mine = {sid for sid in world.known if shard_of(sid, shards) == k}
    keep = np.array([sid in mine for sid in world.ship_ids], dtype=bool)
    world.params = world.params.take(keep)
    world.state, world.inputs = world.state.select(keep), world.inputs.select(keep)
    t = world.timeline
    world.timeline = Timeline.of([s for s in t.spawns if s.ship_id in mine],
                                 [r for r in t.retires if r.ship_id in mine],
                                 [c for c in t.commands if c.ship_id in mine])
    world.known = {sid: spec for sid, spec in world.known.items() if sid in mine}
    return world


def install_stop(worker: Worker) -> None:
    """SIGTERM and Ctrl-C: finish the tick in hand, then stop cleanly."""
    if threading.current_thread() is not threading.main_thread():
        return

    def on_signal(signum, frame):
        worker.stop.set()
    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
