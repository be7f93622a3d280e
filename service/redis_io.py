"""The live service's keys in Redis and the few atomic steps it takes on them.

Keys (``P`` is the prefix, default ``galaxy``; SPEC.md section 5 fixes the first three):

    P:ships                    stream: every transition, rejection and autopilot report
    P:commands                 stream: the players' commands, read by one consumer group per shard
    P:ship:{ship_id}           hash: state, surface_contact_state, landed_body_name, tick, ...
    P:telemetry                stream, capped: Telemetry samples (proto/service.proto)
    P:service:config           hash: the shard count and the scene every worker shares
    P:service:workers          sorted set: live workers, scored by when their heartbeat expires
    P:shard:{k}:owner          string with a time-out: the worker that owns shard k (its lease)
    P:shard:{k}:checkpoint     ShardCheckpoint (proto/service.proto): the shard at a tick
    P:shard:{k}:journal        stream, entry ``{tick}-1``: the requests applied at that tick
    P:shard:{k}:specs          hash: ship id -> its table (JSON), every ship ever in the shard
    P:shard:{k}:published      how many entries shard k has put on P:ships (its high-water mark)
    P:shard:{k}:tick           the last tick whose entries are on P:ships

No coordinator: a worker owns a shard while it holds the shard's lease (SET NX PX, renewed each
tick), and every write that must come from the owner alone (journal, checkpoint, events) is a Lua
script that first checks the lease, so a worker that lost its lease (paused, cut off) cannot
write over its successor. Events are numbered per shard; PUBLISH adds only those above the
shard's mark, so re-sending after a lost reply, a Redis restart or a takeover adds nothing twice.
"""
from __future__ import annotations

import json

import numpy as np
import redis
from redis.backoff import NoBackoff
from redis.retry import Retry

from proto import service_pb2 as spb
from sim.params import SHIP_DTYPE, ShipParams
from sim.state import INPUTS_DTYPE, STATE_DTYPE, Inputs, State

CHECKPOINT_FORMAT = 1
DTYPES = json.dumps([str(d.descr) for d in (SHIP_DTYPE, STATE_DTYPE, INPUTS_DTYPE)])


class Keys:
    def __init__(self, prefix: str = "galaxy", events: str | None = None,
                 commands: str | None = None):
        self.prefix = prefix
        self.events = events or f"{prefix}:ships"
        self.commands = commands or f"{prefix}:commands"
        self.telemetry = f"{prefix}:telemetry"
        self.config = f"{prefix}:service:config"
        self.workers = f"{prefix}:service:workers"

    def ship(self, ship_id: str) -> str:
        return f"{self.prefix}:ship:{ship_id}"

    def shard(self, k: int, what: str) -> str:
        """``what``: owner, checkpoint, journal, specs, published or tick."""
        return f"{self.prefix}:shard:{{{k}}}:{what}"  # {k}: a Redis Cluster hash tag

    @staticmethod
    def group(k: int) -> str:
        return f"touchdown-shard-{k}"


def connect(url: str) -> redis.Redis:
    """A client that fails fast: no retries (redis-py's default retries for seconds, which
    would stall the tick loop; the loop retries by itself) and short time-outs."""
    return redis.Redis.from_url(url, socket_connect_timeout=0.5, socket_timeout=2.0,
                                retry=Retry(NoBackoff(), 0), health_check_interval=0)


#: Shard k's entries for the event stream, above its mark: KEYS owner, mark, events, tick;
#: ARGV worker, the tick, maxlen (0: none), then per entry: number, field count, fields...
PUBLISH = """
if redis.call('GET', KEYS[1]) ~= ARGV[1] then return -1 end
local mark = tonumber(redis.call('GET', KEYS[2]) or '-1')
local i, added = 4, 0
while i <= #ARGV do
  local n, nf = tonumber(ARGV[i]), tonumber(ARGV[i + 1])
  if n > mark then
    local args = {}
    for j = 0, 2 * nf - 1 do args[#args + 1] = ARGV[i + 2 + j] end
    if ARGV[3] ~= '0' then
      redis.call('XADD', KEYS[3], 'MAXLEN', '~', ARGV[3], '*', unpack(args))
    else
      redis.call('XADD', KEYS[3], '*', unpack(args))
    end
    mark, added = n, added + 1
  end
  i = i + 2 + 2 * nf
end
redis.call('SET', KEYS[2], mark)
if ARGV[2] ~= '-1' then redis.call('SET', KEYS[4], ARGV[2]) end
return added
"""

