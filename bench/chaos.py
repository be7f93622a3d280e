"""``touchdown bench chaos``: the live service's promise (SPEC.md section 5; issue 34), checked by
accounting under faults. A gateway writes uniquely-valued commands (spawns of new ships, throttles
of a unique value each, retires, and commands of another player's ship) to the shards' command
streams, as a game's gateway does, while faults are injected into private redis-servers and
worker processes; afterwards every entry Redis accepted is looked for:

- applied: in the flight logs (a spawn's join, a retire's leave, a throttle's value at a tick),
  each file read up to its ``superseded_after_tick`` (what Redis never held of a lost shard);
- rejected: a ``ship.command_rejected`` on the event stream naming the entry (``stream`` and
  ``entry_id``), to its sender (``player_id``); or, unpublished past the sender's cap, in the
  shard's results stream;
- superseded: a throttle for a ship followed by another in the same tick (the results stream
  says so; the flight log records the last of a tick's commands for a ship);

and each must be found exactly once: **lost** (neither), **twice** (applied at two ticks,
rejected twice, or both). The faults (``FAULTS``): a worker SIGKILLed in a burst of spawns, Redis
paused (SIGSTOP) shorter and longer than the lease, Redis killed and restarted from its
append-only file, Redis restarted empty (its data gone: the workers must write back what they
hold), a Redis Cluster master killed with its replica promoted, a shard's slot moved to another
master (a reshard). ``run_case`` runs one; ``chaos`` draws a sequence from a seed.

Everything runs on private redis-servers on free loopback ports, and workers as subprocesses of
``touchdown serve`` (``cli.py``), so that a SIGKILL is a real one. The machine's Redis on 6379
is never touched.
"""
from __future__ import annotations

import json
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import redis

ROOT = Path(__file__).resolve().parents[1]
SHARDS = 4
GATEWAYS = 4  # writers at once
CHECKPOINT_TICKS = 20  # the workers' --checkpoint-every (a checkpoint flushes the flight log)
SPACING_S = 0.25  # a ship's throttles are at least this far apart (see Gateway._throttle)


# -- the gateway --------------------------------------------------------------------------------
@dataclass
class Sent:
    stream: str
    entry_id: str
    cmd: str
    ship_id: str
    player_id: str
    value: str = ""  # a throttle's value (unique)
    sent_at: float = 0.0
    #: the XADD's reply never came (a connection lost with the command sent): the entry may or
    #: may not exist; found once or not at all is right, twice is not
    unknown: bool = False
    #: Redis Cluster with replicas: WAIT found no replica had it (Redis itself may lose it in a
    #: failover; counted apart)
    unreplicated: bool = False
    wrong_player: bool = False  # sent by a player who does not own the ship: must be rejected


class Gateways:
    """``n`` gateways at once (a game's gateway has many writes in flight: at a fault several
    are queued in Redis's sockets), each with its own connection and ship names."""

    def __init__(self, n: int, connect, keys, shards: int, rate: float, seed: int,
                 cluster: bool, wait: bool):
        # on one Redis, half of them write SPEC.md's shared stream P:commands (routed by the
        # owner of shard 0), half the shards' own streams
        self.all = [Gateway(connect, keys, shards, rate / n, seed * 31 + i, "stuvwxyz"[i],
                            cluster, wait, shared=not cluster and i % 2 == 1)
                    for i in range(n)]

    def start(self) -> None:
        for g in self.all:
            g.start()

    @property
    def sent(self) -> list:
        return [s for g in self.all for s in g.sent]

    @property
    def burst(self) -> int:
        return 0

    @burst.setter
    def burst(self, n: int) -> None:
        for g in self.all:
            g.burst = n // len(self.all)

    def halt(self) -> None:
        for g in self.all:
            g.stop_flag.set()
        for g in self.all:
            g.join(timeout=120)

    def is_alive(self) -> bool:
        return any(g.is_alive() for g in self.all)


