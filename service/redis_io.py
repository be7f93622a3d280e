"""The live service's keys in Redis and the few atomic steps it takes on them (the calls
themselves are service.store's).

Keys (``P`` is the prefix, default ``galaxy``; SPEC.md section 5 fixes the first three):

    P:ships                    stream: every transition, rejection, retirement and autopilot
                               report (trimmed: approximate MAXLEN, --events-maxlen); on a
                               Redis Cluster one per shard, P:ships:{k} (shard_events)
    P:commands:{k}             stream: the commands for shard k's ships (a client picks k by
                               service.commands.shard_of), read by shard k's consumer group;
                               trimmed to what is not yet acknowledged
    P:commands                 stream (SPEC.md section 5): commands routed to P:commands:{k} by
                               the worker that owns shard 0, atomically (ROUTE; not on a
                               Redis Cluster, where ROUTE's keys span slots)
    P:ship:{ship_id}           hash: state, surface_contact_state, landed_body_name, tick, ...
    P:telemetry                stream, capped: Telemetry samples (proto/service.proto)
    P:service:config           hash: the shard count and the scene every worker shares
    P:service:workers          sorted set: live workers, scored by when their heartbeat expires
    P:shard:{k}:owner          string with a time-out: the worker that owns shard k (its lease)
    P:shard:{k}:epoch          "N:worker": the Nth take of shard k, and who took it (never
                               expires): a worker whose lease lapsed while nobody took the shard
                               holds the same epoch and goes on; a new owner makes a new one
    P:shard:{k}:from           "epoch tick": the tick the latest epoch went on from (what Redis
                               held when it took the shard): a worker that lost the shard marks
                               its flight log superseded after it (superseded_after_tick)
    P:shard:{k}:results        stream, entry ``{tick}-1`` a tick that applied commands: each
                               entry's result (applied, rejected) by stream and entry id
                               (bounded: --results-maxlen)
    P:shard:{k}:checkpoint     ShardCheckpoint (proto/service.proto): the shard at a tick
    P:shard:{k}:journal        stream, entry ``{tick}-1``: the requests applied at that tick
    P:shard:{k}:journaled      the last tick journaled (a journal trimmed by a checkpoint keeps it)
    P:shard:{k}:specs          hash: ship id -> [join tick, its table] (JSON), the shard's ships
                               (a retired ship's removed by the first checkpoint after it left)
    P:shard:{k}:params         hash: ship id -> its parameter record (SHIP_DTYPE bytes), written
                               once when it joins: checkpoints carry only what changes
    P:worker:{id}:stats        hash with a time-out: the worker's figures (its health key)
    P:shard:{k}:published      how many entries shard k has put on P:ships (its high-water mark)
    P:shard:{k}:tick           the last tick whose entries are on P:ships

No coordinator: a worker owns a shard while it holds the shard's lease (TAKE: SET NX PX, and a new
epoch; renewed every lease / 4), and every write that must come from the owner alone (journal,
checkpoint, events) is a Lua script that first checks the shard's epoch (``FENCE``), so a worker
that lost the shard (paused, cut off) cannot write over its successor, and a worker whose lease
merely lapsed (Redis paused past it, nobody took the shard) takes it back and goes on. A shard
whose epoch is gone (Redis restarted empty) is answered -3: its owner writes back what it holds. Events are numbered per shard; PUBLISH adds only those above the
shard's mark, so re-sending after a lost reply, a Redis restart or a takeover adds nothing twice.
"""
from __future__ import annotations

import json
import re
import zlib
from urllib.parse import urlsplit

import numpy as np
import redis
import zstandard
from redis.backoff import NoBackoff
from redis.retry import Retry

from touchdown.proto import service_pb2 as spb
from touchdown.sim.params import SHIP_DTYPE, ShipParams
from touchdown.sim.state import INPUTS_DTYPE, STATE_DTYPE, Inputs, State

