"""``touchdown serve`` tried as an operator would before a game's first day (issue 22), each case on
real redis-servers (the shared one under a prefix of its own, or a private one on a free port for a
password, an ACL, TLS, maxmemory, or a server to pause): workers killed while spawns, retires and
commands flow; Redis paused and out of memory; the log disk full and read-only; players
commanding ships not theirs; floods and a burst; secrets; what operators see. Each asserts that
nothing was lost or doubled and that the tick held."""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
import urllib.request
import uuid
from pathlib import Path

import pytest
import redis

import touchdown.scenarios as builtin
from touchdown.logs.reader import LogReader
from redis_server import _free_port, redis_url  # noqa: F401  (a pytest fixture)
from touchdown.replay.verify import verify
from touchdown.service import redis_io as rio
from touchdown.service.commands import shard_of
from touchdown.service.redis_io import Keys
from touchdown.service.serve import ServeConfig, Worker
from touchdown.sim.enums import SurfaceState
from touchdown.sim.scenario import parse_text
from test_serve import _wait  # noqa: F401  (also the cluster tests')

pytestmark = pytest.mark.redis

ROOT = Path(__file__).resolve().parents[1]
FLEET = parse_text(builtin.text("fleet"), "fleet")


# -- helpers -----------------------------------------------------------------------------------
def _prefix() -> str:
    return f"test:ops:{uuid.uuid4().hex[:10]}"


def _cleanup(url: str, prefix: str) -> None:
    client = redis.Redis.from_url(url)
    keys = list(client.scan_iter(f"{prefix}:*", count=10_000))
    for i in range(0, len(keys), 1000):
        client.delete(*keys[i:i + 1000])
    client.close()


def _cli(*args: str) -> list[str]:
    return [sys.executable, str(ROOT / "cli.py"), *args]


class _Proc:
    """A ``touchdown serve`` subprocess whose stderr goes to a file (readable while it runs)."""

    def __init__(self, args: list[str], tmp: Path, name: str, env: dict | None = None):
        self.err_path = tmp / f"{name}.err"
        self._err = open(self.err_path, "w")
        self.p = subprocess.Popen(_cli(*args), stdout=subprocess.DEVNULL, stderr=self._err,
                                  text=True, env={**os.environ, **(env or {})})

    def err(self) -> str:
        return self.err_path.read_text()

    def term(self, timeout: float = 60) -> int:
        if self.p.poll() is None:
            self.p.send_signal(signal.SIGTERM)
        rc = self.p.wait(timeout=timeout)
        self._err.close()
        return rc

    def kill(self) -> None:
        if self.p.poll() is None:
            self.p.kill()
            self.p.wait()
        self._err.close()


def _server(tmp: Path, *args: str, port: int | None = None) -> tuple[subprocess.Popen, int]:
    """A private redis-server on a free port (or ``port``), data in ``tmp``."""
    binary = shutil.which("redis-server")
    if binary is None:
        pytest.fail("these tests need redis-server on PATH")
    port = port or _free_port()
    tmp.mkdir(parents=True, exist_ok=True)
    proc = subprocess.Popen([binary, "--port", str(port), "--bind", "127.0.0.1", "--dir",
                             str(tmp), "--save", "", "--appendonly", "no", *args],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return proc, port


def _ready(client, timeout: float = 10.0) -> None:
    def ok():
        try:
            return bool(client.ping())
        except redis.exceptions.AuthenticationError:
            return True
        except redis.exceptions.ResponseError as exc:  # NOAUTH: up, and wanting a password
            return "NOAUTH" in str(exc)
        except redis.exceptions.RedisError:
            return False
    _wait(ok, timeout, "redis-server to start")


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGCONT)
        proc.kill()
    proc.wait()


def _events(client, stream: str) -> list[dict]:
    return [{k.decode(): v.decode("utf-8", "replace") if k != b"proto" else v
             for k, v in f.items()} for _id, f in client.xrange(stream)]


def _gapless(events: list[dict], shards: int) -> None:
    for k in range(shards):
        numbers = [int(e["seq"].split(":")[1]) for e in events if e["seq"].startswith(f"{k}:")]
        assert numbers == list(range(len(numbers))), f"shard {k}: {numbers[:20]}"


def _files(folder: Path) -> list[Path]:
    return sorted(folder.rglob("*.mcap")) + sorted(folder.rglob("*.partial"))


def _nothing_lost(client, keys, events, flight, n, sent_throttles, retired) -> None:
    """Ships s0..s{n-1} (player p{i % 3}) each joined once; every throttle sent was applied once
    or rejected once; every retire gave one ship.retired and removed the hash; every other
    ship's hash says what its flight log says."""
    rejected = {e["entry_id"]: e for e in events if e["event"] == "ship.command_rejected"}
    joins, throttles, last = _from_logs(flight)
    for i in range(n):
        assert len(joins.get(f"s{i}", ())) == 1, (f"s{i}", joins.get(f"s{i}"))
    for eid, (sid, value) in sent_throttles.items():
        applied = len(throttles.get((sid, value), ()))
        assert applied + (eid in rejected) == 1, (sid, value, applied, rejected.get(eid))
    for sid in retired:
        mine = [e for e in events if e["ship_id"] == sid and e["event"] == "ship.retired"]
        assert len(mine) == 1, sid
        assert not client.exists(keys.ship(sid))
    for i in range(n):
        sid = f"s{i}"
        if sid in retired:
            continue
        h = client.hgetall(keys.ship(sid))
        assert h[b"state"].decode() == SurfaceState(last[sid][1]).label, sid
        assert h[b"player_id"].decode() == f"p{i % 3}"


def _all_verify(folder: Path) -> None:
    for path in _files(folder):
        res = verify(str(path))
        assert res.divergence is None, (path, res.report())