class Gateway(threading.Thread):
    """Writes commands at ``rate`` entries a second until stopped: each step spawns a new ship,
    throttles two ships spawned before (a unique value each), now and then retires an old ship
    (one not throttled for a while) and has a player command another's ship (which must be
    rejected, to that player). Every entry Redis accepted is noted in ``sent``."""

    def __init__(self, connect, keys, shards: int = SHARDS, rate: float = 150.0,
                 seed: int = 1, tag: str = "c", cluster: bool = False, wait: bool = False,
                 shared: bool = False):
        super().__init__(daemon=True, name="chaos-gateway")
        from touchdown.service.commands import shard_of
        self.shard_of = shard_of
        self.connect = connect  # () -> a Redis client (single) or RedisCluster
        self.keys, self.shards, self.rate = keys, shards, rate
        self.rng = random.Random(seed)
        self.tag = tag
        self.cluster, self.wait, self.shared = cluster, wait, shared
        self.sent: list[Sent] = []
        self.errors = 0
        self.stop_flag = threading.Event()
        self.burst = 0  # spawns to send at once at the next step (a burst)
        self._n = 0
        self._value = 0
        self._ships: list[str] = []  # spawned, not retired
        self._last_throttle: dict[str, float] = {}
        self._born: dict[str, float] = {}
        self._client = None
        self.lock = threading.Lock()

    def run(self) -> None:
        self._client = self.connect()
        period = 3.2 / self.rate  # a step is about 3.2 entries
        due = time.monotonic()
        while not self.stop_flag.is_set():
            now = time.monotonic()
            if now < due:
                time.sleep(min(period, due - now))
                continue
            due = now if now - due > 1.0 else due + period
            self._step()
            if self.burst:
                n, self.burst = self.burst, 0
                for _ in range(n):
                    self._spawn()

    def _step(self) -> None:
        self._spawn()
        for _ in range(2):
            self._throttle()
        if self._n % 10 == 0:
            self._retire()
        if self._n % 15 == 0:
            self._steal()

    def _spawn(self) -> None:
        self._n += 1
        sid = f"{self.tag}{self._n}"
        player = f"p{self._n % 7}"
        spec = json.dumps({"initial": {"altitude": 2.0, "vertical_speed": -1.0}})
        if self._send(sid, {"cmd": "spawn", "ship_id": sid, "player_id": player, "ship": spec}):
            self._ships.append(sid)
            self._born[sid] = time.monotonic()

    def _player(self, sid: str) -> str:
        return f"p{int(sid[len(self.tag):]) % 7}"

    def _throttle(self) -> None:
        """A throttle of a unique value for a ship spawned a second ago or more and not
        throttled for SPACING_S: two throttles for one ship in one tick keep only the last
        (0.7.0: the other was "superseded", nowhere recorded): under a fault they bunch."""
        now = time.monotonic()
        for _ in range(20):
            if not self._ships:
                return
            sid = self.rng.choice(self._ships)
            if (now - self._born.get(sid, now) >= 1.0
                    and now - self._last_throttle.get(sid, -1e9) >= SPACING_S):
                break
        else:
            return
        self._value += 1
        value = f"{self._value / 1e6:.6f}"
        self._last_throttle[sid] = now
        self._send(sid, {"cmd": "throttle", "ship_id": sid, "player_id": self._player(sid),
                         "value": value}, value=value)

    def _retire(self) -> None:
        now = time.monotonic()
        for sid in self._ships[:50]:
            if now - self._last_throttle.get(sid, -1e9) > 5.0 and \
                    now - self._born.get(sid, now) > 2.0:
                self._ships.remove(sid)
                self._send(sid, {"cmd": "retire", "ship_id": sid,
                                 "player_id": self._player(sid)})
                return

    def _steal(self) -> None:
        if not self._ships:
            return
        sid = self.rng.choice(self._ships)
        thief = "mallory"
        self._value += 1
        value = f"{self._value / 1e6:.6f}"
        self._send(sid, {"cmd": "throttle", "ship_id": sid, "player_id": thief,
                         "value": value}, value=value, wrong=True)

    def _send(self, sid: str, fields: dict, value: str = "", wrong: bool = False) -> bool:
        stream = (self.keys.commands if self.shared else
                  self.keys.shard_commands(self.shard_of(sid, self.shards)))
        note = Sent(stream, "", fields["cmd"], sid, fields["player_id"], value,
                    time.monotonic(), wrong_player=wrong)
        for attempt in range(200):
            if self.stop_flag.is_set() and attempt:
                break
            try:
                eid, replicas = self._xadd(stream, fields)
            except (redis.exceptions.ConnectionError, redis.exceptions.TimeoutError):
                # sent, and no reply: the entry may exist. Not sent again (a new entry would
                # be the same command twice); found once or not at all is right
                self.errors += 1
                note.unknown = True
                with self.lock:
                    self.sent.append(note)
                time.sleep(0.2)
                self._refresh()
                return False
            except (redis.exceptions.ClusterDownError, redis.exceptions.RedisClusterException,
                    redis.exceptions.ResponseError):
                self.errors += 1  # refused (MOVED, CLUSTERDOWN, LOADING): not written
                time.sleep(0.2)
                self._refresh()
                continue
            note.entry_id = eid
            note.unreplicated = replicas == 0
            with self.lock:
                self.sent.append(note)
            return True
        return False

    def _xadd(self, stream: str, fields: dict) -> tuple[str, int | None]:
        c = self._client
        if not self.cluster:
            return c.xadd(stream, fields).decode(), None
        # on a cluster, through the slot's master's own client (never re-sent by the cluster
        # client's retries); with replicas, a careful gateway's WAIT on the same connection (it
        # counts the replicas that have this connection's writes)
        node = c.get_node_from_key(stream)
        r = c.get_redis_connection(node)
        pipe = r.pipeline(transaction=False)
        pipe.xadd(stream, fields)
        if self.wait:
            pipe.execute_command("WAIT", 1, 200)
        got = pipe.execute()
        return got[0].decode(), (int(got[1]) if self.wait else None)

    def _refresh(self) -> None:
        try:
            if self.cluster:
                self._client.nodes_manager.initialize()
        except Exception:  # noqa: BLE001  (the cluster may still be electing)
            pass

    def halt(self) -> None:
        self.stop_flag.set()
        self.join(timeout=120)