#: The requests applied at a tick, then their command entries acknowledged: KEYS owner,
#: journal, commands; ARGV worker, group, journal id, payload ('' = nothing to journal), ids...
JOURNAL = """
if redis.call('GET', KEYS[1]) ~= ARGV[1] then return -1 end
if ARGV[4] ~= '' then
  local ok = redis.pcall('XADD', KEYS[2], ARGV[3], 'requests', ARGV[4])
  if type(ok) == 'table' and ok.err and not string.find(ok.err, 'equal or smaller') then
    return redis.error_reply(ok.err)
  end
end
if #ARGV > 4 then redis.call('XACK', KEYS[3], ARGV[2], unpack(ARGV, 5)) end
return 1
"""

#: KEYS owner, checkpoint, journal, published mark; ARGV worker, blob, the checkpoint's tick
#: (journal entries before it are dropped: the checkpoint holds what they did), the entries
#: the shard has emitted (refused, -2, unless all of them are out: a successor starts counting
#: there, and would never send the missing ones)
CHECKPOINT = """
if redis.call('GET', KEYS[1]) ~= ARGV[1] then return -1 end
if tonumber(redis.call('GET', KEYS[4]) or '-1') < tonumber(ARGV[4]) - 1 then return -2 end
redis.call('SET', KEYS[2], ARGV[2])
redis.call('XTRIM', KEYS[3], 'MINID', ARGV[3])
return 1
"""

#: KEYS the owner keys of the shards the worker holds; ARGV worker, lease ms.
#: Returns 1 for each lease renewed, 0 for each lost.
RENEW = """
local out = {}
for i, key in ipairs(KEYS) do
  if redis.call('GET', key) == ARGV[1] then
    redis.call('PEXPIRE', key, ARGV[2]); out[i] = 1
  else out[i] = 0 end
end
return out
"""

#: KEYS owner; ARGV worker
RELEASE = """
if redis.call('GET', KEYS[1]) == ARGV[1] then return redis.call('DEL', KEYS[1]) end
return 0
"""


def checkpoint_blob(k: int, shards: int, world, scene_json: str, autoland, published: int
                    ) -> bytes:
    w = world
    return spb.ShardCheckpoint(
        format=CHECKPOINT_FORMAT, shard=k, shards=shards, tick=w.tick, scene_json=scene_json,
        ship_ids=list(w.ship_ids), player_ids=list(w.params.ships.player_id),
        ship_rows=np.ascontiguousarray(w.params.ships.rows).tobytes(),
        state_rows=np.ascontiguousarray(w.state.rows).tobytes(),
        input_rows=np.ascontiguousarray(w.inputs.rows).tobytes(), dtypes=DTYPES,
        autoland=list(autoland), published=published).SerializeToString()


def read_checkpoint(blob: bytes) -> tuple[spb.ShardCheckpoint, ShipParams, State, Inputs]:
    """The checkpoint and its arrays; ValueError if it is not one this code wrote."""
    cp = spb.ShardCheckpoint.FromString(blob)
    if cp.format != CHECKPOINT_FORMAT or cp.dtypes != DTYPES:
        raise ValueError("a checkpoint of another version of touchdown (format or records "
                         "differ)")
    n = len(cp.ship_ids)
    arrays = []
    for data, dt in ((cp.ship_rows, SHIP_DTYPE), (cp.state_rows, STATE_DTYPE),
                     (cp.input_rows, INPUTS_DTYPE)):
        if len(data) != n * dt.itemsize:
            raise ValueError("a checkpoint's records do not match its ship count")
        arrays.append(np.frombuffer(data, dt).copy())
    ships = ShipParams(rows=arrays[0], ship_id=tuple(cp.ship_ids),
                       player_id=tuple(cp.player_ids))
    return cp, ships, State(rows=arrays[1], tick=int(cp.tick)), Inputs(rows=arrays[2])


def flat_entries(entries: list[tuple[int, dict]]) -> list:
    """PUBLISH's ARGV tail for ``entries`` (number, fields)."""
    out: list = []
    for n, fields in entries:
        out += [n, len(fields)]
        for k, v in fields.items():
            out += [k, v]
    return out