#: 2: no parameter records (P:shard:{k}:params), rows zlib-compressed (0.6.0); 3: rows zstd-
#: compressed (a tenth of zlib's time). Format 2 is still read (a service upgraded in place).
CHECKPOINT_FORMAT = 3
READABLE_FORMATS = (2, 3)
CHECKPOINT_ZSTD_LEVEL = 1
DTYPES = json.dumps([str(d.descr) for d in (SHIP_DTYPE, STATE_DTYPE, INPUTS_DTYPE)])


class Keys:
    def __init__(self, prefix: str = "galaxy", events: str | None = None,
                 commands: str | None = None, cluster: bool = False):
        self.prefix = prefix
        self.cluster = cluster
        self.events = events or f"{prefix}:ships"
        self.commands = commands or f"{prefix}:commands"
        self.telemetry = f"{prefix}:telemetry"
        self.config = f"{prefix}:service:config"
        self.workers = f"{prefix}:service:workers"

    def ship(self, ship_id: str) -> str:
        return f"{self.prefix}:ship:{ship_id}"

    def shard_events(self, k: int) -> str:
        """Where shard k publishes: the one event stream ``P:ships``, or on a Redis Cluster
        shard k's own ``P:ships:{k}`` (PUBLISH writes it with the shard's mark, so it must be
        in the shard's slot)."""
        return f"{self.events}:{{{k}}}" if self.cluster else self.events

    def all_events(self, shards: int) -> list[str]:
        """Every event stream of a service of ``shards`` shards (one, or one per shard)."""
        return [self.shard_events(k) for k in range(shards)] if self.cluster else [self.events]

    def shard_commands(self, k: int) -> str:
        """Shard k's command stream (in a Redis Cluster, in the slot of shard k's keys)."""
        return f"{self.commands}:{{{k}}}"

    def stats(self, worker: str) -> str:
        return f"{self.prefix}:worker:{worker}:stats"

    def shard_results(self, k: int) -> str:
        """Shard k's results stream: each command entry applied or rejected, by tick."""
        return self.shard(k, "results")

    def shard(self, k: int, what: str) -> str:
        """``what``: owner, epoch, checkpoint, journal, specs, params, published, tick or
        results."""
        return f"{self.prefix}:shard:{{{k}}}:{what}"  # {k}: a Redis Cluster hash tag

    @staticmethod
    def group(k: int) -> str:
        return f"touchdown-shard-{k}"

    ROUTER = "touchdown-router"


SCHEMES = ("redis", "rediss", "unix")


def redact(url: str) -> str:
    """``url`` with its password (and a ``password=`` query value) replaced by ``***``: what
    every message shows of a Redis URL."""
    try:
        parts = urlsplit(url)
    except ValueError:
        return "<a Redis URL that does not parse>"
    netloc = parts.netloc
    if "@" in netloc:
        cred, host = netloc.rsplit("@", 1)
        user = cred.split(":", 1)[0] if ":" in cred else ""
        netloc = f"{user}:***@{host}" if ":" in cred else f"***@{host}"
    query = re.sub(r"(?i)(password=)[^&]*", r"\1***", parts.query)
    out = f"{parts.scheme}://{netloc}{parts.path}"
    return out + (f"?{query}" if query else "")


def scrub(text: str, *secrets: str | None) -> str:
    """One line of an error's text with every secret in it replaced by ``***``."""
    line = (str(text).splitlines() or [""])[0]
    for secret in secrets:
        if secret:
            line = line.replace(secret, "***")
    return line


def password_of(url: str) -> str | None:
    try:
        return urlsplit(url).password
    except ValueError:
        return None