def _traffic(send, i: int, sent_throttles: dict, retired: list) -> None:
    """The i-th step of the nothing-lost tests' traffic: ship s{i} spawned (player p{i % 3}), every
    fourth a throttle of an earlier ship, every eighth a retire; ``send(ship_id, fields)`` writes
    an entry and returns its id. Throttles sent and ships retired are noted for _nothing_lost."""
    sid = f"s{i}"
    send(sid, _spawn(sid, f"p{i % 3}"))
    if i >= 2 and (i - 2) % 4 == 2:
        t = f"s{i - 2}"
        value = f"0.{i:03d}"
        sent_throttles[send(t, {"cmd": "throttle", "ship_id": t, "player_id":
                                f"p{(i - 2) % 3}", "value": value})] = (t, float(value))
    if i >= 6 and (i - 6) % 8 == 1:
        r = f"s{i - 6}"
        send(r, {"cmd": "retire", "ship_id": r, "player_id": f"p{(i - 6) % 3}"})
        retired.append(r)


def _spawn(ship_id: str, player: str, altitude: float = 3.0) -> dict:
    return {"cmd": "spawn", "ship_id": ship_id, "player_id": player,
            "ship": json.dumps({"initial": {"altitude": altitude, "vertical_speed": -2.0}})}


def _from_logs(folder: Path) -> tuple[dict, dict, dict]:
    """Across every log (overlapping ones agree): each ship's join ticks, each (ship, throttle)'s
    command ticks, and each ship's state at the last tick logged. A log of a shard lost to
    another worker counts up to the last tick it published (its summary's
    superseded_after_tick): what it holds after that, the world does not follow."""
    joins: dict[str, set] = {}
    throttles: dict[tuple, set] = {}
    last: dict[str, tuple[int, int]] = {}
    for path in _files(folder):
        with LogReader(path) as r:
            s = r.read_summary() if r.status.complete else None
            upto = s.superseded_after_tick if s is not None and s.HasField(
                "superseded_after_tick") else float("inf")
            tl = r.timeline()
            for sp in tl.spawns:
                if sp.tick < upto:
                    joins.setdefault(sp.ship_id, set()).add(sp.tick)
            for c in tl.commands:
                if c.tick < upto:
                    throttles.setdefault((c.ship_id, c.throttle), set()).add(c.tick)
            table = r.ship_table()
            for t in r.ticks():
                if t.tick > upto:
                    break
                states = t.arrays.get("surface_state")
                if states is None:  # a tick with no ships
                    continue
                for j, key in enumerate(t.keys):
                    sid = table.ids[int(key)]
                    if sid not in last or last[sid][0] <= t.tick:
                        last[sid] = (t.tick, int(states[j]))
    return joins, throttles, last


# -- nothing lost --------------------------------------------------------------------------------
def test_a_worker_killed_while_spawns_retires_and_commands_flow_loses_and_doubles_nothing(
        redis_url, tmp_path):  # noqa: F811
    """Two workers; spawns, throttles and retires flow (half through the shared stream and its
    router, half straight to the shards' streams); one worker is SIGKILLed in the middle. Every
    spawn joins exactly once (none "taken"), every throttle is applied at exactly one tick or
    rejected once, every retire gives ship.retired once, each shard's seq is gapless, each ship's
    hash is its state in the flight logs, and every log verifies."""
    prefix = _prefix()
    flight = tmp_path / "flight"
    args = ["serve", "--redis", redis_url, "--prefix", prefix, "--log-dir", str(flight),
            "--shards", "2", "--lease", "0.6", "--rate", "40", "--checkpoint-every", "10"]
    a = _Proc([*args, "--worker-id", "a"], tmp_path, "a")
    client = redis.Redis.from_url(redis_url)
    keys = Keys(prefix)
    b = None
    try:
        _wait(lambda: client.get(keys.shard(1, "owner")) == b"a", 60, "a to own the shards")
        b = _Proc([*args, "--worker-id", "b"], tmp_path, "b")
        owners = lambda: {client.get(keys.shard(k, "owner")) for k in (0, 1)}  # noqa: E731
        _wait(lambda: owners() == {b"a", b"b"}, 60, "a shard each")
        sent_throttles, retired = {}, []
        n = 90
        for i in range(n):
            def send(sid, fields):
                direct = int(sid[1:]) % 2
                stream = keys.shard_commands(shard_of(sid, 2)) if direct else keys.commands
                return client.xadd(stream, fields).decode()
            _traffic(send, i, sent_throttles, retired)
            if i == n // 2:
                a.p.send_signal(signal.SIGKILL)
                a.p.wait()
            time.sleep(0.03)
        _wait(lambda: owners() == {b"b"}, 30, "b to take both shards")
        mark = [int(client.get(keys.shard(k, "tick"))) for k in (0, 1)]
        _wait(lambda: all(int(client.get(keys.shard(k, "tick"))) > mark[k] + 40
                          for k in (0, 1)), 60, "b to step on")
        assert b.term() == 0, b.err()
        assert "Traceback" not in b.err()
        events = _events(client, keys.events)
        _gapless(events, 2)
        assert not [e for e in events if "taken" in e.get("reason", "")]
        _nothing_lost(client, keys, events, flight, n, sent_throttles, retired)
        _all_verify(flight)
    finally:
        a.kill()
        if b is not None:
            b.kill()
        client.close()
        _cleanup(redis_url, prefix)