class Follower(threading.Thread):
    """What a gateway reads as it goes: every event stream and results stream, followed with XREAD
    from the last id seen (through restarts: a stream begun anew has later ids), each event kept
    once by its ``seq`` and each results entry once by its shard and tick, the latest version of
    each: Redis may lose what it held (restarted empty, rolled back), and what was read before is
    kept here, unless written again; a new owner after a rollback writes its own history under
    the same numbers and ticks (the old owner's versions are of ticks its log marks superseded)."""

    def __init__(self, connect, keys, shards: int):
        super().__init__(daemon=True, name="chaos-follower")
        self.connect, self.keys, self.shards = connect, keys, shards
        self.events: dict = {}  # seq -> fields
        self.results: dict = {}  # (shard, tick) -> fields
        self.stop_flag = threading.Event()
        self.last = {s: "0" for s in keys.all_events(shards)}
        self.last.update({keys.shard_results(k): "0" for k in range(shards)})

    def run(self) -> None:
        client = None
        while not self.stop_flag.is_set():
            try:
                if client is None:
                    client = self.connect()
                self.poll(client)
            except (redis.exceptions.RedisError, redis.exceptions.RedisClusterException):
                client = None
                time.sleep(0.2)
            self.stop_flag.wait(0.05)

    def poll(self, client) -> None:
        for stream in list(self.last):
            for entry_id, f in client.xrange(stream, f"({self.last[stream]}" if
                                             self.last[stream] != "0" else "-", count=2000):
                self.last[stream] = entry_id.decode()
                d = _decode(f)
                # the latest version of each seq and each tick's results: a new owner after a
                # rollback publishes its own history under the numbers and ticks the old one
                # used (Redis lost them); the first version kept hid its rejections (chaos run
                # of 2026-11-27: a rejection at seq 0:508 behind the old owner's 0:508)
                if "seq" in d:
                    self.events[d["seq"]] = d
                elif "results" in d:
                    k = int(stream.split("{")[1].split("}")[0])
                    self.results[(k, d["tick"])] = d

    def halt(self, client) -> None:
        self.stop_flag.set()
        self.join(timeout=30)
        try:
            self.poll(client)
        except (redis.exceptions.RedisError, redis.exceptions.RedisClusterException):
            pass


# -- accounting ---------------------------------------------------------------------------------
@dataclass
class Verdict:
    sent: int = 0
    applied: int = 0
    rejected: int = 0
    superseded: int = 0
    lost: list = field(default_factory=list)
    twice: list = field(default_factory=list)
    unknown_found: int = 0  # sends without a reply, found (once)
    unreplicated: int = 0
    wrong_recipient: list = field(default_factory=list)  # a rejection not to its sender
    pending_left: int = 0
    pending_detail: list = field(default_factory=list)
    tracebacks: list = field(default_factory=list)  # workers that printed one
    seq_gaps: list = field(default_factory=list)  # (shard, detail): a hole or a repeat in seq
    unverified: list = field(default_factory=list)  # flight logs replay --verify refused
    first_ticks: list = field(default_factory=list)  # s from taking a lease to its first tick
    #: sent in the second before Redis was restarted empty and not found: lost with Redis's data
    lost_with_redis: int = 0
    #: a worker's lines saying a shard went back (lost to another worker, or started anew)
    backwards: list = field(default_factory=list)
    #: what flight logs held past the world's run (logs.shards): (file, tick, what)
    not_kept: list = field(default_factory=list)

    def line(self) -> str:
        maybe = sum(1 for w in self.lost if w[-1] == "a later throttle of the ship applied")
        return (f"sent {self.sent:,}: applied {self.applied:,}, rejected {self.rejected:,}, "
                f"superseded {self.superseded:,}; LOST {len(self.lost)} ({maybe} followed by a "
                f"later throttle of the same ship that was applied), TWICE "
                f"{len(self.twice)}; rejections to the wrong player {len(self.wrong_recipient)}; "
                f"left pending {self.pending_left}; seq holes {len(self.seq_gaps)}"
                + (f"; logs not verifying {len(self.unverified)}" if self.unverified else "")
                + (f"; lost with Redis's data {self.lost_with_redis}" if self.lost_with_redis
                   else "")
                + (f"; shards gone back {len(self.backwards)}" if self.backwards else "")
                + (f"; applied in histories not kept {len(self.not_kept)}" if self.not_kept
                   else ""))

    @property
    def ok(self) -> bool:
        """Nothing lost, nothing twice, every rejection to its sender, nothing left pending, no
        traceback (a shard moving to another worker may be right: a worker that saw no fault
        takes a shard whose lease Redis lost; the tests assert ``backwards`` where it is not)."""
        return not (self.lost or self.twice or self.wrong_recipient or self.pending_left
                    or self.tracebacks or self.seq_gaps or self.unverified)


def _files(folder: Path) -> list[Path]:
    return sorted(folder.rglob("*.mcap")) + sorted(folder.rglob("*.partial"))


def from_logs(folder: Path, dropped: list | None = None) -> tuple[dict, dict, dict]:
    """Across every flight log, each read for the ticks that are the world's (logs.shards: up
    to its ``superseded_after_tick`` and to the first tick of any later take of its shard): the
    ticks at which each ship joined, left, and each throttle value was given (value -> ship ->
    ticks). ``dropped``: given a list, what the files held past their ``until`` is appended to
    it (file, tick, what), as evidence that a fault made a history the world did not keep."""
    from touchdown.logs.reader import LogReader
    from touchdown.logs.shards import shard_file, world_until
    read = []
    for path in _files(folder):
        if path.suffix == ".partial" and _empty_start(path):
            continue  # (begun by a worker SIGKILLed before it wrote anything)
        try:
            with LogReader(path) as r:
                read.append((shard_file(r, path), r.timeline()))
        except Exception as exc:  # noqa: BLE001  (a file cut by a SIGKILL: read what is whole)
            print(f"  (a log not read: {path.name}: {type(exc).__name__}: {exc})")
            continue
    until = world_until(f for f, _tl in read)
    joins: dict[str, set] = {}
    leaves: dict[str, set] = {}
    throttles: dict[str, dict[str, set]] = {}
    for f, tl in read:
        upto = until[f.key]
        found = [(sp.tick, "join", sp.ship_id, joins) for sp in tl.spawns if sp.tick >= 0]
        found += [(rt.tick, "leave", rt.ship_id, leaves) for rt in tl.retires]
        for tick, what, ship, into in found:
            if tick < upto:
                into.setdefault(ship, set()).add(tick)
            elif dropped is not None:
                dropped.append((f.key.name, tick, f"{what} {ship}"))
        for c in tl.commands:
            v = f"{c.throttle:.6f}"
            if c.tick < upto:
                throttles.setdefault(v, {}).setdefault(c.ship_id, set()).add(c.tick)
            elif dropped is not None:
                dropped.append((f.key.name, c.tick, f"throttle {c.ship_id} {v}"))
    return joins, leaves, throttles


