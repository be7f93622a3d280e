"""``touchdown serve`` against a real Redis (SPEC.md section 5): events out with the seed's fields
and in order, commands in at the tick recorded, rejections, each ship's hash, the flight logs
verifying, a clean stop, a Redis restart with nothing lost or doubled, two workers and a takeover,
the landing autopilot."""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import pytest
import redis

import touchdown.scenarios as builtin
from touchdown.logs.reader import LogReader
from touchdown.proto import touchdown_pb2 as pb
from redis_server import _free_port, redis_url  # noqa: F401  (a pytest fixture)
from touchdown.replay.verify import verify
from touchdown.service.commands import shard_of
from touchdown.service.redis_io import Keys
from touchdown.service.serve import ServeConfig, Worker
from touchdown.sim.scenario import parse_text

pytestmark = pytest.mark.redis

ROOT = Path(__file__).resolve().parents[1]
FLEET = parse_text(builtin.text("fleet"), "fleet")


def _key(prefix: str, k: int, what: str) -> str:
    return Keys(prefix).shard(k, what)


def _prefix() -> str:
    return f"test:serve:{uuid.uuid4().hex[:10]}"


def _cleanup(url: str, prefix: str) -> None:
    client = redis.Redis.from_url(url)
    keys = list(client.scan_iter(f"{prefix}:*", count=1000))
    if keys:
        client.delete(*keys)
    client.close()


@pytest.fixture
def service(redis_url, tmp_path):  # noqa: F811
    """Start workers in threads of this process; cleans the prefix's keys afterwards."""
    prefix = _prefix()
    workers = []

    def start(**kw) -> tuple[Worker, threading.Thread]:
        cfg = ServeConfig(url=redis_url, prefix=prefix, log_dir=tmp_path / "flight",
                          **{"rate_hz": 0.0, "shards": 2, **kw})
        w = Worker(cfg, say=lambda line: said.append(line))
        th = threading.Thread(target=w.run, daemon=True)
        th.start()
        workers.append((w, th))
        return w, th

    said: list[str] = []
    start.prefix, start.said, start.url, start.dir = prefix, said, redis_url, tmp_path / "flight"
    yield start
    for w, th in workers:
        w.stop.set()
        th.join(timeout=30)
    _cleanup(redis_url, prefix)


def _fields(raw: dict) -> dict:
    return {k.decode(): v for k, v in raw.items()}


def _events(url: str, stream: str) -> list[dict]:
    client = redis.Redis.from_url(url)
    out = [_fields(f) for _id, f in client.xrange(stream)]
    client.close()
    return out


def _logs(folder: Path) -> list[Path]:
    return sorted(folder.rglob("*.mcap"))


def _logged_events(folder: Path) -> dict[int, list[pb.TransitionEvent]]:
    """The transition events of the flight logs of each shard, in tick order, each once."""
    by_shard: dict[int, dict] = {}
    for path in _logs(folder):
        k = int(path.parent.name.split("-")[1])
        with LogReader(path) as r:
            for ev in r.events():
                by_shard.setdefault(k, {})[(ev.tick, ev.ship_id, ev.event)] = ev
    return {k: [v[key] for key in sorted(v, key=lambda x: x[0])] for k, v in by_shard.items()}


def _wait(pred, timeout: float = 30.0, what: str = "") -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return
        time.sleep(0.02)
    raise AssertionError(f"timed out waiting for {what}")