def test_a_read_whose_reply_was_lost_is_read_again_with_or_without_an_error(tmp_path):
    """A spawn delivered to the worker's consumer whose reply never reached it (made so here:
    the entry is read for that consumer in the same transaction as it is written; what a
    pipeline re-sent by redis-py's cluster client does, with no error for the worker to see)
    was pending for ever (0.7.0): the worker now finds more entries pending to it than it holds
    after its next read, and reads them again. Then Redis is paused (SIGSTOP, 3 s: the
    worker's calls time out) with a second spawn just sent: after SIGCONT both ships have
    joined, once."""
    server, port = _server(tmp_path / "redis")
    url = f"redis://127.0.0.1:{port}/0"
    client = redis.Redis(port=port)
    w = None
    try:
        _ready(client)
        w = _Proc(["serve", "--redis", url, "--scenario", "fleet", "--shards", "1", "--rate", "40",
                   "--lease", "10", "--log-dir", str(tmp_path / "flight"), "--worker-id", "w1"],
                  tmp_path, "w")
        keys = Keys("galaxy")
        _wait(lambda: int(client.get(keys.shard(0, "tick")) or 0) > 10, 60, "the worker")
        pipe = client.pipeline(transaction=True)
        pipe.xadd(keys.shard_commands(0), _spawn("lost-reply", "p1"))
        pipe.xreadgroup(Keys.group(0), "w1", {keys.shard_commands(0): ">"}, count=10)
        pipe.execute()
        _wait(lambda: client.exists(keys.ship("lost-reply")), 30, "the unseen spawn")
        assert "unreachable" not in w.err()  # (found without any error)
        client.xadd(keys.shard_commands(0), _spawn("before-pause", "p1"))
        server.send_signal(signal.SIGSTOP)
        time.sleep(3.0)
        server.send_signal(signal.SIGCONT)
        _wait(lambda: client.exists(keys.ship("lost-reply"))
              and client.exists(keys.ship("before-pause")), 30, "both ships")
        assert w.term() == 0
        err = w.err()
        assert "Traceback" not in err and "unreachable" in err
        joins, _t, _l = _from_logs(tmp_path / "flight")
        assert len(joins["lost-reply"]) == 1 and len(joins["before-pause"]) == 1
        assert client.xpending(keys.shard_commands(0), Keys.group(0))["pending"] == 0
        _gapless(_events(client, keys.events), 1)
    finally:
        if w is not None:
            w.kill()
        client.close()
        _stop(server)


def test_redis_out_of_memory_is_said_once_and_nothing_is_lost(tmp_path):
    """Redis at maxmemory (noeviction) refuses every write for 3 s: the worker says so in one
    line (no traceback), ticks on, holds its entries and the command it read, and delivers them
    in order when memory is back."""
    server, port = _server(tmp_path / "redis", "--maxmemory-policy", "noeviction")
    url = f"redis://127.0.0.1:{port}/0"
    client = redis.Redis(port=port)
    w = None
    try:
        _ready(client)
        w = _Proc(["serve", "--redis", url, "--scenario", "fleet", "--shards", "2", "--rate", "50",
                   "--lease", "10", "--log-dir", str(tmp_path / "flight")], tmp_path, "w")
        keys = Keys("galaxy")
        _wait(lambda: int(client.get(keys.shard(0, "tick")) or 0) > 10, 60, "the worker")
        client.config_set("maxmemory", "1")
        time.sleep(0.3)
        cmd_id = None
        try:
            cmd_id = client.xadd(keys.shard_commands(shard_of("hover", 2)),
                                 {"cmd": "throttle", "ship_id": "hover", "player_id":
                                  "player-hover", "value": "0.5"})
        except redis.exceptions.ResponseError:
            pass  # refused to the client too: nothing to check for it
        time.sleep(3.0)
        client.config_set("maxmemory", "0")
        tick_then = int(client.get(keys.shard(0, "tick")))
        _wait(lambda: int(client.get(keys.shard(0, "tick"))) > tick_then + 20, 30, "delivery")
        assert w.term() == 0
        err = w.err()
        assert "Traceback" not in err
        oom = [line for line in err.splitlines() if "OOM" in line]
        assert 1 <= len(oom) <= 2, oom
        assert json.loads(oom[0])["level"] == "error"
        events = _events(client, keys.events)
        _gapless(events, 2)
        assert len([e for e in events if e["event"].startswith("ship.")]) > 5
        if cmd_id is not None:
            _j, throttles, _l = _from_logs(tmp_path / "flight")
            assert len(throttles.get(("hover", 0.5), ())) == 1
        _all_verify(tmp_path / "flight")
    finally:
        if w is not None:
            w.kill()
        client.close()
        _stop(server)


# -- the log disk ----------------------------------------------------------------------------------
def _mount(path: Path, size: str) -> bool:
    path.mkdir(parents=True, exist_ok=True)
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)],
                          capture_output=True)
    return done.returncode == 0


def test_a_full_then_read_only_log_disk_pauses_the_log_and_the_ships_go_on(redis_url, tmp_path):  # noqa: F811,E501
    """The flight logs on a 3 MiB tmpfs: filled, the log pauses (one line) while the ships step
    and publish; space back, it resumes with a keyframe and says where the gap was; then the
    file system goes read-only and back. Every file verifies (the cut ones their intact part)."""
    disk = tmp_path / "disk"
    if not _mount(disk, "3m"):  # a machine's capability, not a fault of the code: a skip
        pytest.skip("cannot mount a tmpfs (the full and read-only log disk needs root)")
    prefix = _prefix()
    client = redis.Redis.from_url(redis_url)
    keys = Keys(prefix)
    w = None
    try:
        filler = disk / "filler"
        free = shutil.disk_usage(disk).free
        filler.write_bytes(b"\0" * (free - 48 * 1024))
        flight = disk / "flight"
        w = _Proc(["serve", "--redis", redis_url, "--prefix", prefix, "--scenario", "fleet",
                   "--shards", "1", "--rate", "100", "--log-dir", str(flight),
                   "--log-max-mb", "0.03", "--log-min-free-mb", "0"], tmp_path, "w")
        _wait(lambda: "paused" in w.err(), 60, "the log to pause")
        tick_then = int(client.get(keys.shard(0, "tick")) or 0)
        _wait(lambda: int(client.get(keys.shard(0, "tick"))) > tick_then + 30, 30,
              "ticks while paused")
        filler.unlink()
        _wait(lambda: "resumed" in w.err(), 30, "the log to resume")
        # the log folder made read-only under it (a read-only bind mount: the file in hand
        # writes on, the next rotation cannot create its file)
        subprocess.run(["mount", "--bind", str(flight), str(flight)], check=True)
        subprocess.run(["mount", "-o", "remount,bind,ro", str(flight)], check=True)
        _wait(lambda: w.err().count("paused") >= 2, 30, "the log to pause on a read-only dir")
        subprocess.run(["umount", str(flight)], check=True)
        try:
            _wait(lambda: w.err().count("resumed") >= 2, 30, "the log to resume again")
        except AssertionError as exc:  # what the worker said, to tell a slow machine from a fault
            raise AssertionError(f"{exc}; the worker said:\n{w.err()[-3000:]}") from None
        time.sleep(0.5)
        assert w.term() == 0
        err = w.err()
        assert "Traceback" not in err
        assert len([ln for ln in err.splitlines() if "paused" in ln]) <= 4
        _gapless(_events(client, keys.events), 1)
        resumed = []
        for path in _files(flight):
            res = verify(str(path))
            assert res.divergence is None, (path, res.report())
            if path.suffix == ".mcap":
                with LogReader(path) as r:
                    desc = r.scenario.description
                if "gap" in desc:
                    resumed.append(path)
        assert resumed, "no log says where its gap was"
    finally:
        if w is not None:
            w.kill()
        client.close()
        _cleanup(redis_url, prefix)
        subprocess.run(["umount", "-l", str(disk / "flight")], capture_output=True)
        subprocess.run(["umount", "-l", str(disk)], capture_output=True)