def connect(url: str, password: str | None = None, timeout: float = 2.0,
            cluster: bool = False) -> redis.Redis:
    """A client that fails fast: no retries (redis-py's default retries for seconds, which
    would stall the tick loop; the loop retries by itself) and short time-outs. ValueError
    (naming the scheme, never the URL) for a URL that is not a Redis one. ``cluster``: a
    ``RedisCluster`` reached through the node of ``url`` (it learns the others from it; a
    refused or lost connection re-reads the slot map, then fails like a single Redis)."""
    scheme = url.split("://", 1)[0].lower() if "://" in url else ""
    if scheme not in (("redis", "rediss") if cluster else SCHEMES):
        raise ValueError(f"not a Redis URL: scheme {scheme or 'missing'!r} (redis://, "
                         f"rediss://{'' if cluster else ' or unix://'})")
    extra = {"password": password} if password is not None else {}
    if cluster:
        from redis.cluster import RedisCluster
        return RedisCluster.from_url(url, socket_connect_timeout=min(0.5, timeout),
                                     socket_timeout=timeout, retry=Retry(NoBackoff(), 0),
                                     health_check_interval=0, **extra)
    return redis.Redis.from_url(url, socket_connect_timeout=min(0.5, timeout),
                                socket_timeout=timeout, retry=Retry(NoBackoff(), 0),
                                health_check_interval=0, **extra)


#: The fence every owner-only script begins with: KEYS[1] the shard's owner key, KEYS[2] its epoch
#: key; ARGV[1] the worker, ARGV[2] its epoch ("N:worker", from TAKE), ARGV[3] the lease in ms.
#: 1: this worker's (a lapsed lease taken back: nobody took the shard since), -1: another worker's
#: (a new epoch), -3: the epoch is gone (Redis lost the shard's state: restarted empty).
FENCE = """
local function fence()
  local e = redis.call('GET', KEYS[2])
  if not e then return -3 end
  if e ~= ARGV[2] then return -1 end
  local o = redis.call('GET', KEYS[1])
  if o == ARGV[1] then return 1 end
  if o then return -1 end
  redis.call('SET', KEYS[1], ARGV[1], 'PX', ARGV[3])
  return 1
end
"""


def fenced(body: str) -> str:
    """A script whose body runs only if ``fence()`` says the shard is this worker's (else it
    returns what fence() said); its own KEYS begin at 3 and its ARGV at 4."""
    return FENCE + "local f = fence()\nif f ~= 1 then return f end\n" + body


#: TAKE: a free shard's lease, and a new epoch "N:worker". KEYS owner, epoch; ARGV worker, lease
#: ms. Returns [the epoch, Redis's TIME (seconds, microseconds)], or nil (taken by another). The
#: time orders a shard's flight logs where the epoch's number cannot: Redis started from an
#: older snapshot hands out a number again. (TIME last: before Redis 7, a script may not write
#: after a non-deterministic command.)
TAKE = """
if not redis.call('SET', KEYS[1], ARGV[1], 'NX', 'PX', ARGV[2]) then return false end
local e = redis.call('GET', KEYS[2])
local n = 0
if e then n = tonumber(string.match(e, '^(%d+):')) or 0 end
local mine = tostring(n + 1) .. ':' .. ARGV[1]
redis.call('SET', KEYS[2], mine)
local t = redis.call('TIME')
return {mine, t[1], t[2]}
"""

#: Shard k's entries for the event stream, above its mark: KEYS owner, epoch, mark, events, tick;
#: ARGV worker, epoch, lease ms, the tick, maxlen (0: none), the mark the worker last saw Redis
#: confirm, then per entry: number, field count, fields... Returns how many were added, or -5
#: (nothing written) if the mark is below what the worker saw confirmed: Redis lost writes (a
#: failover, an older snapshot), which the worker writes again first (no gap in seq).
PUBLISH = fenced("""
local mark = tonumber(redis.call('GET', KEYS[3]) or '-1')
if mark < tonumber(ARGV[6]) then return -5 end
local i, added = 7, 0
while i <= #ARGV do
  local n, nf = tonumber(ARGV[i]), tonumber(ARGV[i + 1])
  if n > mark then
    local args = {}
    for j = 0, 2 * nf - 1 do args[#args + 1] = ARGV[i + 2 + j] end
    if ARGV[5] ~= '0' then
      redis.call('XADD', KEYS[4], 'MAXLEN', '~', ARGV[5], '*', unpack(args))
    else
      redis.call('XADD', KEYS[4], '*', unpack(args))
    end
    mark, added = n, added + 1
  end
  i = i + 2 + 2 * nf
end
redis.call('SET', KEYS[3], mark)
if ARGV[4] ~= '-1' then redis.call('SET', KEYS[5], ARGV[4]) end
return added
""")

