"""Every Redis call of a live-service worker (``service.serve.Worker``): its leases, the commands
it reads, the journal, what it publishes, its checkpoints, what it loads when it takes a shard
over, its health key and the router of the shared command stream. The keys and the scripts are
``service.redis_io``'s; the worker decides what to do (when a lease is lost, when Redis is away,
the budgets), this module only how it is written and read.

Results are typed (``Read``, ``Flushed``, ``FlushResult``, ``Loaded``, ``JournalTail``), never
loose tuples. Errors are Redis's own exceptions, as redis-py raises them: ``UNREACHABLE`` (a
connection lost, a time-out, a cluster's slot map unreachable) or a refusal (any other
``redis.exceptions.RedisError``: OOM, NOPERM, READONLY, ...), named by ``refusal_kind``. The
round trips are the worker's of before: one pipeline per flush (the journal, rare, first, one
script per tick that had commands), one per read, one per lease renewal.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import NamedTuple

import redis

from touchdown.service import redis_io as rio
from touchdown.service.commands import from_json

#: Redis (or, on a cluster, the node of a slot, or the slot map) unreachable
UNREACHABLE = (redis.exceptions.ConnectionError, redis.exceptions.TimeoutError,
               redis.exceptions.RedisClusterException)
#: anything Redis or the client can raise (unreachable, or a refusal)
ERRORS = (redis.exceptions.RedisError, redis.exceptions.RedisClusterException)
#: what Redis can answer instead of doing a write, by the name a message gives it
REFUSALS = {"OOM": "out of memory (maxmemory)", "NOPERM": "a permission missing from the ACL "
            "user", "READONLY": "a read-only replica", "BUSY": "busy running a script",
            "MISCONF": "unable to persist (MISCONF)", "LOADING": "loading its data"}

#: redis-py's exception classes, by the error code Redis sent (redis-py drops the code)
_KINDS = {"OutOfMemoryError": "OOM", "NoPermissionError": "NOPERM", "ReadOnlyError": "READONLY",
          "BusyLoadingError": "LOADING", "NoScriptError": "NOSCRIPT"}

PUBLISH_CHUNK = 500  # entries a PUBLISH script takes at most
#: ships' hashes a HASHES script writes at most (a single Redis): a call of 1,000 takes Redis a
#: few milliseconds, in which it answers nobody else
HASHES_CHUNK = 1000


def refusal_kind(exc: BaseException, text: str) -> str:
    """The kind of a refusal (OOM, NOPERM, ...), from redis-py's class or the error's text."""
    return _KINDS.get(type(exc).__name__) or (
        "NOPERM" if "can't run this command" in text or "no permissions" in text else
        text.split(" ", 1)[0] if text.split(" ", 1)[0].isupper() else type(exc).__name__)


def is_unreachable(exc: BaseException) -> bool:
    return isinstance(exc, UNREACHABLE)


# -- typed results -------------------------------------------------------------------------------
@dataclass
class Read:
    """One shard's read: its entries (id, raw fields or None: deleted), or ``nogroup`` (Redis
    lost the group: made again), or the ``error`` Redis answered; and, after the read, how many
    entries of the group are pending to this worker (``mine``) and to other consumers
    (``others``): more of them pending to this worker than it holds means a read's reply was
    lost (a re-sent pipeline, a time-out); any pending to another consumer, on a shard this
    worker owns, were read by an owner that has lost it."""
    k: int
    start: str
    entries: list = field(default_factory=list)
    nogroup: bool = False
    error: Exception | None = None
    mine: int = 0
    others: int = 0


@dataclass(frozen=True)
class JournalWrite:
    """One shard's JOURNAL of a tick, before the tick applies its requests: by the holder of
    ``fence``; ``retract``: the ticks of earlier writes whose reply never came (their requests
    are among these, now at this tick: removed in the same step); ``seen``: the last tick the
    worker saw journaled (-1 none: the script refuses if Redis holds less, having lost writes)."""
    k: int
    fence: "Fence"
    tick: int
    requests: list
    retract: list | None
    seen: int


class JournalRecord(NamedTuple):
    """A tick's requests as the journal holds them (kept by the worker to write again if Redis
    loses them)."""
    tick: int
    requests: list


class ShardHeld(NamedTuple):
    """What Redis holds of a shard (``ShardStore.state``): its epoch (None: gone), its mark (the
    last entry number out), the tick it records, its journal's last tick (-1: none)."""
    epoch: str | None
    mark: int
    tick: int
    journal_tick: int


