"""``touchdown serve --redis-cluster`` on a real Redis Cluster (issue 24): three masters of private
redis-servers on loopback (tests/redis_cluster.py), two workers, spawns, throttles and retires
written to the shards' command streams; then one worker SIGKILLed, or one master of the cluster
SIGKILLed and started again on its data. Every spawn joins once, every throttle is applied at one
tick or rejected once, every retire gives one ``ship.retired``, each shard's event stream
``P:ships:{k}`` has a gapless ``seq``, each ship's hash is its state in the flight logs, and every
flight log verifies (``touchdown replay LOG --verify``)."""
from __future__ import annotations

import subprocess
import sys
import time

import pytest

from touchdown.bench.redis_cluster import Cluster
from redis_server import redis_url  # noqa: F401  (a pytest fixture)
from touchdown.service.commands import shard_of
from touchdown.service.redis_io import Keys
from test_serve_ops import ROOT, WORKER_ACL, _acl, _cli, _events, _files, _gapless, _nothing_lost, \
    _prefix, _Proc, _traffic, _wait

pytestmark = [pytest.mark.redis, pytest.mark.slow]

SHARDS = 4


@pytest.fixture
def cluster(tmp_path):
    c = Cluster(tmp_path / "cluster")
    try:
        yield c
    finally:
        c.stop()


