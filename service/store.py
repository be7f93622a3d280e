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
    lost the group: made again), or the ``error`` Redis answered."""
    k: int
    start: str
    entries: list = field(default_factory=list)
    nogroup: bool = False
    error: Exception | None = None


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

    def take_lease(self, k: int, lease_ms: int) -> bool:
        return bool(self.r.set(self.keys.shard(k, "owner"), self.worker, nx=True, px=lease_ms))

    def holds_lease(self, k: int) -> bool:
        return self.r.get(self.keys.shard(k, "owner")) == self.worker.encode()

    def release(self, k: int) -> None:
        self._script("RELEASE", [self.keys.shard(k, "owner")], [self.worker])

    def lease_keeper(self, timeout: float) -> "LeaseKeeper":
        """A connection of its own for the lease thread."""
        return LeaseKeeper(self, timeout)

    # -- commands ---------------------------------------------------------------------------------
    def read(self, plan: list[tuple[int, str, int]]) -> list[Read]:
        """Each (shard, start id, count): its entries from its consumer group, in one round
        trip (``>``: new ones; an id: this worker's own pending ones after it). A shard whose
        group Redis lost has it made again (``nogroup``)."""
        pipe = self.r.pipeline(transaction=False)
        for k, start, count in plan:
            pipe.xreadgroup(rio.Keys.group(k), self.worker, {self.keys.shard_commands(k): start},
                            count=count)
        replies = pipe.execute(raise_on_error=False)
        out = []
        for (k, start, _count), reply in zip(plan, replies):
            if isinstance(reply, redis.exceptions.ResponseError) and "NOGROUP" in str(reply):
                self.ensure_group(k)  # Redis lost it (restarted without its data)
                out.append(Read(k, start, nogroup=True))
                continue
            if isinstance(reply, Exception):
                out.append(Read(k, start, error=reply))
                continue
            out.append(Read(k, start, [e for _s, es in (reply or []) for e in es]))
        return out

    def read_router(self, start: str, count: int) -> list | None:
        """The shared command stream's entries for the router (None: the group was lost, and
        made again)."""
        try:
            reply = self.r.xreadgroup(rio.Keys.ROUTER, self.worker, {self.keys.commands: start},
                                      count=count)
        except redis.exceptions.ResponseError as exc:
            if "NOGROUP" not in str(exc):
                raise
            self.ensure_group(None)
            return None
        return [e for _s, es in (reply or []) for e in es]

    def route(self, moves: list[tuple[bytes, int, dict]], shards: int) -> int:
        """ROUTE: each (entry id, shard, raw fields) moved to its shard's stream and
        acknowledged, in one script."""
        args: list = [rio.Keys.ROUTER]
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
    def journal(self, k: int, tick: int, requests: list, ids: list[str]) -> bool:
        """JOURNAL: the requests applied at ``tick`` with their entries' acknowledgements, in
        one script; False if the lease is another worker's."""
        payload = json.dumps([r.as_json() for r in requests]) if requests else ""
        ok = self._script("JOURNAL", [self.keys.shard(k, "owner"), self.keys.shard(k, "journal"),
                                      self.keys.shard_commands(k)],
                          [self.worker, rio.Keys.group(k), f"{tick}-1", payload, *ids])
        return ok != -1

    # -- a flush: the events, hashes, specs, parameters, telemetry, checkpoints ------------------
    def flush(self, shards: list[ShardWrites], events_maxlen: int, telemetry_maxlen: int,
              phase=None) -> FlushResult:
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
                self._script("PUBLISH", [keys.shard(k, "owner"), keys.shard(k, "published"),
                                         keys.shard_events(k), keys.shard(k, "tick")],
                             [self.worker, tick, events_maxlen, *rio.flat_entries(chunk)],
                             client=pipe)
                plan.append(("publish", k, len(chunk), tick))
            for sid, fields in w.hashes.items():
                if fields is None:
                    pipe.delete(keys.ship(sid))
                else:
                    pipe.hset(keys.ship(sid), mapping=fields)
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
                             [self.worker, cp.blob, cp.tick, cp.published, *cp.gone],
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
            elif what == "checkpoint" and reply == 1:
                f.checkpointed = True
            elif what == "publish" and not f.lost:
                f.out += n
                f.added += reply
                if tick != -1:
                    f.tick = tick
        return result

    # -- checkpoints ------------------------------------------------------------------------------
    def checkpoint(self, k: int, cp: CheckpointWrite) -> int:
        """CHECKPOINT now (a hand-over, a stop): 1 written, -1 the lease lost, -2 refused (not
        every entry it counts is out)."""
        return self._script("CHECKPOINT", self._checkpoint_keys(k),
                            [self.worker, cp.blob, cp.tick, cp.published, *cp.gone])

    def _checkpoint_keys(self, k: int) -> list[str]:
        return [self.keys.shard(k, w) for w in ("owner", "checkpoint", "journal", "published",
                                                "specs", "params")]

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

    def renew(self, shards: list[int], lease_ms: int) -> list[bool]:
        """RENEW each shard's lease: whether it is still this worker's. One script (a cluster:
        one per shard, each in its slot, pipelined)."""
        if not shards:
            return []
        if self.cluster:
            pipe = self.r.pipeline()
            for k in shards:
                pipe.execute_command("EVAL", rio.RENEW, 1, self.keys.shard(k, "owner"),
                                     self.worker, lease_ms)
            kept = [x[0] for x in pipe.execute()]
        else:
            kept = self.r.eval(rio.RENEW, len(shards),
                               *[self.keys.shard(k, "owner") for k in shards], self.worker,
                               lease_ms)
        return [bool(x) for x in kept]

    def close(self) -> None:
        self.r.close()


def _server_time(r) -> float:
    t = r.time()
    if isinstance(t, dict):  # a cluster client may answer per node
        t = next(iter(t.values()))
    s, us = t
    return s + us * 1e-6