def test_events_arrive_with_the_seeds_fields_in_order_and_logs_verify(service):
    w, th = service(scenario=FLEET, source="fleet", ticks=400)
    th.join(timeout=120)
    slowest = w.slow.slowest()  # what the slowest loops spent their time on
    assert len(slowest) == 20 and slowest[0]["tick_s"] == round(max(w.stats.tick_s), 4)
    assert [x["tick_s"] for x in slowest] == sorted((x["tick_s"] for x in slowest), reverse=True)
    for x in slowest:  # each one's phases (some nest: redis_io within flush), within its time
        assert set(x["phases"]) <= set(w.stats.phases)
        assert max(x["phases"].values(), default=0.0) <= x["tick_s"] + 1e-4
    assert any(x["phases"] for x in slowest)
    events = _events(service.url, f"{service.prefix}:ships")
    transitions = [e for e in events if e["event"].decode().startswith("ship.")]
    assert len(transitions) > 5
    for e in transitions:
        for name in ("event", "ship_id", "player_id", "body", "tick", "proto", "seq"):
            assert name in e, name
        assert e["body"] == b"Luna"
    # each shard's entries in order, numbered without gaps, the same as its flight logs
    logged = _logged_events(service.dir)
    for k in (0, 1):
        mine = [e for e in transitions if e["seq"].decode().startswith(f"{k}:")]
        assert [int(e["seq"].decode().split(":")[1]) for e in mine] == list(range(len(mine)))
        assert [pb.TransitionEvent.FromString(e["proto"]) for e in mine] == logged.get(k, [])
        ticks = [int(e["tick"]) for e in mine]
        assert ticks == sorted(ticks)
    # each ship's hash: its state now, the seed's surface_contact_state and landed_body_name
    client = redis.Redis.from_url(service.url)
    for sid in FLEET.params.ships.ship_id:
        h = _fields(client.hgetall(f"{service.prefix}:ship:{sid}"))
        with_ship = [e for e in transitions if e["ship_id"].decode() == sid]
        if with_ship:
            last = pb.TransitionEvent.FromString(with_ship[-1]["proto"])
            assert h["surface_contact_state"].decode() == last.ship.surface_contact_state
            assert h["tick"].decode() == str(last.tick)
            assert h["landed_body_name"] == (b"" if last.ship.surface_contact_state == ""
                                             else b"Luna")
    client.close()
    for path in _logs(service.dir):
        assert verify(str(path)).identical, path
    # the shards' keyframes staggered (every 10 ticks: shard 0's at 0, 10, ...; shard 1's at 5,
    # 15, ...), so that no tick encodes both
    phases = {}
    for path in _logs(service.dir):
        k = int(path.parent.name.split("-")[1])
        with LogReader(path) as r:
            phases[k] = r.keyframe_phase
            keyframes = {td.tick for td in r.ticks() if td.is_keyframe} - {r.start_tick}
        assert len(keyframes) >= 30 and {t % 10 for t in keyframes} == {phases[k]}, path
    assert phases == {0: 0, 1: 5}


def test_the_flush_behind_the_tick_publishes_what_the_flush_in_the_tick_does(redis_url,  # noqa: F811,E501
                                                                              tmp_path):
    """flush_behind (the default: the flush's round trip on a thread, its replies taken at the
    next loop's start) and the flush waited for in the tick: the same entries, numbered the
    same, and the same ships' hashes (written by HASHES scripts)."""
    got = []
    for behind in (True, False):
        prefix = _prefix()
        try:
            cfg = ServeConfig(url=redis_url, prefix=prefix, log_dir=tmp_path / f"flight{behind}",
                              rate_hz=0.0, shards=2, scenario=FLEET, source="fleet", ticks=200,
                              flush_behind=behind)
            w = Worker(cfg, say=lambda line: None)
            w.run()
            assert w._flushing is None  # the last flush's replies taken at the stop
            events = [{k: v for k, v in e.items()} for e in _events(redis_url, f"{prefix}:ships")]
            client = redis.Redis.from_url(redis_url)
            hashes = {sid: _fields(client.hgetall(f"{prefix}:ship:{sid}"))
                      for sid in FLEET.params.ships.ship_id}
            client.close()
            got.append((events, hashes))
        finally:
            _cleanup(redis_url, prefix)
    (ev_a, h_a), (ev_b, h_b) = got
    assert len([e for e in ev_a if e["event"].startswith(b"ship.")]) > 5
    assert sorted(ev_a, key=lambda e: e["seq"]) == sorted(ev_b, key=lambda e: e["seq"])
    assert h_a == h_b and all(h_a.values())