# -- players, ACLs, TLS, secrets --------------------------------------------------------------------
WORKER_ACL = ("+ping +time +eval +xadd +xreadgroup +xack +xautoclaim "
              "+xgroup|create +xrange +xpending +xtrim +xdel +get +set +del +hset +hsetnx +hgetall "
              "+hmget +hdel +expire +pexpire +zadd +zremrangebyscore +zcard +zrem")
GATEWAY_ACL = "+ping +xadd"
READER_ACL = "+ping +xread +xrange +xrevrange +hgetall +hget"


def _acl(client, user: str, password: str, prefix: str, keys: str, perms: str) -> None:
    client.execute_command("ACL", "SETUSER", user, "reset", "on", f">{password}",
                           *keys.replace("P:", f"{prefix}:").split(), *perms.split())


def test_only_a_ships_player_commands_it_with_the_least_acl_permissions(tmp_path):
    """The worker runs as an ACL user with exactly the permissions docs/SERVICE.md lists; the
    gateway's user may only add to the command streams; a reader's only read events and hashes.
    Commands for another player's ship are rejected and not applied; a spawn belongs to its
    command's player; retire publishes ship.retired. A worker user missing a permission (XTRIM)
    gets one line, no traceback, and ticks on."""
    server, port = _server(tmp_path / "redis")
    admin = redis.Redis(port=port)
    prefix = "g"
    w = None
    try:
        _ready(admin)
        _acl(admin, "worker", "wpw", prefix, "~P:*", WORKER_ACL)
        _acl(admin, "gateway", "gpw", prefix, "%W~P:commands %W~P:commands:*", GATEWAY_ACL)
        _acl(admin, "reader", "rpw", prefix, "%R~P:ships %R~P:ship:* %R~P:telemetry",
             READER_ACL)
        admin.execute_command("ACL", "SETUSER", "root", "on", ">rootpw", "~*", "&*", "+@all")
        admin.execute_command("ACL", "SETUSER", "default", "off")
        root = redis.Redis(port=port, username="root", password="rootpw")
        admin = redis.Redis(port=port, username="worker", password="wpw")
        url = f"redis://worker@127.0.0.1:{port}/0"
        pwfile = tmp_path / "pw"
        pwfile.write_text("wpw\n")
        w = _Proc(["serve", "--redis", url, "--redis-password-file", str(pwfile), "--prefix",
                   prefix, "--shards", "2", "--rate", "50", "--log-dir", str(tmp_path / "flight")],
                  tmp_path, "w")
        gw = redis.Redis(port=port, username="gateway", password="gpw")
        reader = redis.Redis(port=port, username="reader", password="rpw")
        keys = Keys(prefix)
        _wait(lambda: admin.get(keys.shard(1, "owner")) is not None, 60, "the worker")
        gw.xadd(keys.commands, _spawn("mine", "alice", altitude=50.0))
        # a spawn can't claim another player's id in its table
        bad = _spawn("theirs", "mallory")
        bad["ship"] = json.dumps({"player_id": "alice"})
        bad_id = gw.xadd(keys.commands, bad).decode()
        _wait(lambda: reader.hgetall(keys.ship("mine")), 30, "the spawn")
        assert reader.hget(keys.ship("mine"), "player_id") == b"alice"
        steal = [gw.xadd(keys.commands, {"cmd": c, "ship_id": "mine", "player_id": "mallory",
                                          **f}).decode()
                 for c, f in (("throttle", {"value": "1"}), ("rcs", {"x": "1", "y": "0",
                                                                     "z": "0"}),
                              ("retire", {}))]
        own = gw.xadd(keys.commands, {"cmd": "retire", "ship_id": "mine",
                                      "player_id": "alice"}).decode()
        _wait(lambda: any(e["event"] == "ship.retired" for e in _events(reader, keys.events)),
              30, "ship.retired")
        events = _events(reader, keys.events)
        rejected = {e["entry_id"]: e["reason"] for e in events
                    if e["event"] == "ship.command_rejected"}
        for eid in steal:
            assert "belongs to another player" in rejected[eid], rejected.get(eid)
        assert "player_id is not the command's" in rejected[bad_id]
        assert own not in rejected
        # the gateway may not write anything else, nor read; the reader may not write
        for attempt in (lambda: gw.xadd(keys.events, {"event": "ship.landed"}),
                        lambda: gw.hset(keys.ship("mine"), "state", "landed"),
                        lambda: gw.xrange(keys.commands),
                        lambda: reader.xadd(keys.commands, {"cmd": "retire"}),
                        lambda: gw.xadd(f"other:commands", {"cmd": "retire"})):
            with pytest.raises(redis.exceptions.NoPermissionError):
                attempt()
        assert w.term() == 0, w.err()
        assert "Traceback" not in w.err() and "NOPERM" not in w.err()
        assert "lost" not in w.err() and "not renewed" not in w.err()
        # a permission missing: one line, the worker ticks on and stops cleanly
        root.execute_command("ACL", "SETUSER", "worker", "-xtrim")
        w = _Proc(["serve", "--redis", url, "--redis-password-file", str(pwfile), "--prefix",
                   prefix, "--shards", "2", "--rate", "50", "--ticks", "120", "--log-dir",
                   str(tmp_path / "flight2")], tmp_path, "w2")
        time.sleep(1.0)
        gw.xadd(keys.commands, _spawn("later", "bob"))
        assert w.p.wait(timeout=60) == 0
        err = w.err()
        assert "Traceback" not in err
        noperm = [ln for ln in err.splitlines() if "NOPERM" in ln]
        assert 1 <= len(noperm) <= 2, err
        assert "wpw" not in err
    finally:
        if w is not None:
            w.kill()
        _stop(server)