def verify_logs(folder: Path) -> list:
    """Every flight log's ``replay --verify``: those that do not verify, with the report. A
    ``.partial`` file without even the MCAP magic (a worker SIGKILLed as it began the file) holds
    nothing to verify and is left out."""
    from touchdown.logs import LogError
    from touchdown.replay.verify import verify
    bad = []
    for path in _files(folder):
        if path.suffix == ".partial" and _empty_start(path):
            continue
        try:
            res = verify(str(path))
        except LogError as exc:
            bad.append((path.name, str(exc)[:300]))
            continue
        if res.divergence is not None:
            bad.append((path.name, res.report()[:300]))
    return bad


def _empty_start(path: Path) -> bool:
    from touchdown.logs.safe_read import MAGIC
    with open(path, "rb") as f:
        return f.read(len(MAGIC)) != MAGIC


def _decode(fields: dict) -> dict:
    return {k.decode(): (v.decode("utf-8", "replace") if k != b"proto" else v)
            for k, v in fields.items()}


def read_events(client, keys, shards: int) -> list[dict]:
    out = []
    for stream in keys.all_events(shards):
        for _id, f in client.xrange(stream):
            out.append(_decode(f))
    return out


def read_results(client, keys, shards: int) -> dict:
    """(stream, entry id) -> [(result, tick)] from the shards' results streams (if any)."""
    out: dict = {}
    for k in range(shards):
        key = keys.shard_results(k) if hasattr(keys, "shard_results") else None
        if key is None:
            return out
        for _id, f in client.xrange(key):
            d = _decode(f)
            tick = int(d["tick"])
            for stream, by in json.loads(d["results"]).items():
                for result, ids in by.items():
                    for eid in ids:
                        out.setdefault((stream, eid), []).append((result, tick))
    return out


def _results_of(entries) -> dict:
    out: dict = {}
    for d in entries:
        for stream, by in json.loads(d["results"]).items():
            for result, ids in by.items():
                for eid in ids:
                    out.setdefault((stream, eid), []).append((result, int(d["tick"])))
    return out


def account(sent: list[Sent], folder: Path, client, keys, shards: int,
            wiped: list | None = None, follower: Follower | None = None) -> Verdict:
    """Each entry sent found exactly once: applied in the logs, rejected on the event stream (or
    by the results stream), or superseded. ``follower``: what a gateway read as it went (else
    the streams as they are at the end)."""
    not_kept: list = []
    joins, leaves, throttles = from_logs(folder, not_kept)
    if follower is not None:
        events = list(follower.events.values())
    else:
        events = read_events(client, keys, shards)
    rejected: dict = {}
    for e in events:
        if e.get("event") == "ship.command_rejected":
            # (a version whose rejections do not name the stream: the entry id and the ship,
            # as ids repeat across the shards' streams)
            key = ((e["stream"], e["entry_id"]) if e.get("stream") else
                   (e["entry_id"], e.get("ship_id")))
            rejected.setdefault(key, []).append(e)
    results = read_results(client, keys, shards) if follower is None else \
        _results_of(follower.results.values())
    v = Verdict(not_kept=not_kept)
    for k in range(shards):  # each shard's seq: no hole, no repeat (from the first kept)
        nums = sorted(int(e["seq"].split(":")[1]) for e in events
                      if e.get("seq", "").startswith(f"{k}:"))
        if nums and nums != list(range(nums[0], nums[0] + len(nums))):
            holes = sorted(set(range(nums[0], nums[-1] + 1)) - set(nums))
            v.seq_gaps.append((k, f"{len(nums)} entries {nums[0]}..{nums[-1]}, missing "
                                  f"{holes[:5]}, repeated {len(nums) - len(set(nums))}"))
    later: dict = {}  # (ship, value) -> the next throttle's value sent to the ship
    by_ship: dict = {}
    for s in sorted((s for s in sent if s.cmd == "throttle" and not s.wrong_player),
                    key=lambda s: s.value):
        prev = by_ship.get(s.ship_id)
        if prev is not None:
            later[(s.ship_id, prev)] = s.value
        by_ship[s.ship_id] = s.value
    for s in sent:
        v.sent += 1
        v.unreplicated += s.unreplicated
        rej = rejected.get((s.stream, s.entry_id)) or rejected.get((s.entry_id, s.ship_id)) or []
        res = results.get((s.stream, s.entry_id), [])
        res_rejected = [r for r in res if r[0] == "rejected"]
        superseded = [r for r in res if r[0] == "superseded"]
        if s.cmd == "spawn":
            applied = len(joins.get(s.ship_id, ()))
        elif s.cmd == "retire":
            applied = len(leaves.get(s.ship_id, ()))
        else:
            applied = len(throttles.get(s.value, {}).get(s.ship_id, ()))
        n_rej = max(len(rej), len(res_rejected))
        found = applied + n_rej + len(superseded)
        what = (s.cmd, s.ship_id, s.value, s.stream, s.entry_id, round(s.sent_at, 2))
        if s.unknown:
            if found == 1:
                v.unknown_found += 1
            elif found > 1:
                v.twice.append(what + ("applied", applied, "rejected", n_rej))
            continue
        if found == 0:
            if s.unreplicated:
                continue  # Redis's own loss in a failover, counted apart
            if any(a <= s.sent_at <= b for a, b in wiped or ()):
                v.lost_with_redis += 1
                continue
            nxt = later.get((s.ship_id, s.value))
            if s.cmd == "throttle" and nxt and throttles.get(nxt, {}).get(s.ship_id):
                what = what + ("a later throttle of the ship applied",)
            if res:
                what = what + ("results say", res)
            v.lost.append(what)
        elif found > 1:
            v.twice.append(what + ("applied", applied, "rejected", n_rej,
                                   "superseded", len(superseded)))
        elif applied:
            v.applied += 1
        elif n_rej:
            v.rejected += 1
            for e in rej:
                if e.get("player_id") != s.player_id:
                    v.wrong_recipient.append(what + (e.get("player_id"),))
        else:
            v.superseded += 1
        if s.wrong_player and applied:
            v.twice.append(what + ("a stolen command applied",))
    for stream in [keys.shard_commands(k) for k in range(shards)] + (
            [] if keys.cluster else [keys.commands]):
        try:
            for g in client.xinfo_groups(stream):
                v.pending_left += int(g["pending"])
                if int(g["pending"]):
                    p = client.xpending_range(stream, g["name"], "-", "+", 10)
                    v.pending_detail.append((stream, [(x["message_id"].decode(),
                                                       x["consumer"].decode()) for x in p]))
        except redis.exceptions.ResponseError:
            pass
    return v