def test_a_command_changes_the_ship_at_the_tick_recorded(service):
    """A throttle command is applied at the tick the service reads it and recorded there: the
    flight log's command record and the ship's inputs from the next tick on say the same."""
    w, th = service(scenario=FLEET, source="fleet", ticks=300, rate_hz=200.0)
    client = redis.Redis.from_url(service.url)
    _wait(lambda: client.exists(f"{service.prefix}:ship:hover"), what="the service to start")
    time.sleep(0.2)
    client.xadd(f"{service.prefix}:commands", {"cmd": "throttle", "ship_id": "hover",
                                               "value": "0.25", "player_id": "player-hover"})
    th.join(timeout=120)
    client.close()
    k = shard_of("hover", 2)
    found = []
    for path in _logs(service.dir / f"shard-{k:03d}"):
        with LogReader(path) as r:
            found += [c for c in r.timeline().commands if c.ship_id == "hover"
                      and c.throttle == 0.25]
            applied = {t.tick: float(t.arrays["input_throttle"][list(t.keys).index(
                r.ship_table().key("hover"))]) for t in r.ticks()}
        assert verify(str(path)).identical
    assert len(found) == 1
    tick = found[0].tick
    assert applied[tick + 1] == 0.25 and applied[tick] != 0.25
    assert 0 < tick < 300


HOSTILE = [
    ({"cmd": "throttle", "ship_id": "hover", "value": "nan"}, "value"),
    ({"cmd": "throttle", "ship_id": "hover", "value": "1e308"}, "value"),
    ({"cmd": "throttle", "ship_id": "hover", "value": "0x1p3"}, "value"),
    ({"cmd": "throttle", "ship_id": "nobody", "value": "0.5"}, "no ship"),
    ({"cmd": "rcs", "ship_id": "hover", "x": "1", "y": "0", "z": "0", "w": "1"}, "unknown field"),
    ({"cmd": "rcs", "ship_id": "hover", "x": "2", "y": "0", "z": "0"}, "x must be"),
    ({"cmd": "hold", "ship_id": "hover", "mode": "sideways"}, "mode must be"),
    ({"cmd": "warp", "ship_id": "hover"}, "unknown command"),
    ({"ship_id": "hover"}, "unknown command"),
    ({"cmd": "throttle", "value": "0.5"}, "ship_id"),
    ({"cmd": "spawn", "ship_id": "hover", "ship": "{}"}, "taken"),
    ({"cmd": "spawn", "ship_id": "new-1", "ship": "[1, 2"}, "not valid JSON"),
    ({"cmd": "spawn", "ship_id": "new-2", "ship": '{"initial": {"altitude": "high"}}'},
     "altitude"),
    ({"cmd": "spawn", "ship_id": "new-3", "ship": '{"id": "other"}'}, "not ship_id"),
    ({"cmd": "retire", "ship_id": "nobody"}, "no ship"),
    ({"cmd": "throttle", "ship_id": "hover", "value": "0.5", "x" * 100: "1"}, "field"),
    ({"cmd": "spawn", "ship_id": "big", "ship": "[" * 100_000}, "longer than"),
    ({"cmd": "throttle", "ship_id": "hover\x00", "value": "0.5"}, "printable"),
]