@dataclass
class Journaled:
    """One shard's JOURNAL: ``code`` 1 written (or there already), -1 the shard is another
    worker's, -3 its state is gone (Redis restarted empty), -4 refused (the journal holds a later
    tick); or the ``refused`` error Redis answered."""
    k: int
    code: int = 0
    refused: Exception | None = None


@dataclass
class ShardWrites:
    """What one shard has for Redis at a flush: its held entries (number, fields), the ship
    hashes (fields, or None: deleted), the specs and parameters of ships that joined, the
    telemetry samples, and a checkpoint packed and ready (or None)."""
    k: int
    tick: int
    entries: list
    hashes: dict
    specs: dict
    params: dict
    telemetry: list
    checkpoint: "CheckpointWrite | None" = None
    fence: "Fence | None" = None
    results: list = field(default_factory=list)  # (tick, results JSON) to write
    mark: int = -1  # the shard's mark the worker last saw Redis confirm (PUBLISH checks it)


@dataclass(frozen=True)
class Fence:
    """What every owner-only script is given: the worker, the shard's epoch it took, the lease;
    and when the take happened by Redis's clock (µs since 1970; 0: not known), which orders a
    shard's flight logs (logs.shards)."""
    worker: str
    epoch: str
    lease_ms: int
    taken_us: int = 0

    def args(self) -> list:
        return [self.worker, self.epoch, self.lease_ms]


@dataclass(frozen=True)
class CheckpointWrite:
    blob: bytes
    tick: int
    published: int
    gone: tuple  # ship ids whose specs and parameters it drops


@dataclass
class Flushed:
    """One shard's flush. ``out``: how many of its held entries are now on the stream (in
    order, from the first), ``added`` of them new there; ``tick``: the shard's tick Redis now
    records (its last entries went out), else None; ``checkpointed``: the checkpoint was
    written; ``lost``: the lease is another worker's; ``refused``: the first refusal of one of
    its writes (what was not written stays held)."""
    out: int = 0
    added: int = 0
    tick: int | None = None
    checkpointed: bool = False
    lost: bool = False
    refused: Exception | None = None
    gone: bool = False  # the shard's epoch is gone: Redis lost its state
    behind: bool = False  # the shard's mark is below what the worker saw: Redis lost writes
    results: int = 0  # results entries written (or there already), in order from the first


@dataclass
class FlushResult:
    shards: dict  # k -> Flushed
    #: Redis went away while replying: the replies before it are in ``shards``, the rest unknown
    unreachable: Exception | None = None
    #: the first refusal, of any shard
    refused: Exception | None = None


@dataclass
class Loaded:
    """What Redis holds of shard k for a take-over: its checkpoint (None: a new shard) and its
    ships' specs (ship id -> [join tick, table])."""
    blob: bytes | None
    specs: dict


@dataclass
class JournalTail:
    """The journal from a tick on: the requests applied at each tick, and their entry ids."""
    requests: dict  # tick -> [Request | Rejected]
    ids: set