#: Ships' hashes, many in one call (a single Redis; a cluster's ship keys are in many slots):
#: KEYS the ships' hashes; ARGV the number of fields F, their F names, then each ship's F values
#: in order. The same HSETs as one command a ship, at a third of the client's work and half the
#: round trip's (a fleet touching down writes hundreds of hashes a tick; a new shard every ship's).
HASHES = """
local nf = tonumber(ARGV[1])
local j = 2 + nf
local args = {}
for i = 1, #KEYS do
  for f = 1, nf do
    args[2 * f - 1] = ARGV[1 + f]
    args[2 * f] = ARGV[j]
    j = j + 1
  end
  redis.call('HSET', KEYS[i], unpack(args, 1, 2 * nf))
end
return #KEYS
"""

#: The requests a tick applies, journaled before the tick applies them, with their command
#: entries acknowledged, then the command stream trimmed below its oldest unacknowledged entry
#: (acknowledged commands only): KEYS owner, epoch, journal, the shard's commands, the last
#: journaled tick; ARGV worker, epoch, lease ms, group, journal id, payload ('' = nothing to
#: journal), the journal ids (comma-separated; '' none) of writes whose reply never came and whose
#: requests this one carries instead (removed if they are there, in the same step, after the
#: XADD: a refused XADD leaves everything as it was), the last tick the worker saw journaled (-1
#: none), the tick, ids... Returns 1; -4 if the journal already holds a later tick; -5 if it
#: lacks a tick the worker saw journaled (Redis lost writes: written again first); nothing is
#: written or acknowledged on either.
JOURNAL = fenced("""
if tonumber(redis.call('GET', KEYS[5]) or '-1') < tonumber(ARGV[8]) then return -5 end
if ARGV[6] ~= '' then
  local ok = redis.pcall('XADD', KEYS[3], ARGV[5], 'requests', ARGV[6])
  if type(ok) == 'table' and ok.err then
    if not string.find(ok.err, 'equal or smaller') then return redis.error_reply(ok.err) end
    -- a re-send of this very entry (its reply lost) is fine; anything else is not
    if #redis.call('XRANGE', KEYS[3], ARGV[5], ARGV[5]) == 0 then return -4 end
  end
end
for id in string.gmatch(ARGV[7], '[^,]+') do
  if id ~= ARGV[5] then redis.call('XDEL', KEYS[3], id) end
end
if ARGV[6] ~= '' and tonumber(redis.call('GET', KEYS[5]) or '-1') < tonumber(ARGV[9]) then
  redis.call('SET', KEYS[5], ARGV[9])
end
if #ARGV > 9 then
  redis.call('XACK', KEYS[4], ARGV[4], unpack(ARGV, 10))
  local p = redis.call('XPENDING', KEYS[4], ARGV[4])
  local floor = ARGV[#ARGV]
  if p[1] > 0 then floor = p[2] end
  redis.call('XTRIM', KEYS[4], 'MINID', '~', floor)
end
return 1
""")

#: A tick's results (what each command entry it applied came to) at id ``{tick}-1``, once (a
#: re-send, or a successor re-stepping the tick, adds nothing): KEYS results; ARGV id, maxlen,
#: tick, results JSON. Returns 1 added, 0 there already.
RESULTS = """
local ok = redis.pcall('XADD', KEYS[1], 'MAXLEN', '~', ARGV[2], ARGV[1], 'tick', ARGV[3],
                       'results', ARGV[4])
if type(ok) == 'table' and ok.err then
  if string.find(ok.err, 'equal or smaller') then return 0 end
  return redis.error_reply(ok.err)
end
return 1
"""

