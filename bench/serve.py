"""``touchdown bench serve``: how many ships one ``touchdown serve`` worker keeps at a 10 Hz tick in
real time, with everything on (events to Redis, 1 Hz telemetry, the flight log, checkpoints).

Each trial starts a fresh service (a Redis key prefix of its own) on the Redis at ``--redis``
(default 127.0.0.1:6379): the bench writes the service's config (its scenario: N ships, tick
0.1 s so that 10 ticks a second is real time), then runs ``touchdown serve --rate 10`` in a
subprocess pinned to one CPU for ``seconds``; the worker reports each tick's working time (its
time in the loop, sleeping excluded) and the entries it delivered. A load is kept when the
worker's p99 tick time is under the 100 ms period and no more than 1% of ticks began a whole
period late.
The first 2 s (taking the shards, writing every ship's hash) are left out of the percentiles.

The fleet is bench.speed's mix: 40% flying high, 40% landed, 10% tipped, 10% arriving at 2-49
m/s (touchdowns, bounces and crashes: events). Redis runs on the same 2-core machine: with one
worker, Redis has the other core; with two workers (pinned one to each core), Redis shares them.

No figure here is asserted anywhere: the machines are shared and noisy; read the ratio of two
figures from the same run (two workers against one) rather than an absolute.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import redis

from bench.speed import fleet_doc, machine
from sim.scenario import parse

ROOT = Path(__file__).resolve().parents[1]
RATE_HZ = 10.0
DT_S = 0.1


#: the Redis Cluster the bench runs on (``main(cluster=True)``): its clients and the flag
CLUSTER = {"on": False}


def _client(url: str):
    if CLUSTER["on"]:
        from redis.cluster import RedisCluster
        return RedisCluster.from_url(url)
    return redis.Redis.from_url(url)


def _redis_args(url: str) -> list[str]:
    return ["--redis-cluster" if CLUSTER["on"] else "--redis", url]


def _redis_figures(url: str) -> tuple[int, int, int]:
    """Summed over the Redis (every master of a cluster): memory used, bytes received, bytes
    sent."""
    client = _client(url)
    try:
        if CLUSTER["on"]:
            nodes = [(n.host, n.port) for n in client.get_primaries()]
        else:
            nodes = None
        infos = []
        if nodes is None:
            infos.append(client.info())
        else:
            for host, port in nodes:
                c = redis.Redis(host=host, port=port)
                infos.append(c.info())
                c.close()
    finally:
        client.close()
    return tuple(sum(int(i[k]) for i in infos) for k in
                 ("used_memory", "total_net_input_bytes", "total_net_output_bytes"))


def _config(url: str, prefix: str, n_ships: int, shards: int) -> None:
    doc = fleet_doc(n_ships, 3600.0)
    doc["sim"] = {"dt": DT_S}
    scn = parse(doc, "bench-serve")
    client = _client(url)
    client.hset(f"{prefix}:service:config", mapping={
        "shards": shards, "scenario_json": json.dumps(scn.resolved, sort_keys=True)})
    client.close()


def _cleanup(url: str, prefix: str) -> None:
    client = _client(url)
    keys = list(client.scan_iter(f"{prefix}:*", count=10_000))  # (a cluster: every master)
    pipe = client.pipeline()
    for i, key in enumerate(keys):
        pipe.delete(key)
        if i % 1000 == 999:
            pipe.execute()
    pipe.execute()
    client.close()


def trial(url: str, n_ships: int, seconds: float, workers: int = 1, shards: int = 4,
          warmup_s: float = 2.0) -> dict:
    """One service of ``n_ships`` run for ``seconds`` with ``workers`` workers (each pinned to
    its own CPU); returns tick-time percentiles (ms) over the workers' ticks after warm-up, the
    late fraction and the entries delivered per second."""
    prefix = f"bench:serve:{uuid.uuid4().hex[:8]}"
    _config(url, prefix, n_ships, shards)
    cpus = sorted(os.sched_getaffinity(0))
    ticks = int(seconds * RATE_HZ)
    procs = []
    before = _redis_figures(url)
    t_start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="touchdown-bench-serve-") as tmp:
        try:
            for w in range(workers):
                stats = Path(tmp) / f"stats-{w}.json"
                cpu = cpus[w % len(cpus)]
                cmd = [sys.executable, str(ROOT / "cli.py"), "serve", *_redis_args(url),
                       "--prefix", prefix, "--rate", str(RATE_HZ), "--ticks", str(ticks),
                       "--log-dir", str(Path(tmp) / "flight"), "--shards", str(shards),
                       "--worker-id", f"w{w}", "--stats-json", str(stats)]
                if workers > 1:
                    cmd += ["--max-shards", str(shards // workers)]
                procs.append((subprocess.Popen(
                    cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                    preexec_fn=lambda c=cpu: os.sched_setaffinity(0, {c})), stats))
            results = []
            for proc, stats in procs:
                _out, err = proc.communicate(timeout=seconds * 4 + 300)
                if proc.returncode != 0:
                    raise RuntimeError(f"serve failed: {err.strip().splitlines()[-1:]}")
                results.append(json.loads(stats.read_text()))
            after = _redis_figures(url)
            span = time.monotonic() - t_start
        finally:
            for proc, _ in procs:
                proc.kill()
            _cleanup(url, prefix)
    skip = int(warmup_s * RATE_HZ)
    times = sorted(t for r in results for t in r["tick_s"][skip:])
    # a tick is late when it began a whole period after it was due (after warm-up)
    lates = [x for r in results for x in r["start_late_s"][skip:]]
    late = sum(x >= 1.0 / RATE_HZ for x in lates) / max(1, len(lates))
    sent = sum(r["entries_sent"] for r in results)
    wall = max(r["wall_s"] for r in results)

    def pct(q: float) -> float:
        return times[min(len(times) - 1, int(q * len(times)))] * 1e3 if times else float("nan")
    return {"ships": n_ships, "workers": workers, "p50_ms": pct(0.5), "p99_ms": pct(0.99),
            "max_ms": times[-1] * 1e3 if times else float("nan"), "late": late,
            "entries_per_s": sent / wall if wall else 0.0,
            # what the service holds in Redis at the end (all of it: the bench's keys only)
            # and its traffic over the run (into Redis, out of it), per 10,000 ships
            "redis_mb_per_10k": (after[0] - before[0]) / 1e6 * 1e4 / n_ships,
            "redis_in_mbps_per_10k": (after[1] - before[1]) / span / 1e6 * 1e4 / n_ships,
            "redis_out_mbps_per_10k": (after[2] - before[2]) / span / 1e6 * 1e4 / n_ships,
            "keeps_up": bool(times) and pct(0.99) < 1e3 / RATE_HZ and late <= 0.01}


def _line(r: dict) -> str:
    return (f"  {r['ships']:>7,} ships, {r['workers']} worker(s): tick p50 {r['p50_ms']:6.1f} ms, "
            f"p99 {r['p99_ms']:6.1f} ms, max {r['max_ms']:6.1f} ms; late {r['late']:.1%}; "
            f"{r['entries_per_s']:,.0f} entries/s to Redis; per 10,000 ships Redis holds "
            f"{r['redis_mb_per_10k']:.1f} MB, takes in {r['redis_in_mbps_per_10k']:.2f} MB/s, "
            f"sends {r['redis_out_mbps_per_10k']:.2f} MB/s  "
            f"{'keeps 10 Hz' if r['keeps_up'] else 'FALLS BEHIND'}")


def largest(url: str, workers: int, start: int, seconds: float, limit: int) -> tuple[int, list]:
    """Double the fleet until a trial falls behind, then bisect twice: the largest kept."""
    rows, good, bad = [], 0, None
    n = start
    while n <= limit:
        r = trial(url, n, seconds, workers)
        rows.append(r)
        print(_line(r), flush=True)
        if not r["keeps_up"]:
            bad = n
            break
        good = n
        n *= 2
    for _ in range(2 if bad else 0):
        mid = (good + bad) // 2
        r = trial(url, mid, seconds, workers)
        rows.append(r)
        print(_line(r), flush=True)
        if r["keeps_up"]:
            good = mid
        else:
            bad = mid
    return good, rows


def burst(url: str, n_spawns: int, shards: int = 4, lease_s: float = 2.0,
          after_s: float = 10.0) -> dict:
    """Two workers (4 shards, 10 Hz, a 2 s lease), idle; then ``n_spawns`` spawns at once,
    straight into the shards' command streams. Returns the tick-time p99 during the burst (from
    its sending until every ship has joined) and for ``after_s`` after it, how long the joining
    took, the leases that changed hands and the spawns rejected."""
    from service.commands import shard_of
    from service.redis_io import Keys
    prefix = f"bench:burst:{uuid.uuid4().hex[:8]}"
    keys = Keys(prefix, cluster=CLUSTER["on"])
    client = _client(url)
    cpus = sorted(os.sched_getaffinity(0))
    procs = []
    with tempfile.TemporaryDirectory(prefix="touchdown-bench-burst-") as tmp:
        try:
            for w in range(2):
                stats = Path(tmp) / f"stats-{w}.json"
                cmd = [sys.executable, str(ROOT / "cli.py"), "serve", *_redis_args(url),
                       "--prefix", prefix, "--rate", str(RATE_HZ), "--shards", str(shards),
                       "--lease", str(lease_s), "--log-dir", str(Path(tmp) / "flight"),
                       "--worker-id", f"w{w}", "--max-shards", str(shards // 2),
                       "--stats-json", str(stats), "--stats-every", "1"]
                procs.append((subprocess.Popen(
                    cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                    preexec_fn=lambda c=cpus[w % len(cpus)]: os.sched_setaffinity(0, {c})),
                    stats))
            owners = lambda: [client.get(keys.shard(k, "owner")) for k in range(shards)]  # noqa
            end = time.monotonic() + 120
            while None in owners() and time.monotonic() < end:
                time.sleep(0.1)
            time.sleep(2.0)
            before = owners()
            spec = json.dumps({"initial": {"altitude": 500.0}})
            t_send = time.monotonic()
            pipe = client.pipeline(transaction=False)
            for i in range(n_spawns):
                sid = f"burst-{i}"
                pipe.xadd(keys.shard_commands(shard_of(sid, shards)),
                          {"cmd": "spawn", "ship_id": sid, "player_id": f"p{i % 100}",
                           "ship": spec})
                if i % 5000 == 4999:
                    pipe.execute()
            pipe.execute()

            def ships():
                return sum(int(client.hget(keys.stats(f"w{w}"), "ships") or 0)
                           for w in range(2))
            while ships() < n_spawns and time.monotonic() < t_send + 600:
                time.sleep(0.2)
            t_joined = time.monotonic()
            time.sleep(after_s)
            changed = sum(a != b for a, b in zip(before, owners()))
            errs = []
            for proc, _stats in procs:
                proc.send_signal(2)
            results = []
            for proc, stats in procs:
                _out, err = proc.communicate(timeout=300)
                errs.append(err)
                results.append(json.loads(stats.read_text()))
        finally:
            for proc, _ in procs:
                proc.kill()
            rejected = sum(1 for stream in keys.all_events(shards)
                           for _id, f in client.xrange(stream)
                           if f.get(b"event") == b"ship.command_rejected")
            _cleanup(url, prefix)
            client.close()
    during = sorted(d for r in results for t, d in r["recent"] if t_send <= t <= t_joined)
    after = sorted(d for r in results for t, d in r["recent"] if t_joined < t)

    def p99(xs):
        return xs[min(len(xs) - 1, int(0.99 * len(xs)))] * 1e3 if xs else float("nan")
    lost = sum(e.count("lost at tick") for e in errs)
    return {"spawns": n_spawns, "join_s": t_joined - t_send, "p99_during_ms": p99(during),
            "p99_after_ms": p99(after), "leases_changed": changed, "shards_lost": lost,
            "rejected": rejected}


def main(quick: bool = False, url: str = "redis://127.0.0.1:6379/0",
         cluster: bool = False) -> None:
    """``cluster``: the same figures on a private Redis Cluster of three masters (no replicas,
    AOF with fsync every second as a deployment would run) started on free loopback ports for
    the bench, the workers on ``--redis-cluster``."""
    if cluster:
        from bench.redis_cluster import Cluster
        with tempfile.TemporaryDirectory(prefix="touchdown-bench-cluster-") as tmp:
            c = Cluster(Path(tmp), fsync="everysec")
            CLUSTER["on"] = True
            try:
                _main(quick, c.url, "a Redis Cluster of 3 masters (no replicas; AOF, fsync "
                      f"every second) on loopback, {c.url}")
            finally:
                CLUSTER["on"] = False
                c.stop()
        return
    _main(quick, url, f"Redis at {url}")


def _main(quick: bool, url: str, where: str) -> None:
    print(f"machine: {machine()}")
    print(f"touchdown serve at {RATE_HZ:g} Hz (dt {DT_S} s: real time), events, 1 Hz telemetry, "
          f"flight logs, checkpoints every 5 s (50 ticks); {where}")
    seconds = 6.0 if quick else 20.0
    start, limit = (1000, 4000) if quick else (12_500, 400_000)
    t0 = time.perf_counter()
    print("one worker (one CPU):")
    one, _ = largest(url, 1, start, seconds, limit)
    print(f"=> one worker keeps {one:,} ships at 10 Hz [aim: 50,000]")
    print("two workers (one CPU each, two shards each):")
    two, _ = largest(url, 2, start, seconds, limit)
    print(f"=> two workers keep {two:,} ships at 10 Hz ({two / max(one, 1):.2f}x one worker)")
    n = 5000 if quick else 50_000
    b = burst(url, n)
    print(f"burst: {b['spawns']:,} spawns at once into two idle workers (4 shards, 10 Hz, lease "
          f"2 s): all joined in {b['join_s']:.1f} s; tick p99 {b['p99_during_ms']:.0f} ms "
          f"during it, {b['p99_after_ms']:.0f} ms in the 10 s after (with {b['spawns']:,} "
          f"ships); leases changed hands {b['leases_changed']}, shards lost "
          f"{b['shards_lost']}, spawns rejected {b['rejected']}")
    print(f"(bench took {time.perf_counter() - t0:.0f} s)")