def test_malformed_and_hostile_commands_are_rejected_and_the_loop_goes_on(service):
    w, th = service(scenario=FLEET, source="fleet", ticks=250, rate_hz=200.0)
    client = redis.Redis.from_url(service.url)
    _wait(lambda: client.exists(f"{service.prefix}:ship:hover"), what="the service to start")
    ids = {}
    for entry, why in HOSTILE:
        if "cmd" in entry and "ship_id" in entry:
            entry = {**entry, "player_id": "player-hover"}
        ids[client.xadd(f"{service.prefix}:commands", entry).decode()] = why
    client.xadd(f"{service.prefix}:commands",
                {"cmd": "spawn", "ship_id": "late", "player_id": "p-1", "ship": json.dumps(
                    {"initial": {"altitude": 2.0, "vertical_speed": -3.0}})})
    th.join(timeout=120)
    events = _events(service.url, f"{service.prefix}:ships")
    rejected = {e["entry_id"].decode(): e for e in events
                if e["event"] == b"ship.command_rejected"}
    assert set(rejected) == set(ids)
    for eid, why in ids.items():
        assert why in rejected[eid]["reason"].decode(), (why, rejected[eid]["reason"])
        assert "\n" not in rejected[eid]["reason"].decode()
    # the loop went on: every tick ran, and the good spawn after them flew and touched down
    assert w.stats.ticks == 250
    assert any(e["event"] == b"ship.contact" and e["ship_id"] == b"late" for e in events)
    # nothing is left pending in any shard's group
    for k in (0, 1):
        for group in client.xinfo_groups(Keys(service.prefix).shard_commands(k)):
            assert group["pending"] == 0
    client.close()