def _openssl(*args: str) -> None:
    subprocess.run(["openssl", *args], check=True, capture_output=True)


def make_test_ca(folder: Path) -> None:
    """The commands docs/SERVICE.md gives for a test CA, a server and a client certificate."""
    f = lambda name: str(folder / name)  # noqa: E731
    _openssl("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "2", "-subj",
             "/CN=touchdown-test-ca", "-keyout", f("ca.key"), "-out", f("ca.crt"))
    for who in ("server", "client"):
        _openssl("req", "-newkey", "rsa:2048", "-nodes", "-subj", f"/CN={who}",
                 "-keyout", f(f"{who}.key"), "-out", f(f"{who}.csr"))
        ext = folder / f"{who}.ext"
        ext.write_text("subjectAltName=IP:127.0.0.1,DNS:localhost\n")
        _openssl("x509", "-req", "-in", f(f"{who}.csr"), "-CA", f("ca.crt"), "-CAkey",
                 f("ca.key"), "-CAcreateserial", "-days", "2", "-extfile", str(ext),
                 "-out", f(f"{who}.crt"))


def test_tls_mutual_tls_a_password_and_no_secret_printed(tmp_path):
    """requirepass, TLS and mutual TLS through rediss:// URLs; the password from
    TOUCHDOWN_REDIS_URL (never in the process list) or a file; a wrong password, a wrong CA and
    an http:// URL each one line, exit 2, no traceback, the password nowhere."""
    if shutil.which("openssl") is None:
        pytest.fail("the TLS test needs openssl")
    certs = tmp_path / "certs"
    certs.mkdir()
    make_test_ca(certs)
    c = lambda name: str(certs / name)  # noqa: E731
    secret = "s3cret-Pw-42"
    tls_port = _free_port()
    server, _port = _server(tmp_path / "redis", "--requirepass", secret, "--tls-port",
                            str(tls_port), "--tls-cert-file", c("server.crt"), "--tls-key-file",
                            c("server.key"), "--tls-ca-cert-file", c("ca.crt"),
                            "--tls-auth-clients", "optional")
    try:
        plain = f"redis://:{secret}@127.0.0.1:{_port}/0"
        _ready(redis.Redis.from_url(plain))
        run = lambda *a, env=None: subprocess.run(  # noqa: E731
            _cli("serve", "--scenario", "fleet", "--ticks", "20", "--rate", "0", "--shards", "1",
                 "--log-dir", str(tmp_path / "flight"), *a), capture_output=True, text=True,
            timeout=120, env={**os.environ, **(env or {})})
        tls = (f"rediss://:{secret}@127.0.0.1:{tls_port}/0?ssl_ca_certs={c('ca.crt')}")
        mtls = tls + f"&ssl_certfile={c('client.crt')}&ssl_keyfile={c('client.key')}"
        for url in (tls, mtls):
            done = run(env={"TOUCHDOWN_REDIS_URL": url})
            assert done.returncode == 0, done.stderr
            assert secret not in done.stderr + done.stdout
        # the password only in a file, the URL without it; while it runs, the process list
        # has no password
        pw = tmp_path / "pw"
        pw.write_text(secret)
        p = subprocess.Popen(_cli("serve", "--redis", f"redis://127.0.0.1:{_port}/0",
                                  "--redis-password-file", str(pw), "--scenario", "fleet",
                                  "--shards", "1", "--log-dir", str(tmp_path / "flight")),
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        client = redis.Redis.from_url(plain)
        _wait(lambda: int(client.get(Keys("galaxy").shard(0, "tick")) or 0) > 60, 60, "ticks")
        cmdline = Path(f"/proc/{p.pid}/cmdline").read_bytes()
        p.send_signal(signal.SIGTERM)
        _out, err = p.communicate(timeout=60)
        assert p.returncode == 0, err
        assert secret.encode() not in cmdline
        # the bad ones in this process (each one line, exit 2)
        from click.testing import CliRunner
        from touchdown import cli
        for bad in (f"redis://:wrong-{secret}@127.0.0.1:{_port}/0",
                    f"rediss://:{secret}@127.0.0.1:{tls_port}/0?ssl_ca_certs={c('server.crt')}",
                    f"http://:{secret}@127.0.0.1:{_port}/0"):
            done = CliRunner().invoke(cli.main, ["serve", "--redis", bad, "--ticks", "1",
                                                 "--log-dir", str(tmp_path / "flight")])
            out = done.output
            assert done.exit_code == 2, (bad, out, done.exception)
            lines = out.strip().splitlines()
            assert len(lines) == 1 and "Traceback" not in out, out
            assert secret not in out, out
    finally:
        _stop(server)


# -- bursts, floods, operators ---------------------------------------------------------------
def test_a_burst_of_spawns_with_two_workers_loses_no_lease_and_holds_the_tick(redis_url, tmp_path):  # noqa: F811,E501
    """10,000 spawns at once into a 4-shard service of two workers at 10 Hz: every ship joins
    (none rejected), no lease changes hands, and the tick's p99 during the burst is stated."""
    n = 10_000
    prefix = _prefix()
    keys = Keys(prefix)
    client = redis.Redis.from_url(redis_url)
    args = ["serve", "--redis", redis_url, "--prefix", prefix, "--shards", "4", "--lease", "1",
            "--rate", "10", "--log-dir", str(tmp_path / "flight"), "--stats-every", "1",
            "--telemetry-hz", "0"]
    ws = []
    try:
        ws.append(_Proc([*args, "--worker-id", "a", "--max-shards", "2"], tmp_path, "a"))
        ws.append(_Proc([*args, "--worker-id", "b", "--max-shards", "2"], tmp_path, "b"))
        owners = lambda: [client.get(keys.shard(k, "owner")) for k in range(4)]  # noqa: E731
        _wait(lambda: sorted(map(str, owners())) == ["b'a'"] * 2 + ["b'b'"] * 2, 60,
              "two shards each")
        before = owners()
        pipe = client.pipeline(transaction=False)
        spec = json.dumps({"initial": {"altitude": 500.0}})
        for i in range(n):
            sid = f"b{i}"
            pipe.xadd(keys.shard_commands(shard_of(sid, 4)),
                      {"cmd": "spawn", "ship_id": sid, "player_id": f"p{i % 50}", "ship": spec})
            if i % 2000 == 1999:
                pipe.execute()
        pipe.execute()
        t0 = time.monotonic()

        def ships():
            return sum(int(client.hget(keys.stats(w), "ships") or 0) for w in ("a", "b"))
        _wait(lambda: ships() == n, 90, "every ship to join")
        took = time.monotonic() - t0
        assert owners() == before
        for w in ws:
            assert w.term() == 0
        stats = [json.loads(ln) for w in ws for ln in w.err().splitlines()
                 if ln.startswith("{") and '"stats"' in ln]
        p99 = max(s["tick_p99_ms"] for s in stats)
        for w in ws:
            assert "lost" not in w.err() and "Traceback" not in w.err()
        events = _events(client, keys.events)
        assert not [e for e in events if e["event"] == "ship.command_rejected"]
        print(f"\nburst of {n:,} spawns, two workers: all joined in {took:.1f} s; tick p99 "
              f"{p99:.0f} ms (lease 1000 ms)")
        assert p99 < 2500  # (13 s before; the leases are renewed on a thread of their own)
    finally:
        for w in ws:
            w.kill()
        client.close()
        _cleanup(redis_url, prefix)


@pytest.fixture
def worker(redis_url, tmp_path):  # noqa: F811
    prefix = _prefix()
    made = []

    def start(**kw):
        said: list[str] = []
        cfg = ServeConfig(url=redis_url, prefix=prefix, log_dir=tmp_path / "flight",
                          **{"rate_hz": 0.0, "shards": 2, "scenario": FLEET, "source": "fleet",
                             **kw})
        w = Worker(cfg, say=said.append)
        th = threading.Thread(target=w.run, daemon=True)
        th.start()
        made.append((w, th))
        w.said = said
        return w, th
    start.prefix, start.url, start.dir = prefix, redis_url, tmp_path / "flight"
    yield start
    for w, th in made:
        w.stop.set()
        th.join(timeout=60)
    _cleanup(redis_url, prefix)


def test_floods_are_bounded_and_counted(worker):
    """20,000 throttles for one ship and 20,000 commands for ships that do not exist: the ship
    takes one throttle a tick (each in the flight log at its own tick), at most 4 wait and the
    rest are rejected (the per-ship rate); at most 100 rejections a tick are published for each
    sender (the rest counted, and named in the results stream), so another player's one bad
    command in the middle of the flood still reaches that player; nothing counts as dropped;
    300 commands of 64 KiB wait within the per-tick byte budget."""
    w, th = worker(ticks=400, rate_hz=100.0, stats_every_s=0.5)
    client = redis.Redis.from_url(worker.url)
    keys = Keys(worker.prefix)
    _wait(lambda: client.exists(keys.ship("hover")), 60, "the worker")
    k = shard_of("hover", 2)
    pipe = client.pipeline(transaction=False)
    bob = None
    for i in range(20_000):
        pipe.xadd(keys.shard_commands(k), {"cmd": "throttle", "ship_id": "hover",
                                           "player_id": "player-hover", "value": "0.5"})
        sid = f"ghost-{i}"
        pipe.xadd(keys.shard_commands(shard_of(sid, 2)),
                  {"cmd": "throttle", "ship_id": sid, "player_id": "p", "value": "0.5"})
        if i == 5000:  # another player, once, in the middle of the flood
            pipe.xadd(keys.shard_commands(k), {"cmd": "throttle", "ship_id": "hover",
                                               "player_id": "bob", "value": "1"})
            bob = len(pipe.command_stack) - 1
        if i % 2000 == 1999:
            got = pipe.execute()
            if bob is not None and isinstance(bob, int):
                bob = got[bob].decode()
    big = json.dumps({"initial": {"altitude": 100.0}, "description": "x" * (64 * 1024 - 100)})
    for i in range(300):
        sid = f"big-{i}"
        pipe.xadd(keys.shard_commands(shard_of(sid, 2)),
                  {"cmd": "spawn", "ship_id": sid, "player_id": "p", "ship": big[:64 * 1024]})
    pipe.execute()
    th.join(timeout=180)
    assert not th.is_alive()
    fig = w.last_figures
    events = _events(client, keys.events)
    rejections = [e for e in events if e["event"] == "ship.command_rejected"]
    per_tick: dict[tuple, int] = {}
    for e in rejections:
        key = (e["seq"].split(":")[0], e["tick"], e["player_id"])
        per_tick[key] = per_tick.get(key, 0) + 1
    assert max(per_tick.values()) <= 100
    assert {e["player_id"] for e in rejections} >= {"p", "player-hover", "bob"}
    to_bob = [e for e in rejections if e["player_id"] == "bob"]
    assert len(to_bob) == 1 and to_bob[0]["entry_id"] == bob, to_bob
    assert to_bob[0]["owner_id"] == "player-hover"
    assert to_bob[0]["stream"] == keys.shard_commands(k)
    assert fig["rejected"] >= 40_000 - 400
    assert fig["rejections_unpublished"] == fig["rejected"] - len(rejections)
    assert fig["dropped"] == 0
    applied = {}
    for path in _files(worker.dir / f"shard-{k:03d}"):
        with LogReader(path) as r:
            for c in r.timeline().commands:
                if c.ship_id == "hover" and c.tick > 0:  # (tick 0: the scenario's)
                    applied.setdefault(c.tick, c)
    # every throttle the results stream calls applied is in the log, at one tick each
    results = [json.loads(f[b"results"]) for _id, f in client.xrange(keys.shard_results(k))]
    applied_ids = [i for r in results for i in r.get(keys.shard_commands(k), {})
                   .get("applied", [])]
    assert len(applied_ids) == len(applied) > 0
    assert fig["tick_p99_ms"] < 1000
    client.close()


def test_operators_see_stats_lines_a_stats_hash_with_a_ttl_and_prometheus_metrics(worker):
    port = _free_port()
    w, th = worker(rate_hz=50.0, stats_every_s=0.5, metrics_port=port,
                   log_max_bytes=20_000, log_max_total_bytes=100_000)
    client = redis.Redis.from_url(worker.url)
    key = Keys(worker.prefix).stats(w.id)
    try:
        _wait(lambda: client.exists(key), 30, "the stats hash")
        assert 0 < client.ttl(key) <= 2
        fig = {k.decode(): v.decode() for k, v in client.hgetall(key).items()}
        for name in ("tick", "tick_p50_ms", "tick_p99_ms", "ships", "held", "lag_s",
                     "late_share", "commands_per_s", "events_per_s", "dropped",
                     "rejections_unpublished", "redis", "redis_down_s", "logs_paused",
                     "shard_ticks", "shard_step_ms", "version"):
            assert name in fig, name
        assert fig["redis"] == "up" and fig["logs_paused"] == "0"
        assert set(json.loads(fig["shard_ticks"])) == {"0", "1"}
        body = urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=5).read()
        text = body.decode()
        for name in ("touchdown_tick_seconds_bucket", "touchdown_ships ",
                     "touchdown_late_ticks_total", "touchdown_commands_applied_total",
                     "touchdown_commands_rejected_total", "touchdown_lag_seconds",
                     "touchdown_held_entries", "touchdown_rejections_unpublished_total",
                     "touchdown_redis_up 1.0", 'touchdown_redis_state{state="up"} 1.0',
                     "touchdown_logs_paused 0.0", 'touchdown_shard_tick{shard="0"',
                     'touchdown_shard_step_seconds{shard="1"', "touchdown_build_info{"):
            assert name in text, name
        line = next(json.loads(ln) for ln in w.said if '"stats"' in ln)
        for name in ("time", "level", "worker", "tick", "tick_p99_ms", "ships", "held"):
            assert name in line
        time.sleep(2.0)
        for folder in worker.dir.iterdir():  # retention: each shard's folder stays bounded
            total = sum(p.stat().st_size for p in folder.iterdir())
            assert total < 100_000 + 3 * 20_000, total
    finally:
        w.stop.set()
        th.join(timeout=60)
        client.close()
    assert not client.exists(key)  # a clean stop removes its health key