#: Entries of the shared command stream moved to their shards' streams and acknowledged, in one
#: step (nothing routed twice, nothing lost): KEYS source, then shard 0..S-1's streams; ARGV
#: group, the router (consumer), then per entry: id, shard, field count, fields...
ROUTED = "routed_from"  # the field ROUTE adds: the entry's id on the shared stream
ROUTE = """
local ROUTED = 'routed_from'
local i, moved, last = 3, 0, nil
while i <= #ARGV do
  local id, k, nf = ARGV[i], tonumber(ARGV[i + 1]), tonumber(ARGV[i + 2])
  -- only an entry still pending to this router: another that claimed it may have moved it
  if #redis.call('XPENDING', KEYS[1], ARGV[1], id, id, 1, ARGV[2]) == 1 then
    local args = {}
    for j = 0, 2 * nf - 1 do args[#args + 1] = ARGV[i + 3 + j] end
    if nf > 0 then redis.call('XADD', KEYS[k + 2], '*', ROUTED, id, unpack(args)) end
    redis.call('XACK', KEYS[1], ARGV[1], id)
    moved = moved + 1
  end
  last = id
  i = i + 3 + 2 * nf
end
if last then
  local p = redis.call('XPENDING', KEYS[1], ARGV[1])
  local floor = last
  if p[1] > 0 then floor = p[2] end
  redis.call('XTRIM', KEYS[1], 'MINID', '~', floor)
end
return moved
"""

#: KEYS owner, epoch, checkpoint, journal, published mark, specs, params; ARGV worker, epoch,
#: lease ms, blob, the checkpoint's tick (journal entries before it are dropped: the checkpoint
#: holds what they did), the entries the shard has emitted (refused, -2, unless all of them are
#: out: a successor starts counting there, and would never send the missing ones), then the
#: ships that left before the checkpoint (their specs and parameters are dropped)
CHECKPOINT = fenced("""
if tonumber(redis.call('GET', KEYS[5]) or '-1') < tonumber(ARGV[6]) - 1 then return -2 end
redis.call('SET', KEYS[3], ARGV[4])
redis.call('XTRIM', KEYS[4], 'MINID', ARGV[5])
if #ARGV > 6 then
  redis.call('HDEL', KEYS[6], unpack(ARGV, 7))
  redis.call('HDEL', KEYS[7], unpack(ARGV, 7))
end
return 1
""")

#: KEYS the owner and epoch keys of the shards the worker holds, in pairs; ARGV worker, lease
#: ms, then each shard's epoch. Per shard: 1 renewed (or a lapsed lease taken back: nobody took
#: it), 0 another's, -3 its epoch gone (Redis lost the shard's state).
RENEW = """
local out = {}
for i = 1, #KEYS / 2 do
  local owner, epoch = KEYS[2 * i - 1], KEYS[2 * i]
  local e = redis.call('GET', epoch)
  if not e then out[i] = -3
  elseif e ~= ARGV[2 + i] then out[i] = 0
  else
    local o = redis.call('GET', owner)
    if o == ARGV[1] then redis.call('PEXPIRE', owner, ARGV[2]); out[i] = 1
    elseif not o then redis.call('SET', owner, ARGV[1], 'PX', ARGV[2]); out[i] = 1
    else out[i] = 0 end
  end
end
return out
"""

#: KEYS owner, epoch; ARGV worker, epoch
RELEASE = """
if redis.call('GET', KEYS[2]) == ARGV[2] and redis.call('GET', KEYS[1]) == ARGV[1] then
  return redis.call('DEL', KEYS[1])
end
return 0
"""

#: A shard's keys written back by the worker that holds it, after Redis lost them (restarted
#: empty, or a failover lost its last writes): KEYS owner, epoch, mark, tick; ARGV worker, its
#: epoch, lease ms, the mark (the last entry number out), the tick Redis records. Refused (-1)
#: if another worker has taken the shard meanwhile (a new epoch).
RESTORE = """
local e = redis.call('GET', KEYS[2])
if e and e ~= ARGV[2] then return -1 end
local o = redis.call('GET', KEYS[1])
if o and o ~= ARGV[1] then return -1 end
redis.call('SET', KEYS[2], ARGV[2])
redis.call('SET', KEYS[1], ARGV[1], 'PX', ARGV[3])
redis.call('SET', KEYS[3], ARGV[4])
redis.call('SET', KEYS[4], ARGV[5])
return 1
"""