# -- the store -----------------------------------------------------------------------------------
class ShardStore:
    """A worker's Redis: ``keys`` (redis_io.Keys), the worker's id, and its clients (the loop's,
    and one with a short time-out for pinging while Redis is away). ``connect`` raises
    ValueError for a URL that is not a Redis one and Redis's errors for the rest."""

    def __init__(self, url: str, password: str | None, keys: rio.Keys, worker: str,
                 cluster: bool = False):
        self.url, self.password, self.cluster = url, password, cluster
        self.keys = keys
        self.worker = worker
        self.r = rio.connect(url, password, cluster=cluster)
        self.r_ping = rio.connect(url, password, timeout=0.25, cluster=cluster)

    # -- the service ---------------------------------------------------------------------------
    def ping(self) -> None:
        self.r.ping()

    def ping_all(self) -> None:
        """Every master answers (a cluster's node's slots are down with it); short time-out."""
        if self.cluster:
            self.r_ping.ping(target_nodes="primaries")
        else:
            self.r_ping.ping()

    def agree_on_config(self, shards: int, scenario_json: str) -> tuple[int, str]:
        """The service's shard count and scenario: the first worker's (these, if first)."""
        self.r.hsetnx(self.keys.config, "shards", shards)
        self.r.hsetnx(self.keys.config, "scenario_json", scenario_json)
        stored = self.r.hgetall(self.keys.config)
        return int(stored[b"shards"]), stored[b"scenario_json"].decode()

    def ensure_group(self, k: int | None) -> None:
        """Shard k's consumer group (None: the router's on the shared stream), made if missing;
        shard 0's makes the router's too (not on a cluster)."""
        stream, group = ((self.keys.commands, rio.Keys.ROUTER) if k is None else
                         (self.keys.shard_commands(k), rio.Keys.group(k)))
        try:
            self.r.xgroup_create(stream, group, id="0", mkstream=True)
        except redis.exceptions.ResponseError as exc:
            if "BUSYGROUP" not in str(exc):
                raise
        if k == 0 and not self.cluster:
            self.ensure_group(None)

    def write_stats(self, figures: dict, ttl_s: int) -> None:
        """The worker's health key: its figures, with a time-out."""
        key = self.keys.stats(self.worker)
        pipe = self.r.pipeline(transaction=False)
        pipe.hset(key, mapping={k: str(v) for k, v in figures.items()})
        pipe.expire(key, ttl_s)
        pipe.execute()

    def leave(self) -> None:
        """Off the live workers, the health key gone (best effort)."""
        try:
            self.r.zrem(self.keys.workers, self.worker)
            self.r.delete(self.keys.stats(self.worker))
        except ERRORS:
            pass

    def close(self) -> None:
        for client in (self.r, self.r_ping):
            try:
                client.close()
            except ERRORS:
                pass

    # -- leases ----------------------------------------------------------------------------------
    def live_workers(self) -> int:
        return self.r.zcard(self.keys.workers) or 1

    def take_lease(self, k: int, lease_ms: int) -> Fence | None:
        """TAKE: shard k's lease if it is free, with a new epoch (its fence), else None."""
        got = self._script("TAKE", self._fence_keys(k), [self.worker, lease_ms])
        if not got:
            return None
        epoch, sec, usec = (x.decode() if isinstance(x, bytes) else x for x in got)
        return Fence(self.worker, epoch, lease_ms, int(sec) * 1_000_000 + int(usec))

    def holds_lease(self, k: int) -> bool:
        return self.r.get(self.keys.shard(k, "owner")) == self.worker.encode()

    def release(self, k: int, fence: Fence) -> None:
        self._script("RELEASE", self._fence_keys(k), [self.worker, fence.epoch])

    def _fence_keys(self, k: int) -> list[str]:
        return [self.keys.shard(k, "owner"), self.keys.shard(k, "epoch")]

    def lease_keeper(self, timeout: float) -> "LeaseKeeper":
        """A connection of its own for the lease thread."""
        return LeaseKeeper(self, timeout)

    # -- commands ---------------------------------------------------------------------------------
    def read(self, plan: list[tuple[int, str, int]]) -> list[Read]:
        """Each (shard, start id, count): its entries from its consumer group, and then who has
        entries pending in the group (XPENDING's summary), in one round trip (``>``: new ones;
        an id: this worker's own pending ones after it). A shard whose group Redis lost has it
        made again (``nogroup``)."""
        pipe = self.r.pipeline(transaction=False)
        for k, start, count in plan:
            stream = self.keys.shard_commands(k)
            pipe.xreadgroup(rio.Keys.group(k), self.worker, {stream: start}, count=count)
            pipe.xpending(stream, rio.Keys.group(k))
        replies = pipe.execute(raise_on_error=False)
        out = []
        for i, (k, start, _count) in enumerate(plan):
            reply, pending = replies[2 * i], replies[2 * i + 1]
            for r in (reply, pending):
                if isinstance(r, UNREACHABLE):
                    raise r
            if isinstance(reply, redis.exceptions.ResponseError) and "NOGROUP" in str(reply):
                self.ensure_group(k)  # Redis lost it (restarted without its data)
                out.append(Read(k, start, nogroup=True))
                continue
            if isinstance(reply, Exception):
                out.append(Read(k, start, error=reply))
                continue
            rd = Read(k, start, [e for _s, es in (reply or []) for e in es])
            rd.mine, rd.others = _pending_counts(pending, self.worker)
            out.append(rd)
        return out

    def read_router(self, count: int) -> tuple[list, int] | None:
        """The shared command stream's entries for the router: its own pending ones (a read
        whose reply was lost, a route refused) and new ones, in one round trip, and how many are
        pending to other consumers (a former router's). None: the group was lost, and made
        again."""
        pipe = self.r.pipeline(transaction=False)
        pipe.xreadgroup(rio.Keys.ROUTER, self.worker, {self.keys.commands: "0"}, count=count)
        pipe.xreadgroup(rio.Keys.ROUTER, self.worker, {self.keys.commands: ">"}, count=count)
        pipe.xpending(self.keys.commands, rio.Keys.ROUTER)
        replies = pipe.execute(raise_on_error=False)
        for reply in replies:
            if isinstance(reply, redis.exceptions.ResponseError) and "NOGROUP" in str(reply):
                self.ensure_group(None)
                return None
            if isinstance(reply, Exception):
                raise reply
        seen, entries = set(), []
        for reply in replies[:2]:
            for _s, es in reply or []:
                for e in es:
                    if e[0] not in seen and e[1] is not None:
                        seen.add(e[0])
                        entries.append(e)
        return entries, _pending_counts(replies[2], self.worker)[1]

    def route(self, moves: list[tuple[bytes, int, dict]], shards: int) -> int:
        """ROUTE: each (entry id, shard, raw fields) still pending to this router moved to its
        shard's stream and acknowledged, in one script."""
        args: list = [rio.Keys.ROUTER, self.worker]
        for entry_id, k, raw in moves:
            args += [entry_id, k, len(raw)]
            for f, v in raw.items():
                args += [f, v]
        keys = [self.keys.commands] + [self.keys.shard_commands(k) for k in range(shards)]
        return self.r.eval(rio.ROUTE, len(keys), *keys, *args)

    def claim(self, k: int) -> list[tuple[str, dict]]:
        """Every pending entry of shard k's group (read by a former owner), now this worker's."""
        out, start = [], "0-0"
        for _ in range(10_000):  # a bound: at most 10,000 pages of 1,000
            reply = self.r.xautoclaim(self.keys.shard_commands(k), rio.Keys.group(k),
                                      self.worker, 0, start_id=start, count=1000)
            start, entries = reply[0], reply[1]
            out += [(e[0].decode(), e[1]) for e in entries if e[1] is not None]
            if start in (b"0-0", "0-0"):
                break
        return out

    def claim_router(self) -> None:
        """The router's pending entries (a former router read and never routed them)."""
        start = "0-0"
        for _ in range(10_000):
            reply = self.r.xautoclaim(self.keys.commands, rio.Keys.ROUTER, self.worker, 0,
                                      start_id=start, count=1000)
            start = reply[0]
            if start in (b"0-0", "0-0"):
                break

    def ack(self, k: int, ids: list[str]) -> None:
        self.r.xack(self.keys.shard_commands(k), rio.Keys.group(k), *ids)

    # -- the journal ------------------------------------------------------------------------------
    def journal(self, writes: list[JournalWrite]) -> list[Journaled]:
        """JOURNAL, before a tick applies its requests: each write (:class:`JournalWrite`) with
        its entries' acknowledgements, one script a shard, in one round trip. Redis unreachable
        raises (the outcome of each is then unknown)."""
        pipe = self.r.pipeline(transaction=False)
        for w in writes:
            self._journal(pipe, w.k, w.fence, w.tick, w.requests, w.retract, w.seen)
        replies = pipe.execute(raise_on_error=False)
        out = []
        for w, reply in zip(writes, replies):
            k = w.k
            if isinstance(reply, UNREACHABLE):
                raise reply
            if isinstance(reply, Exception):
                out.append(Journaled(k, refused=reply))
            else:
                out.append(Journaled(k, int(reply)))
        return out

    def _journal(self, pipe, k: int, fence: Fence, tick: int, requests: list,
                 retract: list | None, seen: int) -> None:
        payload = json.dumps([r.as_json() for r in requests]) if requests else ""
        self._script("JOURNAL", [*self._fence_keys(k), self.keys.shard(k, "journal"),
                                 self.keys.shard_commands(k), self.keys.shard(k, "journaled")],
                     [*fence.args(), rio.Keys.group(k), f"{tick}-1", payload,
                      ",".join(f"{t}-1" for t in retract or ()), seen, tick,
                      *[r.entry_id for r in requests]], client=pipe)

    def rejournal(self, k: int, fence: Fence, records: list[JournalRecord]) -> int:
        """The journal's records (:class:`JournalRecord`) written again after Redis lost them (a
        failover's last writes): each at its own id, with its acknowledgements. 1, or the
        first script's code that was not (-1, -3, -4)."""
        if not records:
            return 1
        pipe = self.r.pipeline(transaction=False)
        for tick, requests in records:
            self._journal(pipe, k, fence, tick, requests, None, -1)
        codes = [int(x) for x in pipe.execute()]
        return next((c for c in codes if c != 1), 1)

    # -- a flush: the events, hashes, specs, parameters, telemetry, checkpoints ------------------
    def flush(self, shards: list[ShardWrites], events_maxlen: int, telemetry_maxlen: int,
              phase=None, results_maxlen: int = 10_000) -> FlushResult:
        """Every shard's writes in one pipeline (one round trip; a cluster's: one per master).
        A shard's entries go in PUBLISH scripts of up to PUBLISH_CHUNK, its tick with the last.
        ``phase``: the worker's phase timer (service.phases), the round trip timed as
        ``redis_io``."""
        pipe = self.r.pipeline(transaction=False)
        plan: list[tuple[str, int, int, int]] = []  # (what, shard, entries, tick or -1)
        keys = self.keys
        for w in shards:
            k = w.k
            entries = w.entries
            chunks = [entries[i:i + PUBLISH_CHUNK]
                      for i in range(0, len(entries), PUBLISH_CHUNK)] or [[]]
            for c, chunk in enumerate(chunks):
                tick = w.tick if c == len(chunks) - 1 else -1
                self._script("PUBLISH", [*self._fence_keys(k), keys.shard(k, "published"),
                                         keys.shard_events(k), keys.shard(k, "tick")],
                             [*w.fence.args(), tick, events_maxlen, w.mark,
                              *rio.flat_entries(chunk)], client=pipe)
                plan.append(("publish", k, len(chunk), tick))
            for tick, payload in w.results:
                self._script("RESULTS", [keys.shard_results(k)],
                             [f"{tick}-1", results_maxlen, tick, payload], client=pipe)
                plan.append(("results", k, 0, -1))
            for _ in range(self._hashes(w.hashes, pipe)):
                plan.append(("hash", k, 0, -1))
            if w.specs:
                pipe.hset(keys.shard(k, "specs"), mapping=w.specs)
                plan.append(("specs", k, 0, -1))
            if w.params:
                pipe.hset(keys.shard(k, "params"), mapping=w.params)
                plan.append(("params", k, 0, -1))
            for sample in w.telemetry:
                pipe.xadd(keys.telemetry, {"tick": str(w.tick), "shard": str(k),
                                           "proto": sample},
                          maxlen=telemetry_maxlen, approximate=True)
                plan.append(("telemetry", k, 0, -1))
            cp = w.checkpoint
            if cp is not None:
                self._script("CHECKPOINT", self._checkpoint_keys(k),
                             [*w.fence.args(), cp.blob, cp.tick, cp.published, *cp.gone],
                             client=pipe)
                plan.append(("checkpoint", k, 0, -1))
        result = FlushResult({w.k: Flushed() for w in shards})
        if not plan:
            return result
        if phase is None:
            replies = pipe.execute(raise_on_error=False)
        else:
            with phase("redis_io"):
                replies = pipe.execute(raise_on_error=False)
        for (what, k, n, tick), reply in zip(plan, replies):
            f = result.shards[k]
            if isinstance(reply, UNREACHABLE):
                result.unreachable = reply
                break
            if isinstance(reply, Exception):
                f.refused = f.refused or reply
                result.refused = result.refused or reply
                continue
            if reply == -1 and what in ("publish", "checkpoint"):
                f.lost = True
            elif reply == -3 and what in ("publish", "checkpoint"):
                f.gone = True
            elif reply == -5 and what == "publish":
                f.behind = True
            elif what == "results":
                f.results += 1
            elif what == "checkpoint" and reply == 1:
                f.checkpointed = True
            elif what == "publish" and not (f.lost or f.gone or f.behind):
                f.out += n
                f.added += reply
                if tick != -1:
                    f.tick = tick
        return result

    # -- checkpoints ------------------------------------------------------------------------------
    def checkpoint(self, k: int, fence: Fence, cp: CheckpointWrite) -> int:
        """CHECKPOINT now (a hand-over, a stop): 1 written, -1 the lease lost, -2 refused (not
        every entry it counts is out), -3 the shard's state gone."""
        return self._script("CHECKPOINT", self._checkpoint_keys(k),
                            [*fence.args(), cp.blob, cp.tick, cp.published, *cp.gone])

    def _checkpoint_keys(self, k: int) -> list[str]:
        return [self.keys.shard(k, w) for w in ("owner", "epoch", "checkpoint", "journal",
                                                "published", "specs", "params")]

    # -- after an outage: what Redis still holds, and writing back what it lost ---------------
    def state(self, shards: list[int]) -> dict[int, ShardHeld]:
        """What Redis holds of each shard (:class:`ShardHeld`), in one round trip."""
        if not shards:
            return {}
        pipe = self.r.pipeline(transaction=False)
        for k in shards:
            self._script("STATE", [self.keys.shard(k, w) for w in ("epoch", "published", "tick",
                                                                    "journaled")], [],
                         client=pipe)
        out = {}
        for k, (epoch, mark, tick, last) in zip(shards, pipe.execute()):
            out[k] = ShardHeld(epoch.decode() if isinstance(epoch, bytes) else epoch, int(mark),
                               int(tick), int(last))
        return out

    def restore(self, k: int, fence: Fence, mark: int, tick: int, specs: dict, params: dict,
                hashes: dict) -> int:
        """RESTORE shard k's epoch, lease, mark and recorded tick (-1: another worker took it
        meanwhile), then its ships' specs, parameters and hashes."""
        got = self._script("RESTORE", [*self._fence_keys(k), self.keys.shard(k, "published"),
                                       self.keys.shard(k, "tick")],
                           [*fence.args(), mark, tick])
        if got != 1:
            return int(got)
        pipe = self.r.pipeline(transaction=False)
        if specs:
            pipe.hset(self.keys.shard(k, "specs"), mapping=specs)
        if params:
            pipe.hset(self.keys.shard(k, "params"), mapping=params)
        self._hashes({sid: f for sid, f in hashes.items() if f is not None}, pipe)
        pipe.execute()
        return 1

    def _hashes(self, hashes: dict, pipe) -> int:
        """Queue the writes of ships' hashes (ship id -> its fields, or None: the ship left,
        its hash deleted) on ``pipe``; returns how many commands were queued. A single Redis
        takes them HASHES_CHUNK at a time, by field names in common (HASHES, one script call:
        the same HSETs, without a command's packing and reply a ship); a cluster, whose ship
        keys are in many slots, one HSET or DEL a ship."""
        ship = self.keys.ship
        if self.cluster:
            for sid, fields in hashes.items():
                if fields is None:
                    pipe.delete(ship(sid))
                else:
                    pipe.hset(ship(sid), mapping=fields)
            return len(hashes)
        groups: dict[tuple, tuple[list, list]] = {}
        gone: list[str] = []
        for sid, fields in hashes.items():
            if fields is None:
                gone.append(ship(sid))
                continue
            names = tuple(fields)
            group = groups.get(names)
            if group is None:
                group = groups[names] = ([], [])
            group[0].append(ship(sid))
            group[1].extend(fields.values())
        queued = 0
        for i in range(0, len(gone), HASHES_CHUNK):
            pipe.delete(*gone[i:i + HASHES_CHUNK])
            queued += 1
        for names, (keys, values) in groups.items():
            nf = len(names)
            for i in range(0, len(keys), HASHES_CHUNK):
                self._script("HASHES", keys[i:i + HASHES_CHUNK],
                             [nf, *names, *values[i * nf:(i + HASHES_CHUNK) * nf]], client=pipe)
                queued += 1
        return queued

    # -- a take-over ------------------------------------------------------------------------------
    def load(self, k: int) -> Loaded:
        """Shard k's checkpoint and its ships' specs."""
        blob = self.r.get(self.keys.shard(k, "checkpoint"))
        specs = {sid.decode(): json.loads(v)
                 for sid, v in self.r.hgetall(self.keys.shard(k, "specs")).items()}
        return Loaded(blob, specs)

    def params(self, k: int, ship_ids: list[str]) -> list:
        """The parameter records of these ships (None for a missing one), in their order."""
        return self.r.hmget(self.keys.shard(k, "params"), ship_ids) if ship_ids else []

    def journal_since(self, k: int, tick: int) -> JournalTail:
        tail = JournalTail({}, set())
        for _id, fields in self.r.xrange(self.keys.shard(k, "journal"), f"{tick}-0", "+"):
            t = int(_id.decode().split("-")[0])
            reqs = [from_json(d) for d in json.loads(fields[b"requests"])]
            tail.requests[t] = reqs
            tail.ids.update(r.entry_id for r in reqs)
        return tail

    def recorded_tick(self, k: int) -> int:
        """The last tick whose entries are on the event stream (-1: none)."""
        return int(self.r.get(self.keys.shard(k, "tick")) or -1)

    def began(self, k: int, fence: Fence, tick: int) -> None:
        """The tick this epoch of shard k goes on from (the new owner, once it has re-stepped
        what Redis holds)."""
        self.r.set(self.keys.shard(k, "from"), f"{fence.epoch} {tick}")

    def successor_start(self, k: int, mine: str) -> int:
        """The tick shard k's latest owner goes on from: its ``began`` if the shard's current
        epoch (not ``mine``, the caller's) wrote one; else (it is re-stepping still, or a rollback lost its ``began``, or
        kept an older epoch's) as its take-over derives it from what Redis holds: past the last
        tick whose entries are out and the last journaled one. (Read first: no owner writes
        the tick or the journal between taking the lease and its ``began``.)"""
        recorded = self.recorded_tick(k)
        journaled = self.r.get(self.keys.shard(k, "journaled"))
        held = max(recorded, int(journaled) + 1 if journaled is not None else -1)
        epoch = self.r.get(self.keys.shard(k, "epoch"))
        got = self.successor_from(k)
        if got is not None and epoch is not None and got[0] == epoch.decode() != mine:
            return got[1]
        return held

    def successor_from(self, k: int) -> tuple[str, int] | None:
        """(epoch, tick) the shard's latest owner went on from, or None."""
        got = self.r.get(self.keys.shard(k, "from"))
        if not got:
            return None
        epoch, tick = got.decode().rsplit(" ", 1)
        return epoch, int(tick)

    def write_tables(self, k: int, specs: dict, params: dict) -> None:
        """A new shard's ships' specs and parameters."""
        if specs:
            self.r.hset(self.keys.shard(k, "specs"), mapping=specs)
        if params:
            self.r.hset(self.keys.shard(k, "params"), mapping=params)

    # -- scripts ----------------------------------------------------------------------------------
    def _script(self, name: str, keys: list, args: list, client=None):
        """One of redis_io's scripts, by EVAL (no SCRIPT LOAD or EXISTS: fewer permissions)."""
        # (execute_command: a cluster's pipeline has no eval(), but routes EVAL by its keys)
        return (client or self.r).execute_command("EVAL", getattr(rio, name), len(keys), *keys,
                                                  *args)