# -- the costs ----------------------------------------------------------------------------------
def test_a_spawn_of_a_class_already_seen_costs_microseconds():
    scene = FLEET.scene
    scene.ship({"id": "warm", "initial": {"altitude": 300.0}})
    t0 = time.perf_counter()
    for i in range(2000):
        ships, state = scene.ship({"id": f"x{i}", "player_id": f"p{i}",
                                   "initial": {"altitude": 300.0}})
    each = (time.perf_counter() - t0) / 2000
    assert ships.ship_id == ("x1999",) and ships.player_id == ("p1999",)
    assert each < 300e-6, each  # about 25 us here; the first of a class about 1 ms


def test_checkpoints_of_ten_thousand_ships_stay_under_a_megabyte_a_second():
    from touchdown.bench.speed import fleet_doc
    from touchdown.sim.scenario import parse
    from touchdown.sim.world import World
    doc = fleet_doc(10_000, 3600.0)
    doc["sim"] = {"dt": 0.1}
    world = World.of(parse(doc, "ckpt"))
    for _ in world.blocks(20):
        pass
    blob = rio.checkpoint_blob(0, 1, world, [], 0)
    every = ServeConfig().checkpoint_every
    rate = len(blob) * (1 / 0.1) / every
    assert rate < 1e6, rate
    cp, state, inputs = rio.read_checkpoint(blob)
    assert (state.rows == world.state.rows).all() and state.tick == world.tick