# -- the servers and the workers ----------------------------------------------------------------
def _free_port() -> int:
    import socket
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    """A private redis-server on a free port, data in ``folder`` (AOF, fsync always: what it
    acknowledged survives a SIGKILL), which the faults pause, kill and start again."""

    def __init__(self, folder: Path, fsync: str = "always", aof: bool = True):
        self.binary = shutil.which("redis-server")
        if self.binary is None:
            raise RuntimeError("bench chaos needs redis-server on PATH")
        self.folder = folder
        self.fsync = fsync
        self.aof = aof
        self.port = _free_port()
        self.proc: subprocess.Popen | None = None
        self.start()

    @property
    def url(self) -> str:
        return f"redis://127.0.0.1:{self.port}/0"

    def start(self) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        self.proc = subprocess.Popen(
            [self.binary, "--port", str(self.port), "--bind", "127.0.0.1", "--dir",
             str(self.folder), "--save", "", "--appendonly", "yes" if self.aof else "no",
             "--appendfsync", self.fsync],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        _until(self.answers, 20, "redis-server to start")

    def answers(self) -> bool:
        try:
            c = redis.Redis(port=self.port, socket_connect_timeout=0.5, socket_timeout=1)
            ok = c.ping()
            c.close()
            return bool(ok)
        except redis.exceptions.RedisError:
            return False

    def client(self, **kw) -> redis.Redis:
        return redis.Redis(port=self.port, **kw)

    def pause(self, seconds: float) -> None:
        self.proc.send_signal(signal.SIGSTOP)
        time.sleep(seconds)
        self.proc.send_signal(signal.SIGCONT)

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGCONT)
            self.proc.kill()
            self.proc.wait()

    def restart(self, empty: bool = False, down_s: float = 0.5) -> None:
        self.kill()
        if empty:
            shutil.rmtree(self.folder, ignore_errors=True)
        time.sleep(down_s)
        self.start()

    def snapshot(self) -> Path:
        """SAVE now, the snapshot copied aside (to start from it again later)."""
        c = self.client()
        c.save()
        c.close()
        aside = self.folder.parent / "snapshot.rdb"
        shutil.copy(self.folder / "dump.rdb", aside)
        return aside

    def restart_from(self, snapshot: Path) -> None:
        """SIGKILLed and started from an older snapshot: every write since is lost. (Its
        append-only file removed and AOF off for the start, which loads the snapshot; then on
        again: Redis writes a new one from what it holds.)"""
        self.kill()
        shutil.rmtree(self.folder / "appendonlydir", ignore_errors=True)
        shutil.copy(snapshot, self.folder / "dump.rdb")
        aof, self.aof = self.aof, False
        self.start()
        self.aof = aof
        if aof:
            c = self.client()
            c.config_set("appendonly", "yes")
            c.close()

    def stop(self) -> None:
        self.kill()