#: What Redis holds of a shard, for a worker to compare with what it wrote: KEYS epoch, mark,
#: tick, the last journaled tick. Returns [epoch or false, mark, tick, last journaled tick].
STATE = """
return {redis.call('GET', KEYS[1]), redis.call('GET', KEYS[2]) or '-1',
        redis.call('GET', KEYS[3]) or '-1', redis.call('GET', KEYS[4]) or '-1'}
"""


def checkpoint_blob(k: int, shards: int, world, autoland, published: int) -> bytes:
    """The shard's state and inputs in force at its tick (zstd, a fast level: a fleet at rest
    packs small); the parameters are in P:shard:{k}:params, sent once."""
    return checkpoint_later(k, shards, world, autoland, published)()


def checkpoint_later(k: int, shards: int, world, autoland, published: int):
    """``checkpoint_blob`` in two parts: the shard's records copied now (a few milliseconds for
    tens of thousands of ships), and a function that compresses and packs them, to run on
    another thread (zstd lets go of the GIL while it works): the tick pays for the copy only."""
    w = world
    state = np.ascontiguousarray(w.state.rows).tobytes()
    inputs = np.ascontiguousarray(w.inputs.rows).tobytes()
    ship_ids, player_ids = w.ship_ids, w.params.ships.player_id
    tick, autoland = w.tick, list(autoland)

    def pack() -> bytes:
        z = zstandard.ZstdCompressor(level=CHECKPOINT_ZSTD_LEVEL)
        return spb.ShardCheckpoint(
            format=CHECKPOINT_FORMAT, shard=k, shards=shards, tick=tick,
            ship_ids=ship_ids, player_ids=player_ids, state_rows=z.compress(state),
            input_rows=z.compress(inputs), dtypes=DTYPES, autoland=autoland,
            published=published).SerializeToString()
    return pack


def read_checkpoint(blob: bytes) -> tuple[spb.ShardCheckpoint, State, Inputs]:
    """The checkpoint and its arrays (format 3, zstd; or 2, zlib, as 0.6.0 wrote them);
    ValueError if it is not one this code can read."""
    cp = spb.ShardCheckpoint.FromString(blob)
    if cp.format not in READABLE_FORMATS or cp.dtypes != DTYPES:
        raise ValueError("a checkpoint of another version of touchdown (format or records "
                         "differ)")
    n = len(cp.ship_ids)
    arrays = []
    for data, dt in ((cp.state_rows, STATE_DTYPE), (cp.input_rows, INPUTS_DTYPE)):
        want = n * dt.itemsize
        try:
            if cp.format == 2:
                raw = zlib.decompressobj().decompress(data, want + 1)
            else:
                with zstandard.ZstdDecompressor().stream_reader(data) as zr:  # bounded
                    raw = zr.read(want + 1) if want else b""
        except (zlib.error, zstandard.ZstdError):
            raise ValueError("a checkpoint's records do not decompress") from None
        if len(raw) != want:
            raise ValueError("a checkpoint's records do not match its ship count")
        arrays.append(np.frombuffer(raw, dt).copy())
    return cp, State(rows=arrays[0], tick=int(cp.tick)), Inputs(rows=arrays[1])


def ship_params(cp: spb.ShardCheckpoint, rows: list) -> ShipParams:
    """The checkpoint's ships' parameters from P:shard:{k}:params (HMGET in its ship order)."""
    if any(r is None or len(r) != SHIP_DTYPE.itemsize for r in rows):
        missing = [sid for sid, r in zip(cp.ship_ids, rows) if r is None]
        raise ValueError(f"the parameters of ship(s) {', '.join(missing[:3])} are missing")
    data = np.frombuffer(b"".join(rows), SHIP_DTYPE).copy()
    return ShipParams(rows=data, ship_id=tuple(cp.ship_ids), player_id=tuple(cp.player_ids))


def flat_entries(entries: list[tuple[int, dict]]) -> list:
    """PUBLISH's ARGV tail for ``entries`` (number, fields)."""
    out: list = []
    for n, fields in entries:
        out += [n, len(fields)]
        for k, v in fields.items():
            out += [k, v]
    return out