def test_a_long_tick_keeps_its_lease_and_the_late_count_survives_it(redis_url, tmp_path):  # noqa: F811,E501
    """A 1.5 s tick at 20 ticks a second with a 0.4 s lease: the lease is renewed meanwhile (no
    shard lost), and the 29 or more periods missed are counted."""
    prefix = _prefix()
    said: list[str] = []
    w = Worker(ServeConfig(url=redis_url, prefix=prefix, rate_hz=20.0, ticks=12, shards=1,
                           lease_s=0.4, log_dir=tmp_path / "flight"), say=said.append)
    real = w.loop_once
    calls = []

    grabbed = []
    client = redis.Redis.from_url(redis_url)

    def loop_once():
        calls.append(1)
        if len(calls) == 5:  # a 1.5 s tick: meanwhile another worker tries to take the shard
            time.sleep(1.0)
            grabbed.append(client.set(Keys(prefix).shard(0, "owner"), "intruder", nx=True,
                                      px=5000))
            time.sleep(0.5)
        real()
    w.loop_once = loop_once
    try:
        stats = w.run()
    finally:
        _cleanup(redis_url, prefix)
    client.close()
    assert grabbed == [None]  # the lease was held throughout
    assert stats.late >= 29, stats.late
    assert not [line for line in said if "lost" in line], said
    assert sum(": taken (" in line for line in said) == 1