def _replay_verify(folder) -> None:
    files = _files(folder)
    assert files
    for path in files:
        out = subprocess.run([sys.executable, str(ROOT / "cli.py"), "replay", str(path),
                              "--verify"], capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, (path, out.stdout[-2000:], out.stderr[-2000:])


@pytest.mark.parametrize("what", ["a worker killed", "a master restarted"])
def test_on_a_redis_cluster_a_takeover_or_a_master_restart_loses_and_doubles_nothing(
        cluster, tmp_path, what):
    prefix = _prefix()
    flight = tmp_path / "flight"
    args = ["serve", "--redis-cluster", cluster.url, "--prefix", prefix, "--log-dir",
            str(flight), "--shards", str(SHARDS), "--lease", "0.6", "--rate", "40",
            "--checkpoint-every", "10"]
    client = cluster.client()
    keys = Keys(prefix, cluster=True)
    owners = lambda: {client.get(keys.shard(k, "owner")) for k in range(SHARDS)}  # noqa: E731
    a = _Proc([*args, "--worker-id", "a"], tmp_path, "a")
    b = None
    try:
        _wait(lambda: owners() == {b"a"}, 60, "a to own the shards")
        b = _Proc([*args, "--worker-id", "b"], tmp_path, "b")
        _wait(lambda: owners() == {b"a", b"b"}, 60, "the shards shared")
        # the master holding shards 1 and 2 (of 0: 3, 1: 1 and 2, 2: 0)
        node = cluster.node_of(keys.shard(1, "owner"))
        sent_throttles, retired = {}, []
        n = 80

        def send(sid, fields):
            return client.xadd(keys.shard_commands(shard_of(sid, SHARDS)), fields).decode()
        for i in range(n):
            _traffic(send, i, sent_throttles, retired)
            if i == n // 2:
                if what == "a worker killed":
                    a.kill()
                else:
                    cluster.restart(node)
            time.sleep(0.03)
        survivors = {b"b"} if what == "a worker killed" else {b"a", b"b"}
        _wait(lambda: owners() <= survivors and None not in owners(), 30,
              "the shards owned by live workers")
        mark = [int(client.get(keys.shard(k, "tick"))) for k in range(SHARDS)]
        _wait(lambda: all(int(client.get(keys.shard(k, "tick"))) > mark[k] + 40
                          for k in range(SHARDS)), 60, "the workers to step on")
        if what == "a master restarted":
            assert "unreachable" in a.err() + b.err()
            assert a.term() == 0, a.err()
            assert "Traceback" not in a.err()
        assert b.term() == 0, b.err()
        assert "Traceback" not in b.err()
        if what == "a worker killed":
            assert "taken (from its checkpoint" in b.err()
        events = [e for k in range(SHARDS) for e in _events(client, keys.shard_events(k))]
        assert all(e["seq"].startswith(f"{shard_of(e['ship_id'], SHARDS)}:") for e in events)
        _gapless(events, SHARDS)
        assert not [e for e in events if "taken" in e.get("reason", "")]
        _nothing_lost(client, keys, events, flight, n, sent_throttles, retired)
        for k in range(SHARDS):  # nothing left pending in any shard's group
            for group in client.xinfo_groups(keys.shard_commands(k)):
                assert group["pending"] == 0, (k, group)
        _replay_verify(flight)
    finally:
        a.kill()
        if b is not None:
            b.kill()
        client.close()


def test_redis_cluster_on_a_redis_that_is_not_a_cluster_is_one_line_and_exit_2(
        redis_url, tmp_path):  # noqa: F811
    out = subprocess.run(_cli("serve", "--redis-cluster", redis_url, "--ticks", "1",
                              "--log-dir", str(tmp_path / "flight")),
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 2, out.stderr
    assert "--redis-cluster" in out.stderr and "Cluster mode is not enabled" in out.stderr
    assert "Traceback" not in out.stderr and len(out.stderr.strip().splitlines()) == 1


def test_on_a_cluster_the_worker_needs_its_acl_plus_cluster_slots_and_command(cluster, tmp_path):
    """docs/SERVICE.md's worker user, on every master, plus ``+cluster|slots +command`` (what
    redis-py's cluster client asks when it connects): the worker runs; without the two, it
    stops at start with one line (exit 2), and no message shows the password."""
    import redis
    prefix = _prefix()
    password = "cluster-worker-secret"
    url = cluster.url.replace("redis://", f"redis://touchdown-worker:{password}@")
    for extra in ("", " +cluster|slots +command"):
        for port in cluster.ports:
            node = redis.Redis(port=port)
            _acl(node, "touchdown-worker", password, prefix, "~P:*", WORKER_ACL + extra)
            node.close()
        out = subprocess.run(_cli("serve", "--redis-cluster", url, "--prefix", prefix,
                                  "--scenario", "fleet", "--ticks", "40", "--rate", "0",
                                  "--shards", str(SHARDS), "--log-dir", str(tmp_path / "flight")),
                             capture_output=True, text=True, timeout=120)
        assert password not in out.stderr
        assert "Traceback" not in out.stderr
        if not extra:
            assert out.returncode == 2, out.stderr
            assert len(out.stderr.strip().splitlines()) == 1, out.stderr
            assert "+cluster|slots +command" in out.stderr
        else:
            assert out.returncode == 0, out.stderr
            client = cluster.client()
            keys = Keys(prefix, cluster=True)
            assert sum(client.xlen(keys.shard_events(k)) for k in range(SHARDS)) > 0
            assert all(int(client.get(keys.shard(k, "tick"))) == 40 for k in range(SHARDS))
            client.close()


def test_view_and_record_redis_on_a_cluster_read_and_write_its_streams(cluster, tmp_path):
    """`view --redis NODE` on a cluster follows the telemetry and every shard's event stream
    ``P:ships:{k}`` (found by asking the node; one XREAD per stream); `record --redis NODE`
    publishes through the cluster's slot map whatever node it is given."""
    import threading

    from touchdown.logs.redis_stream import EventPublisher
    from touchdown.proto import touchdown_pb2 as pb
    from touchdown.service.serve import ServeConfig, Worker
    from touchdown.sim.scenario import parse_text
    import touchdown.scenarios as builtin
    from touchdown.view import live

    prefix = _prefix()
    fleet = parse_text(builtin.text("fleet"), "fleet")
    w = Worker(ServeConfig(url=cluster.url, cluster=True, prefix=prefix, scenario=fleet,
                           rate_hz=40.0, ticks=400, shards=SHARDS, telemetry_hz=10.0,
                           log_dir=tmp_path / "flight"), say=lambda line: None)
    th = threading.Thread(target=w.run, daemon=True)
    th.start()
    client = cluster.client()
    keys = Keys(prefix, cluster=True)
    try:
        _wait(lambda: client.xlen(f"{prefix}:telemetry") > 5, 60, "telemetry")
        _wait(lambda: sum(client.xlen(s) for s in keys.all_events(SHARDS)) > 0, 60, "events")
        read = []
        real = live._event

        def seen(rr, rec, fleet_, fields):
            read.append(fields.get(b"seq"))
            return real(rr, rec, fleet_, fields)
        live._event = seen
        try:
            for port in cluster.ports:  # any node will do
                n = live.record(f"redis://127.0.0.1:{port}", prefix, 2.0,
                                tmp_path / f"live-{port}.rrd")
                assert n > 0 and (tmp_path / f"live-{port}.rrd").stat().st_size > 0
        finally:
            live._event = real
        shards_seen = {s.split(b":")[0] for s in read if s}
        on_streams = {str(k).encode() for k in range(SHARDS)
                      if client.xlen(keys.shard_events(k)) > 0}
        assert shards_seen == on_streams and len(on_streams) >= 2, (shards_seen, on_streams)
        for port in cluster.ports:
            pub = EventPublisher(f"redis://127.0.0.1:{port}", f"{prefix}:published")
            pub.publish([pb.TransitionEvent(event="ship.landed", ship_id="s", tick=1)])
            pub.close()
        assert client.xlen(f"{prefix}:published") == len(cluster.ports)
    finally:
        w.stop.set()
        th.join(timeout=60)
        client.close()