def _private_redis(tmp: Path, port: int) -> subprocess.Popen:
    """A redis-server of the test's own that keeps its data on disk (fsync on every write), so
    that stopping and starting it again loses nothing of what it acknowledged."""
    binary = shutil.which("redis-server")
    if binary is None:
        pytest.fail("the Redis restart test needs redis-server on PATH")
    proc = subprocess.Popen([binary, "--port", str(port), "--bind", "127.0.0.1", "--dir",
                             str(tmp), "--appendonly", "yes", "--appendfsync", "always",
                             "--save", ""], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    client = redis.Redis(port=port)
    _wait(lambda: _pings(client), 10, "redis-server to start")
    client.close()
    return proc


def _pings(client) -> bool:
    try:
        return bool(client.ping())
    except redis.exceptions.RedisError:
        return False


def _cli(*args: str) -> list[str]:
    return [sys.executable, str(ROOT / "cli.py"), *args]


def test_redis_stopped_and_restarted_loses_and_doubles_nothing(tmp_path):
    """Redis goes away for about a second mid-run: the service ticks on, says so, holds its
    events and delivers them after; the stream then holds each shard's entries exactly once, in
    order, and they are the flight logs' events."""
    port = _free_port()
    data = tmp_path / "redis"
    data.mkdir()
    server = _private_redis(data, port)
    url = f"redis://127.0.0.1:{port}/0"
    flight = tmp_path / "flight"
    proc = subprocess.Popen(_cli("serve", "--redis", url, "--scenario", "fleet", "--rate", "100",
                                 "--ticks", "500", "--log-dir", str(flight), "--shards", "2",
                                 "--lease", "10"),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        client = redis.Redis(port=port)
        _wait(lambda: client.exists("galaxy:ship:hover"), 60, "the service to start")
        time.sleep(0.5)
        client.close()
        server.send_signal(signal.SIGKILL)  # the worst way to go: no goodbye to clients
        server.wait()
        time.sleep(1.0)
        server = _private_redis(data, port)
        out, err = proc.communicate(timeout=120)
        assert proc.returncode == 0, err
        assert "unreachable" in err and "back after" in err
        events = _events(url, "galaxy:ships")
        logged = _logged_events(flight)
        for k in (0, 1):
            mine = [e for e in events if e["seq"].decode().startswith(f"{k}:")]
            numbers = [int(e["seq"].decode().split(":")[1]) for e in mine]
            assert numbers == list(range(len(mine)))  # none lost, none twice, in order
            assert [pb.TransitionEvent.FromString(e["proto"]) for e in mine] == logged.get(k, [])
        assert sum(len(v) for v in logged.values()) > 5
    finally:
        proc.kill()
        server.kill()
        server.wait()


def test_sigterm_finishes_the_tick_flushes_and_closes_the_logs(redis_url, tmp_path):  # noqa: F811
    prefix = _prefix()
    flight = tmp_path / "flight"
    proc = subprocess.Popen(_cli("serve", "--redis", redis_url, "--scenario", "fleet",
                                 "--prefix", prefix, "--log-dir", str(flight), "--shards", "2"),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    client = redis.Redis.from_url(redis_url)
    try:
        _wait(lambda: int(client.get(_key(prefix, 0, "tick")) or 0) > 30, 60, "30 ticks")
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=60)
        assert proc.returncode == 0, err
        assert "Traceback" not in err
        files = _logs(flight)
        assert files and not list(flight.rglob("*.partial"))
        for path in files:
            assert verify(str(path)).identical
            with LogReader(path) as r:
                summary = r.read_summary()
            assert summary.complete
        # the leases are free and each shard's checkpoint is the tick its log ends at
        for k in (0, 1):
            assert client.get(_key(prefix, k, "owner")) is None
            assert client.get(_key(prefix, k, "checkpoint")) is not None
    finally:
        proc.kill()
        client.close()
        _cleanup(redis_url, prefix)


def _ticks_by_ship(folder: Path) -> dict[str, set[int]]:
    out: dict[str, set[int]] = {}
    for path in _logs(folder) + sorted(folder.rglob("*.partial")):
        with LogReader(path) as r:
            table = r.ship_table()
            for t in r.ticks():
                for key in t.keys:
                    out.setdefault(table.ids[int(key)], set()).add(t.tick)
    return out


def test_two_workers_share_the_ships_and_one_takes_over_when_the_other_dies(redis_url, tmp_path):  # noqa: F811,E501
    prefix = _prefix()
    flight = tmp_path / "flight"
    args = ["serve", "--redis", redis_url, "--scenario", "fleet", "--prefix", prefix,
            "--log-dir", str(flight), "--shards", "2", "--lease", "0.6", "--rate", "40",
            "--checkpoint-every", "10"]
    a = subprocess.Popen(_cli(*args, "--worker-id", "a"), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    client = redis.Redis.from_url(redis_url)
    b = None
    try:
        _wait(lambda: client.get(_key(prefix, 1, "owner")) == b"a", 60, "a to own shard 1")
        b = subprocess.Popen(_cli(*args, "--worker-id", "b"), stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
        owners = lambda: {client.get(_key(prefix, k, "owner")) for k in (0, 1)}  # noqa: E731
        _wait(lambda: owners() == {b"a", b"b"}, 60, "a shard each")
        time.sleep(1.0)
        mine = next(k for k in (0, 1) if client.get(_key(prefix, k, "owner")) == b"a")
        a.send_signal(signal.SIGKILL)
        a.wait()
        killed_at = time.monotonic()
        _wait(lambda: client.get(_key(prefix, mine, "owner")) == b"b", 30, "b to take over")
        took = time.monotonic() - killed_at
        assert took < 0.6 + 1.0  # the lease, then within a few ticks
        tick_then = int(client.get(_key(prefix, mine, "tick")))
        _wait(lambda: int(client.get(_key(prefix, mine, "tick"))) > tick_then + 20, 30,
              "b to step the shard on")
        b.send_signal(signal.SIGTERM)
        _out, err = b.communicate(timeout=60)
        assert b.returncode == 0, err
        assert f"shard {mine}: taken (from its checkpoint" in err
        # every log of both workers (a's last one cut off by the kill) replays exactly
        for path in _logs(flight) + sorted(flight.rglob("*.partial")):
            res = verify(str(path))
            assert res.divergence is None, (path, res.report())
        # and together they hold every tick of every ship, from 0 to where b stopped
        end = int(client.get(_key(prefix, mine, "tick")))
        ticks = _ticks_by_ship(flight)
        for sid in FLEET.params.ships.ship_id:
            if shard_of(sid, 2) == mine:
                assert set(range(end + 1)) <= ticks[sid], sid
        # the event stream holds each of the shard's entries once, in order
        events = [e for e in _events(redis_url, f"{prefix}:ships")
                  if e["seq"].decode().startswith(f"{mine}:")]
        numbers = [int(e["seq"].decode().split(":")[1]) for e in events]
        assert numbers == list(range(len(events)))
    finally:
        for p in (a, b):
            if p is not None:
                p.kill()
        client.close()
        _cleanup(redis_url, prefix)


def test_autoland_flies_a_spawned_ship_down_and_reports_it(service):
    """spawn, then autoland: the ship is flown down by recorded commands, lands, the service
    reports ``ship.autoland_complete`` (result landed) and its hash says landed; retire then
    removes it. The shard's flight logs replay it exactly."""
    w, th = service(ticks=1500, rate_hz=0.0)  # room after the landing for the retire, under load
    client = redis.Redis.from_url(service.url)
    commands = f"{service.prefix}:commands"
    p7 = {"player_id": "p-7"}
    client.xadd(commands, {"cmd": "spawn", "ship_id": "ap-1", **p7, "ship": json.dumps(
        {"initial": {"altitude": 300.0, "vertical_speed": -20.0}})})
    client.xadd(commands, {"cmd": "autoland", "ship_id": "ap-1", **p7})  # waits for the join
    _wait(lambda: client.exists(f"{service.prefix}:ship:ap-1"), 60, "the ship to join")
    client.xadd(commands, {"cmd": "autoland", "ship_id": "ap-1", **p7})
    hash_key = f"{service.prefix}:ship:ap-1"
    _wait(lambda: client.hget(hash_key, "state") == b"landed", 120, "the ship to land")
    client.xadd(commands, {"cmd": "retire", "ship_id": "ap-1", **p7})
    th.join(timeout=120)
    events = [e for e in _events(service.url, f"{service.prefix}:ships")
              if e["ship_id"] == b"ap-1"]
    kinds = [e["event"].decode() for e in events]
    assert "ship.command_rejected" not in kinds  # the autoland sent with the spawn waited for it
    assert kinds[-1] == "ship.retired"
    assert "ship.contact" in kinds and "ship.landed" in kinds and "ship.crashed" not in kinds
    done = [e for e in events if e["event"] == b"ship.autoland_complete"]
    assert len(done) == 1 and done[0]["result"] == b"landed" and done[0]["player_id"] == b"p-7"
    contact = pb.TransitionEvent.FromString(
        next(e for e in events if e["event"] == b"ship.contact")["proto"])
    assert -3.0 < contact.v_radial_mps < 0.0  # a soft touchdown
    assert not client.exists(hash_key)  # retired
    client.close()
    for path in _logs(service.dir / f"shard-{shard_of('ap-1', 2):03d}"):
        assert verify(str(path)).identical


def test_lines_said_from_several_threads_stay_whole_lines(capfd):
    """The tick loop, the lease thread and the reporter all log: each JSON line on stderr is a
    line of its own however their writes interleave (print() wrote a line and its newline
    separately, and CI once read two of them run together)."""
    import json as _json
    import sys as _sys
    import threading as _threading
    from touchdown.service.serve import _say_on_stderr
    interval = _sys.getswitchinterval()
    _sys.setswitchinterval(1e-6)  # switch threads as often as CPython lets them
    try:
        def talk(k):
            for i in range(400):
                _say_on_stderr(_json.dumps({"thread": k, "i": i, "msg": "x" * (k * 7 % 50)}))
        threads = [_threading.Thread(target=talk, args=(k,)) for k in range(6)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    finally:
        _sys.setswitchinterval(interval)
    lines = capfd.readouterr().err.splitlines()
    assert len(lines) == 6 * 400
    seen = {(d["thread"], d["i"]) for d in map(_json.loads, lines)}
    assert len(seen) == 6 * 400