def test_view_redis_draws_the_running_fleet(worker, tmp_path):
    """`touchdown view --redis URL` follows the telemetry and event streams of a running service
    into Rerun (here to an .rrd, and a screenshot where software Vulkan is installed)."""
    w, th = worker(rate_hz=40.0, telemetry_hz=10.0, stats_every_s=0.5)
    client = redis.Redis.from_url(worker.url)
    try:
        _wait(lambda: client.xlen(f"{worker.prefix}:telemetry") > 5, 60, "telemetry")
        _wait(lambda: client.exists(Keys(worker.prefix).stats(w.id)), 30, "the stats hash")
        out = tmp_path / "live.rrd"
        done = subprocess.run(_cli("view", "--redis", worker.url, "--prefix", worker.prefix,
                                   "--seconds", "2", "-o", str(out)), capture_output=True,
                              text=True, timeout=120)
        assert done.returncode == 0, done.stderr
        assert out.exists() and out.stat().st_size > 1000
        n = int(done.stdout.split(":")[1].split()[0].replace(",", ""))
        assert n > 5
        from touchdown.view import live  # the service's health, as the view draws it
        workers = live.health(client, Keys(worker.prefix))
        assert [w["worker"] for w in workers] == [w.id]
        assert set(workers[0]["shards"]) == {0, 1}
        table = live.health_table(workers)
        assert w.id in table and "tick p50 / p99 ms" in table
        import rerun.chunk as rc
        seen = {ch.entity_path for ch in rc.RrdReader(out).stream().to_chunks()}
        assert "/health/workers" in seen and f"/health/{w.id}/tick_p99_ms" in seen, sorted(seen)
        icd = Path("/usr/share/vulkan/icd.d")
        if icd.is_dir() and any(icd.glob("lvp_icd*.json")):
            png = tmp_path / "live.png"
            done = subprocess.run(_cli("view", "--redis", worker.url, "--prefix",
                                       worker.prefix, "--seconds", "2", "--screenshot",
                                       str(png)), capture_output=True, text=True, timeout=180)
            assert done.returncode == 0, done.stderr
            assert png.stat().st_size > 1000
        bad = subprocess.run(_cli("view", "--redis", "http://:pw@127.0.0.1:1/0", "-o",
                                  str(tmp_path / "x.rrd")), capture_output=True, text=True,
                             timeout=60)
        assert bad.returncode == 2 and "Traceback" not in bad.stderr and "pw" not in bad.stderr
    finally:
        w.stop.set()
        th.join(timeout=60)
        client.close()


def test_a_worker_cut_off_past_its_lease_marks_the_ticks_its_successor_superseded(tmp_path):
    """Worker a cannot journal (its ACL user loses EVAL: the journal, the events and the lease
    renewals are refused) and steps on; a throttle it reads meanwhile it does not apply (a
    command is applied only once journaled: 0.7.0 applied it, and the logs held it twice
    unless read up to the mark below); its lease runs out and worker b takes the shard over
    from the checkpoint and journal, claims the throttle (pending, never journaled) and applies
    it. When a can write again it finds its lease gone and closes its log "lost", its summary
    naming the last tick Redis holds of it (superseded_after_tick). Every log together holds the
    throttle once."""
    server, port = _server(tmp_path / "redis")
    admin = redis.Redis(port=port)
    prefix = "g"
    flight = tmp_path / "flight"
    a = b = None
    try:
        _ready(admin)
        _acl(admin, "wa", "apw", prefix, "~P:*", WORKER_ACL)
        keys = Keys(prefix)
        args = ["serve", "--prefix", prefix, "--shards", "1", "--rate", "40", "--lease", "1",
                "--checkpoint-every", "10", "--log-dir", str(flight)]
        a = _Proc([*args, "--redis", f"redis://wa:apw@127.0.0.1:{port}/0", "--worker-id", "a"],
                  tmp_path, "a")
        _wait(lambda: admin.get(keys.shard(0, "owner")) == b"a", 60, "a to own the shard")
        admin.xadd(keys.shard_commands(0), _spawn("s0", "p0", altitude=50.0))
        _wait(lambda: admin.exists(keys.ship("s0")), 30, "the spawn")
        _wait(lambda: admin.get(keys.shard(0, "checkpoint")) is not None, 30, "a checkpoint")
        admin.execute_command("ACL", "SETUSER", "wa", "-eval")
        _wait(lambda: "NOPERM" in a.err(), 30, "a to be refused")
        tick = int(admin.get(keys.shard(0, "tick")))
        time.sleep(0.3)  # a steps on, a dozen ticks past what Redis holds of it
        # a throttle read for a whose reply never reached it (a read cut off with its master:
        # made so here as in the test above); a, refused, re-reads its own pending entries each
        # tick, finds it and applies it at a tick past what Redis holds
        pipe = admin.pipeline(transaction=True)
        pipe.xadd(keys.shard_commands(0), {"cmd": "throttle", "ship_id": "s0",
                                           "player_id": "p0", "value": "0.25"})
        pipe.xreadgroup(Keys.group(0), "a", {keys.shard_commands(0): ">"}, count=10)
        eid = pipe.execute()[0].decode()
        _wait(lambda: admin.get(keys.shard(0, "owner")) is None, 30, "a's lease to run out")
        b = _Proc([*args, "--redis", f"redis://127.0.0.1:{port}/0", "--worker-id", "b"],
                  tmp_path, "b")
        _wait(lambda: "1 unjournaled commands claimed" in b.err(), 60, "b to take the shard")
        mark = int(admin.get(keys.shard(0, "tick")))
        _wait(lambda: int(admin.get(keys.shard(0, "tick"))) > mark + 20, 30, "b to step on")
        admin.execute_command("ACL", "SETUSER", "wa", "+eval")
        _wait(lambda: "shard 0: lost" in a.err(), 30, "a to find its lease gone")
        assert a.term() == 0 and b.term() == 0, a.err() + b.err()
        assert "Traceback" not in a.err() + b.err()
        _j, throttles, _l = _from_logs(flight)
        assert len(throttles[("s0", 0.25)]) == 1, throttles[("s0", 0.25)]
        lost = []
        for path in _files(flight):
            with LogReader(path) as r:
                s = r.read_summary()
                if s is not None and s.reason == "lost":
                    lost.append((path, s))
        assert len(lost) == 1 and lost[0][1].HasField("superseded_after_tick"), lost
        with LogReader(lost[0][0]) as r:  # a never applied it: it could not journal it
            mine = [c.tick for c in r.timeline().commands if c.throttle == 0.25]
        assert lost[0][1].superseded_after_tick == tick, (tick, lost)
        assert not mine, (mine, tick)
        events = _events(admin, keys.events)
        assert eid not in {e.get("entry_id") for e in events}
        _gapless(events, 1)
        assert admin.xpending(keys.shard_commands(0), Keys.group(0))["pending"] == 0
        _all_verify(flight)
    finally:
        for p in (a, b):
            if p is not None:
                p.kill()
        admin.close()
        _stop(server)