class Workers:
    """``touchdown serve`` processes, by name; their stderr in files."""

    def __init__(self, folder: Path, args: list[str], python: str = sys.executable):
        self.folder, self.args, self.python = folder, args, python
        self.procs: dict[str, subprocess.Popen] = {}
        self._errs: dict[str, object] = {}

    def start(self, name: str) -> None:
        err = open(self.folder / f"{name}.err", "a")
        self._errs[name] = err
        self.procs[name] = subprocess.Popen(
            [self.python, str(ROOT / "cli.py"), "serve", *self.args, "--worker-id", name],
            stdout=subprocess.DEVNULL, stderr=err)

    def err(self, name: str) -> str:
        return (self.folder / f"{name}.err").read_text()

    def kill(self, name: str) -> None:
        p = self.procs.get(name)
        if p is not None and p.poll() is None:
            p.kill()
            p.wait()

    def term(self, name: str, timeout: float = 120) -> int | None:
        p = self.procs.get(name)
        if p is None:
            return None
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
        try:
            return p.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            p.kill()
            return p.wait()

    def alive(self) -> list[str]:
        return [n for n, p in self.procs.items() if p.poll() is None]

    def signal(self, name: str, sig: int) -> None:
        """``sig`` to worker ``name`` (SIGSTOP, SIGCONT: a worker frozen as by a long GC pause, a
        VM migration, or a swapped-out process)."""
        p = self.procs.get(name)
        if p is not None and p.poll() is None:
            p.send_signal(sig)

    def stop_all(self) -> dict:
        return {n: self.term(n) for n in list(self.procs)}


def _until(pred, timeout: float, what: str) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            if pred():
                return
        except redis.exceptions.RedisError:
            pass
        time.sleep(0.05)
    raise RuntimeError(f"timed out waiting for {what}")


# -- the cases ----------------------------------------------------------------------------------
#: the faults ``bench chaos`` draws from (``pause-S``, ``rollback-S``: any seconds)
FAULTS = ("worker-kill", "takeover-kill", "pause-5", "pause-30", "aof-restart", "empty-restart",
          "rollback-2", "stale-rollback", "failover", "reshard")
CLUSTER_FAULTS = ("failover", "reshard")


@dataclass
class Outcome:
    faults: list
    verdict: Verdict
    seconds: float
    notes: list = field(default_factory=list)

    def line(self) -> str:
        return f"{' + '.join(self.faults):14s} {self.verdict.line()} ({self.seconds:.0f} s)"


def _owners(client, keys, shards: int) -> dict:
    return {k: client.get(keys.shard(k, "owner")) for k in range(shards)}


def _ticks(client, keys, shards: int) -> list[int]:
    return [int(client.get(keys.shard(k, "tick")) or -1) for k in range(shards)]


def _settle(client, keys, shards: int, timeout: float) -> None:
    """Until every shard's group has read everything and holds nothing pending (or timeout)."""
    def quiet():
        for stream in [keys.shard_commands(k) for k in range(shards)] + (
                [] if keys.cluster else [keys.commands]):
            for g in client.xinfo_groups(stream):
                if int(g["pending"]) or int(g.get("lag") or 0):
                    return False
        return True
    try:
        _until(quiet, timeout, "the commands to settle")
    except RuntimeError:
        pass


@dataclass
class Session:
    """What the faults act on: the servers, the workers, the gateways, the notes."""
    server: Server | None
    cluster: object
    workers: Workers
    gateways: Gateways
    keys: object
    notes: list = field(default_factory=list)
    wiped: list = field(default_factory=list)  # (from, to): writes Redis lost by design
    #: when each fault began (wall clock, as the workers' lines say it), and whether it may
    #: legitimately move a shard to another worker
    faults_at: list = field(default_factory=list)
    next_worker: int = 0
    lease_s: float = 2.0