def _pending_counts(summary, worker: str) -> tuple[int, int]:
    """XPENDING's summary: the entries pending to ``worker``, and to every other consumer."""
    mine = others = 0
    if isinstance(summary, dict):
        for c in summary.get("consumers") or ():
            name = c["name"].decode() if isinstance(c["name"], bytes) else c["name"]
            if name == worker:
                mine += int(c["pending"])
            else:
                others += int(c["pending"])
    return mine, others


class LeaseKeeper:
    """The lease thread's connection: the worker's heartbeat and its leases' renewals."""

    def __init__(self, store: ShardStore, timeout: float):
        self.keys, self.worker, self.cluster = store.keys, store.worker, store.cluster
        self.r = rio.connect(store.url, store.password, timeout=timeout, cluster=store.cluster)

    def heartbeat(self, lease_s: float) -> int:
        """This worker alive until a lease from now (Redis's clock); the live workers' count."""
        server_s = _server_time(self.r)
        pipe = self.r.pipeline(transaction=False)
        pipe.zadd(self.keys.workers, {self.worker: server_s + lease_s})
        pipe.zremrangebyscore(self.keys.workers, "-inf", server_s)
        pipe.zcard(self.keys.workers)
        return pipe.execute()[2]

    def renew(self, shards: list[tuple[int, str]], lease_ms: int) -> list[int]:
        """RENEW each (shard, epoch)'s lease: 1 still this worker's (a lapsed lease nobody took
        is taken back), 0 another's, -3 its state gone. One script (a cluster: one per shard,
        each in its slot, pipelined)."""
        if not shards:
            return []
        keys = lambda k: [self.keys.shard(k, "owner"), self.keys.shard(k, "epoch")]  # noqa
        if self.cluster:
            pipe = self.r.pipeline()
            for k, epoch in shards:
                pipe.execute_command("EVAL", rio.RENEW, 2, *keys(k), self.worker, lease_ms,
                                     epoch)
            kept = [x[0] for x in pipe.execute()]
        else:
            flat = [key for k, _e in shards for key in keys(k)]
            kept = self.r.eval(rio.RENEW, len(flat), *flat, self.worker, lease_ms,
                               *[e for _k, e in shards])
        return [int(x) for x in kept]

    def close(self) -> None:
        self.r.close()


def _server_time(r) -> float:
    t = r.time()
    if isinstance(t, dict):  # a cluster client may answer per node
        t = next(iter(t.values()))
    s, us = t
    return s + us * 1e-6