def run_session(faults: list[str], folder: Path, seconds_between: float = 6.0,
                rate: float = 150.0, lease_s: float = 2.0, seed: int = 1, workers: int = 2,
                verbose: bool = True, python: str = sys.executable,
                settle_s: float = 60.0, verify: bool = True) -> Outcome:
    """One service session: servers and ``workers`` workers started, the gateways writing
    throughout, each fault in turn with ``seconds_between`` of traffic before and after it, then
    everything settled, stopped and accounted. The faults of a session are all of one Redis or
    all of a cluster (``failover``: masters with a replica each)."""
    from touchdown.service.redis_io import Keys
    t0 = time.monotonic()
    folder.mkdir(parents=True, exist_ok=True)
    flight = folder / "flight"
    cluster = any(f in CLUSTER_FAULTS for f in faults)
    if cluster and not all(f in CLUSTER_FAULTS for f in faults):
        raise ValueError(f"{faults}: a session's faults are all of one Redis or of a cluster")
    prefix = "chaos"
    keys = Keys(prefix, cluster=cluster)
    server = cl = None
    if cluster:
        from touchdown.bench.redis_cluster import Cluster
        cl = Cluster(folder / "cluster", replicas=1 if "failover" in faults else 0,
                     node_timeout_ms=1500)
        url_args = ["--redis-cluster", cl.url]
        connect = cl.client
    else:
        server = Server(folder / "redis")
        url_args = ["--redis", server.url]
        connect = lambda: server.client(socket_timeout=120)  # noqa: E731  (blocks through pauses)
    args = [*url_args, "--prefix", prefix, "--log-dir", str(flight), "--shards", str(SHARDS),
            "--lease", str(lease_s), "--checkpoint-every", str(CHECKPOINT_TICKS),
            "--stats-every", "1"]
    pool = Workers(folder, args, python)
    client = connect()
    gws = Gateways(GATEWAYS, connect, keys, SHARDS, rate, seed, cluster=cluster,
                   wait="failover" in faults)
    ses = Session(server, cl, pool, gws, keys, lease_s=lease_s)
    verdict = Verdict()
    try:
        names = []
        for i in range(workers):
            name = _next_name(ses)
            pool.start(name)
            names.append(name.encode())
            want = set(names)
            _until(lambda: set(_owners(client, keys, SHARDS).values()) == want, 120,
                   f"the shards shared by {len(names)} worker(s)")
        gws.start()
        follower = Follower(connect, keys, SHARDS)
        follower.start()
        for fault in faults:
            time.sleep(seconds_between)
            ses.notes.append(f"{fault} at {time.monotonic() - t0:.1f} s, ticks "
                             f"{_ticks(client, keys, SHARDS)}")
            ses.faults_at.append((time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime()), fault))
            inject(fault, ses)
            if fault != "reshard" and not cluster:
                client.close()
                client = connect()
        time.sleep(seconds_between)
        gws.halt()
        client.close()
        client = connect()
        _settle(client, keys, SHARDS, settle_s)
        time.sleep(1.0)
        codes = pool.stop_all()
        ses.notes.append(f"exit codes {codes}")
        follower.halt(client)
        verdict = account(gws.sent, flight, client, keys, SHARDS, ses.wiped, follower)
        with open(folder / "sent.jsonl", "w") as f:  # (for a look afterwards)
            for x in gws.sent:
                f.write(json.dumps(x.__dict__) + "\n")
        with open(folder / "events.jsonl", "w") as f:
            for e in follower.events.values():
                f.write(json.dumps({k: v for k, v in e.items() if k != "proto"}) + "\n")
        if verify:
            verdict.unverified = verify_logs(flight)
        for name in pool.procs:
            err = pool.err(name)
            if "Traceback" in err:
                verdict.tracebacks.append(name)
            for line in err.splitlines():
                if not line.startswith("{"):
                    continue
                msg = json.loads(line)
                if ": lost at tick" in msg["msg"] or (
                        "taken (new" in msg["msg"] and ses.faults_at
                        and msg["time"] > ses.faults_at[0][0]):
                    verdict.backwards.append((name, msg["time"], msg["msg"][:160]))
                if "first tick" in msg["msg"]:
                    verdict.first_ticks.append(float(msg["msg"].split("first tick ")[1]
                                                     .split(" s")[0]))
    finally:
        if gws.is_alive():
            gws.halt()
        for name in list(pool.procs):
            pool.kill(name)
        try:
            client.close()
        except Exception:  # noqa: BLE001
            pass
        if server is not None:
            server.stop()
        if cl is not None:
            cl.stop()
    out = Outcome(list(faults), verdict, time.monotonic() - t0, ses.notes)
    if verbose:
        print(out.line(), flush=True)
        for n in ses.notes:
            print(f"    {n}", flush=True)
        for label, items in (("pending", verdict.pending_detail), ("seq", verdict.seq_gaps),
                             ("log", verdict.unverified), ("shard went back",
                                                                    verdict.backwards),
                             ("lost", verdict.lost), ("twice", verdict.twice),
                             ("to the wrong player", verdict.wrong_recipient)):
            for what in items[:10]:
                print(f"    {label}: {what}", flush=True)
    return out


def _next_name(ses: Session) -> str:
    name = "abcdefghijklmnopqrstuvwxyz"[ses.next_worker % 26] + (
        str(ses.next_worker // 26) if ses.next_worker >= 26 else "")
    ses.next_worker += 1
    return name


def inject(fault: str, ses: Session) -> None:
    """One fault, on the session's servers or workers; what it did in the session's notes."""
    server, cl, notes = ses.server, ses.cluster, ses.notes
    if fault == "worker-kill":
        ses.gateways.burst = 200
        time.sleep(0.3)
        victim = ses.workers.alive()[0]
        ses.workers.kill(victim)
        notes.append(f"    worker {victim} SIGKILLed in a burst of 200 spawns")
        time.sleep(1.0)
        name = _next_name(ses)
        ses.workers.start(name)
        notes.append(f"    worker {name} started")
    elif fault == "takeover-kill":
        alive = ses.workers.alive()
        ses.workers.kill(alive[0])
        time.sleep(ses.lease_s + 0.02)  # about when the other takes its shards over
        for name in alive[1:]:
            ses.workers.kill(name)
        notes.append(f"    worker {alive[0]} SIGKILLed, then {', '.join(alive[1:])} a lease "
                     f"later, while taking its shards over")
        for _ in range(max(1, len(alive))):
            name = _next_name(ses)
            ses.workers.start(name)
            notes.append(f"    worker {name} started")
    elif fault.startswith("pause-"):
        s = float(fault.split("-")[1])
        server.pause(s)
        notes.append(f"    redis paused {s:g} s")
    elif fault == "aof-restart":
        server.restart()
        notes.append("    redis SIGKILLed and started on its AOF")
    elif fault == "empty-restart":
        t = time.monotonic() - 1.0  # what it held and no worker had read yet went with it
        server.restart(empty=True)
        ses.wiped.append((t, time.monotonic()))
        notes.append("    redis SIGKILLed and started empty")
    elif fault.startswith("rollback"):
        age = float(fault.split("-")[1]) if "-" in fault else 2.0
        snap = server.snapshot()
        t = time.monotonic() - 0.2
        time.sleep(age)
        server.restart_from(snap)
        ses.wiped.append((t, time.monotonic()))
        notes.append(f"    redis SIGKILLed and started from a snapshot {age:g} s old (every "
                     f"write since lost: a failover to a lagging replica, longer)")
    elif fault == "stale-rollback":
        _stale_rollback(ses)
    elif fault == "failover":
        i = cl.node_of(ses.keys.shard(1, "owner"))
        cl.kill(i)
        notes.append(f"    master {i} SIGKILLed")
        cl.wait_promoted(i, timeout=30)
        notes.append("    its replica promoted")
        time.sleep(1.0)
        cl.start(i)  # back as a replica of the promoted one
    elif fault == "reshard":
        moved = cl.move_slot_of(ses.keys.shard(1, "owner"))
        notes.append(f"    shard 1's slot moved: {moved}")
    else:
        raise ValueError(fault)


def _stale_rollback(ses: Session) -> None:
    """A worker frozen through a rollback and killed before it learns of it (found once under
    load, 2026-12-02: four throttles counted twice). The owner of a shard is frozen for half a
    lease, so that commands wait unread in Redis; Redis saves a snapshot; the owner thaws,
    reads them, journals and applies them, and its flight log is flushed at its next
    checkpoint; it is frozen again and Redis is started from the snapshot (the journal, the
    reads and the checkpoint gone, the commands unread again); the other worker takes the
    shards when the lease lapses and applies the commands again at its own ticks; the frozen
    worker is then SIGKILLed, its log never marked superseded. Its log's ticks from the
    successor's first tick on are a history the world did not keep (logs.shards)."""
    server, notes, pool = ses.server, ses.notes, ses.workers
    alive = pool.alive()
    victim, others = alive[0], alive[1:]
    pool.signal(victim, signal.SIGSTOP)
    time.sleep(ses.lease_s / 2)
    t = time.monotonic() - 0.2
    snap = server.snapshot()
    pool.signal(victim, signal.SIGCONT)
    time.sleep(CHECKPOINT_TICKS * 0.1 + 0.5)  # (a checkpoint flushes its flight log)
    pool.signal(victim, signal.SIGSTOP)
    server.restart_from(snap)
    ses.wiped.append((t, time.monotonic()))
    notes.append(f"    worker {victim} frozen {ses.lease_s / 2:g} s, a snapshot taken, "
                 f"{victim} thawed {CHECKPOINT_TICKS * 0.1 + 0.5:g} s, frozen again, redis "
                 f"started from the snapshot")
    if others:
        c = server.client()
        try:
            _until(lambda: set(_owners(c, ses.keys, SHARDS).values()) <= {
                o.encode() for o in others}, 60, f"{', '.join(others)} to take every shard")
        finally:
            c.close()
    pool.kill(victim)
    notes.append(f"    worker {victim} SIGKILLed once {', '.join(others) or 'nobody'} held "
                 f"every shard")
    name = _next_name(ses)
    pool.start(name)
    notes.append(f"    worker {name} started")


def main(faults: list[str], seconds: float, rate: float, seed: int, minutes: float | None,
         out_dir: str | None, python: str = sys.executable) -> int:
    """``bench chaos``: the given faults once each, or (``minutes``) sessions of faults drawn
    from ``seed`` until the time is up (three faults a session, of one Redis or of a cluster);
    a line per session, then the sums."""
    rng = random.Random(seed)
    print(f"touchdown bench chaos: seed {seed}; {os.cpu_count()} CPUs; redis-server "
          f"{_server_version()}; {GATEWAYS} gateways at {rate:g} entries/s; {SHARDS} shards, "
          f"two workers, lease 2 s", flush=True)
    base = Path(out_dir) if out_dir else Path(tempfile.mkdtemp(prefix="touchdown-chaos-"))
    outcomes = []
    end = time.monotonic() + 60 * minutes if minutes else None
    i = 0
    while True:
        if end is None:
            if i >= len(faults):
                break
            chosen = [faults[i]]
        else:
            if time.monotonic() >= end:
                break
            on_cluster = rng.random() < 0.3
            kind = [f for f in faults if (f in CLUSTER_FAULTS) == on_cluster] or faults
            kind = [f for f in kind if (f in CLUSTER_FAULTS) == (kind[0] in CLUSTER_FAULTS)]
            chosen = [rng.choice(kind) for _ in range(3)]
        outcomes.append(run_session(chosen, base / f"{i:03d}-{'+'.join(chosen)}", seconds / 2,
                                    rate, seed=rng.randrange(1 << 30), python=python))
        i += 1
    sent = sum(o.verdict.sent for o in outcomes)
    lost = sum(len(o.verdict.lost) for o in outcomes)
    twice = sum(len(o.verdict.twice) for o in outcomes)
    print(f"total: {len(outcomes)} sessions, {sum(len(o.faults) for o in outcomes)} faults, "
          f"{sent:,} commands sent, {lost} lost, {twice} twice (seed {seed})", flush=True)
    if out_dir is None:
        shutil.rmtree(base, ignore_errors=True)
    return 0 if all(o.verdict.ok for o in outcomes) else 1


def _server_version() -> str:
    try:
        out = subprocess.run(["redis-server", "--version"], capture_output=True, text=True)
        return out.stdout.split("v=")[1].split()[0]
    except (OSError, IndexError):
        return "?"


def known(fault: str) -> bool:
    """A fault ``bench chaos`` knows (pause-S and rollback-S take any seconds)."""
    head, _, tail = fault.partition("-")
    if head in ("pause", "rollback") and tail:
        try:
            return float(tail) > 0
        except ValueError:
            return False
    return fault in FAULTS or fault in ("rollback",)
