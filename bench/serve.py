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

A fleet is kept when, after the warm-up, the workers' tick p99 is under the 100 ms period and no
tick began a whole period late (``--max-late``, default 0). ``largest`` doubles the fleet with
short trials until one is not kept, bisects to within about 3%, then confirms the size found with
one long trial (``--confirm-seconds``, default 300: the issue's 5 minutes), stepping down 5% at a
time while the confirmation fails. A short trial that is not kept is run again (``--retries``,
default 1) before the search counts its size as too many: on a shared machine one late tick in
20 s is as often a neighbour's burst as the fleet's size, and one such trial capped a search
below what the same code kept in the next run (session 23: 49,218 against 50,781). The retry
cannot keep a fleet that falls behind: the long confirmation still decides. Each trial's line
also gives the CPU the workers used (all their threads; ``process_time``) per ship-tick and where
the loop's thread spent its CPU: read those beside the wall-clock figures on a shared machine.

Pinning (``os.sched_setaffinity``, as ``taskset`` does): worker w is pinned to CPU ``cpus[w]``
of the bench's own CPUs; with ``--private-redis`` the bench starts its own redis-server (no
persistence) pinned to a CPU no worker has when there is one (with two workers on two cores there
is none: it shares them, and the bench says so). ``--worker-python``/``--worker-cwd`` run another
checkout's worker (``PYTHON DIR/cli.py serve``: the version before a change, measured in the
same session).

The fleet is bench.speed's mix: 40% flying high, 40% landed, 10% tipped, 10% arriving at 2-49
m/s (touchdowns, bounces and crashes: events). Redis runs on the same 2-core machine: with one
worker, Redis has the other core; with two workers (pinned one to each core), Redis shares them.

No figure here is asserted anywhere: the machines are shared and noisy; read the ratio of two
figures from the same run (two workers against one) rather than an absolute.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path
from typing import Callable

import redis

from touchdown.bench.speed import fleet_doc, machine
from touchdown.sim.scenario import parse

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
    parse(doc, "bench-serve")  # checked here; the workers resolve its defaults themselves, so
    # the doc holds only keys every version knows (an earlier version's worker, --worker-cwd)
    client = _client(url)
    client.hset(f"{prefix}:service:config", mapping={
        "shards": shards, "scenario_json": json.dumps(doc, sort_keys=True)})
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


#: how the workers are run (``main``'s options): their Python and checkout, the late ticks a
#: kept fleet may have, and the CPUs the workers are pinned to
WORKER = {"python": sys.executable, "cwd": str(ROOT), "max_late": 0, "cpus": None}


def _worker_cpus() -> list[int]:
    return WORKER["cpus"] or sorted(os.sched_getaffinity(0))


def trial(url: str, n_ships: int, seconds: float, workers: int = 1, shards: int = 4,
          warmup_s: float = 2.0) -> dict:
    """One service of ``n_ships`` run for ``seconds`` with ``workers`` workers (each pinned to
    its own CPU); returns tick-time percentiles (ms) over the workers' ticks after warm-up, the
    late fraction and the entries delivered per second."""
    prefix = f"bench:serve:{uuid.uuid4().hex[:8]}"
    _config(url, prefix, n_ships, shards)
    cpus = _worker_cpus()
    ticks = int(seconds * RATE_HZ)
    procs = []
    before = _redis_figures(url)
    t_start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="touchdown-bench-serve-") as tmp:
        try:
            for w in range(workers):
                stats = Path(tmp) / f"stats-{w}.json"
                cpu = cpus[w % len(cpus)]
                cmd = [WORKER["python"], str(Path(WORKER["cwd"]) / "cli.py"), "serve",
                       *_redis_args(url),
                       "--prefix", prefix, "--rate", str(RATE_HZ), "--ticks", str(ticks),
                       "--log-dir", str(Path(tmp) / "flight"), "--shards", str(shards),
                       "--worker-id", f"w{w}", "--stats-json", str(stats)]
                if workers > 1:
                    cmd += ["--max-shards", str(shards // workers)]
                procs.append((subprocess.Popen(
                    cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                    cwd=WORKER["cwd"],
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
    n_ticks = sum(len(r["tick_s"]) for r in results) / max(1, len(results))
    # CPU of every thread of the workers (older workers do not report it)
    cpu = sum(r.get("cpu_s", float("nan")) for r in results)
    loop_cpu = sum(r.get("loop_cpu_s", float("nan")) for r in results)
    # the loop's CPU by phase: after the warm-up where the worker says where its steady loops
    # begin (phases_at_steady), else over the whole run with its start (an older worker)
    phases: dict[str, float] = {}
    steady_phases = all(r.get("phases_at_steady", [0, {}])[1] for r in results)
    phase_ticks = 0.0
    for r in results:
        at = r["phases_at_steady"][1] if steady_phases else {}
        for name, (_w, c) in r.get("phases", {}).items():
            phases[name] = phases.get(name, 0.0) + c - at.get(name, (0.0, 0.0))[1]
        phase_ticks += len(r["tick_s"]) - (r["phases_at_steady"][0] if steady_phases else 0)
    phase_ticks /= max(1, len(results))
    ship_ticks = n_ships * n_ticks
    # the CPU after the warm-up, where the worker says it (every thread: the loop, the log's
    # writer, the checkpoint packer, the leases)
    steady = [(r["cpu_s_at_tick"][-1] - r["cpu_s_at_tick"][skip],
               len(r["cpu_s_at_tick"]) - 1 - skip) for r in results
              if len(r.get("cpu_s_at_tick", ())) > skip + 1]
    # (every worker's CPU over the ticks they ran side by side: a worker's own count)
    steady_us = (sum(c for c, _ in steady) / (sum(n for _, n in steady) / len(steady))
                 / n_ships * 1e6 if steady else float("nan"))
    # the loop thread's own CPU after the warm-up (the rest of ``steady``: the other threads')
    loop_steady = [(r["loop_cpu_s_at_tick"][-1] - r["loop_cpu_s_at_tick"][skip],
                    len(r["loop_cpu_s_at_tick"]) - 1 - skip) for r in results
                   if len(r.get("loop_cpu_s_at_tick", ())) > skip + 1]
    loop_steady_us = (sum(c for c, _ in loop_steady) / (sum(n for _, n in loop_steady)
                                                        / len(loop_steady))
                      / n_ships * 1e6 if loop_steady else float("nan"))
    late_ticks = sum(x >= 1.0 / RATE_HZ for x in lates)

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
            # CPU per ship-tick over the whole run (start-up included), all threads and the
            # loop's own; the loop's CPU per tick by phase (ms)
            "cpu_us_per_ship_tick": cpu / ship_ticks * 1e6 if ship_ticks else float("nan"),
            "steady_cpu_us_per_ship_tick": steady_us,
            "loop_cpu_us_per_ship_tick": loop_cpu / ship_ticks * 1e6 if ship_ticks else
            float("nan"),
            "phases_ms": {k: v / phase_ticks / max(1, len(results)) * 1e3
                          for k, v in sorted(phases.items(), key=lambda kv: -kv[1])},
            "phases_steady": steady_phases,
            "steady_loop_cpu_us_per_ship_tick": loop_steady_us,
            "late_ticks": late_ticks, "seconds": seconds,
            # what the slowest ticks spent their time on, and what came before each late start
            "slowest": sorted((x for r in results for x in r.get("slowest", ())
                               if x["loop"] >= skip), key=lambda x: -x["tick_s"])[:3],
            "late_starts": [x for r in results for x in r.get("late_starts", ())
                            if x["loop"] >= skip],
            "keeps_up": bool(times) and pct(0.99) < 1e3 / RATE_HZ
            and late_ticks <= WORKER["max_late"]}


def _line(r: dict) -> str:
    cpu = ""
    if r["cpu_us_per_ship_tick"] == r["cpu_us_per_ship_tick"]:  # (not NaN: a worker that says)
        top = ", ".join(f"{k} {v:.1f}" for k, v in list(r["phases_ms"].items())[:6])
        loop = r.get("steady_loop_cpu_us_per_ship_tick", float("nan"))
        split = (f" = loop thread {loop:.2f} + other threads "
                 f"{r['steady_cpu_us_per_ship_tick'] - loop:.2f}" if loop == loop else "")
        when = "after the warm-up" if r.get("phases_steady") else "over the run with its start-up"
        cpu = (f"\n           CPU after the warm-up {r['steady_cpu_us_per_ship_tick']:.2f} us a "
               f"ship-tick (every thread{split}; the run with its start-up "
               f"{r['cpu_us_per_ship_tick']:.2f}, its loop thread "
               f"{r['loop_cpu_us_per_ship_tick']:.2f}); loop CPU a tick per worker {when}, ms: "
               f"{top}")
    cpu += _stalls(r)
    return (f"  {r['ships']:>7,} ships, {r['workers']} worker(s), {r['seconds']:g} s: tick p50 "
            f"{r['p50_ms']:6.1f} ms, p99 {r['p99_ms']:6.1f} ms, max {r['max_ms']:6.1f} ms; "
            f"late {r['late_ticks']} ({r['late']:.1%}); "
            f"{r['entries_per_s']:,.0f} entries/s to Redis; per 10,000 ships Redis holds "
            f"{r['redis_mb_per_10k']:.1f} MB, takes in {r['redis_in_mbps_per_10k']:.2f} MB/s, "
            f"sends {r['redis_out_mbps_per_10k']:.2f} MB/s  "
            f"{'keeps 10 Hz' if r['keeps_up'] else 'FALLS BEHIND'}{cpu}")


def _stalls(r: dict) -> str:
    """The slowest ticks by phase, and the late starts with what came before them (a late start
    after a short tick, with nothing between, woke late: the CPU was another process's)."""
    out = ""
    if r.get("slowest"):
        ticks = "; ".join(
            f"{x['tick_s'] * 1e3:.0f} ms (" + ", ".join(
                f"{k} {v * 1e3:.0f}" for k, v in sorted(x["phases"].items(),
                                                         key=lambda kv: -kv[1])[:3]) + ")"
            for x in r["slowest"])
        out += f"\n           slowest ticks: {ticks}"
    late = r.get("late_starts") or []
    if late:
        def span(key: str) -> str:
            vals = [x[key] * 1e3 for x in late]
            return f"{min(vals):.0f}-{max(vals):.0f}"
        out += (f"\n           {len(late)} late start(s): {span('behind_s')} ms late, after a tick "
                f"of {span('previous_tick_s')} ms, {span('between_s')} ms between ticks, the "
                f"wait woke {span('woke_late_s')} ms late")
    return out


def largest(url: str, workers: int, start: int, seconds: float, limit: int,
            confirm_s: float = 0.0, precision: float = 0.03, retries: int = 1
            ) -> tuple[int, list]:
    """The largest fleet ``workers`` keep (:func:`search`, each try a :func:`trial` on ``url``),
    and every trial."""
    rows = []

    def run(n: int, secs: float) -> bool:
        r = trial(url, n, secs, workers)
        rows.append(r)
        print(_line(r), flush=True)
        return r["keeps_up"]
    return search(run, start, seconds, limit, confirm_s, precision, retries), rows


def search(run: Callable[[int, float], bool], start: int, seconds: float, limit: int,
           confirm_s: float = 0.0, precision: float = 0.03, retries: int = 1) -> int:
    """Double the fleet from ``start`` until a short trial (``run(n, seconds)``: kept or not)
    falls behind ``1 + retries`` times at one size, bisect to within ``precision``, then
    (``confirm_s``) confirm the size found with one long trial, 5% less at a time while it
    fails: the largest fleet kept (0: none)."""
    good, bad = 0, None

    def kept(n: int) -> bool:
        for attempt in range(1 + retries):
            if attempt:
                print(f"  not kept: {n:,} ships again ({attempt} of {retries})",
                      flush=True)
            if run(n, seconds):
                return True
        return False
    n = start
    while n <= limit:
        if not kept(n):
            bad = n
            break
        good = n
        n *= 2
    while bad is not None and bad - good > max(good, start / 2) * precision:
        mid = (good + bad) // 2
        if kept(mid):
            good = mid
        else:
            bad = mid
    if confirm_s and good:
        for _ in range(6):
            print(f"  confirming {good:,} ships for {confirm_s:g} s:", flush=True)
            if run(good, confirm_s):
                break
            good = int(good * 0.95)
        else:
            good = 0
    return good


def burst(url: str, n_spawns: int, shards: int = 4, lease_s: float = 2.0,
          after_s: float = 10.0) -> dict:
    """Two workers (4 shards, 10 Hz, a 2 s lease), idle; then ``n_spawns`` spawns at once,
    straight into the shards' command streams. Returns the tick-time p99 during the burst (from
    its sending until every ship has joined) and for ``after_s`` after it, how long the joining
    took, the leases that changed hands and the spawns rejected."""
    from touchdown.service.commands import shard_of
    from touchdown.service.redis_io import Keys
    prefix = f"bench:burst:{uuid.uuid4().hex[:8]}"
    keys = Keys(prefix, cluster=CLUSTER["on"])
    client = _client(url)
    cpus = _worker_cpus()
    procs = []
    with tempfile.TemporaryDirectory(prefix="touchdown-bench-burst-") as tmp:
        try:
            for w in range(2):
                stats = Path(tmp) / f"stats-{w}.json"
                cmd = [WORKER["python"], str(Path(WORKER["cwd"]) / "cli.py"), "serve",
                       *_redis_args(url),
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


class PrivateRedis:
    """A redis-server of the bench's own on a free loopback port (no persistence), pinned to
    ``cpus`` when given."""

    def __init__(self, folder: Path, cpus: set[int] | None = None):
        from touchdown.bench.redis_cluster import free_ports
        binary = shutil.which("redis-server")
        if binary is None:
            raise RuntimeError("--private-redis needs redis-server on PATH")
        self.port = free_ports(1)[0]
        self.proc = subprocess.Popen(
            [binary, "--port", str(self.port), "--bind", "127.0.0.1", "--dir", str(folder),
             "--save", "", "--appendonly", "no"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            preexec_fn=(lambda: os.sched_setaffinity(0, cpus)) if cpus else None)
        end = time.monotonic() + 10
        while True:
            try:
                c = redis.Redis(port=self.port, socket_connect_timeout=0.5)
                c.ping()
                c.close()
                break
            except redis.exceptions.RedisError:
                if time.monotonic() > end:
                    self.stop()
                    raise RuntimeError("the private redis-server did not start") from None
                time.sleep(0.05)

    @property
    def url(self) -> str:
        return f"redis://127.0.0.1:{self.port}/0"

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


def _placement(workers: int, redis_cpus: str | None) -> tuple[set[int] | None, str]:
    """The CPUs Redis is pinned to (None: not pinned) and a sentence saying how the workers
    and Redis share the machine's CPUs."""
    cpus = _worker_cpus()
    used = {cpus[w % len(cpus)] for w in range(workers)}
    free = [c for c in cpus if c not in used]
    if redis_cpus == "none":
        pin = None
    elif redis_cpus:
        pin = {int(c) for c in redis_cpus.split(",")}
    else:
        pin = {free[0]} if free else None
    said = ", ".join(f"worker {w} on CPU {cpus[w % len(cpus)]}" for w in range(workers))
    if pin is None:
        said += "; Redis not pinned (no CPU free of workers: it shares theirs)" if not free \
            else "; Redis not pinned"
    else:
        shared = pin & used
        said += f"; Redis pinned to CPU {','.join(map(str, sorted(pin)))}" + (
            " (shared with a worker)" if shared else " (no worker there)")
    return pin, said


def main(quick: bool = False, url: str = "redis://127.0.0.1:6379/0",
         cluster: bool = False, seconds: float | None = None, confirm_s: float = 300.0,
         start: int | None = None, limit: int = 400_000, workers: tuple[int, ...] = (1, 2),
         burst_spawns: int | None = None, private_redis: bool = False,
         redis_cpus: str | None = None, worker_python: str | None = None,
         worker_cwd: str | None = None, max_late: int = 0, label: str = "",
         retries: int = 1) -> dict:
    """``cluster``: the same figures on a private Redis Cluster of three masters (no replicas,
    AOF with fsync every second as a deployment would run) started on free loopback ports for
    the bench, the workers on ``--redis-cluster``. ``private_redis``: on a redis-server of the
    bench's own, pinned apart from the workers where the machine has a CPU for it. Returns
    the figures (workers -> ships kept, and every trial)."""
    WORKER.update(python=worker_python or sys.executable, cwd=worker_cwd or str(ROOT),
                  max_late=max_late)
    opts = dict(quick=quick, seconds=seconds, confirm_s=confirm_s, start=start, limit=limit,
                workers=workers, burst_spawns=burst_spawns, label=label, retries=retries)

    def placer(pids):
        """For n workers: pin the bench's Redis processes apart from them (where a CPU is
        free); returns how the CPUs are shared."""
        def place(n: int) -> str:
            pin, said = _placement(n, redis_cpus)
            every = set(sorted(os.sched_getaffinity(0)))
            for pid in pids():
                try:
                    os.sched_setaffinity(pid, pin or every)
                except OSError:
                    pass
            return said
        return place
    if cluster:
        from touchdown.bench.redis_cluster import Cluster
        with tempfile.TemporaryDirectory(prefix="touchdown-bench-cluster-") as tmp:
            c = Cluster(Path(tmp), fsync="everysec")
            CLUSTER["on"] = True
            try:
                return _main(c.url, "a Redis Cluster of 3 masters (no replicas; AOF, fsync "
                             f"every second) on loopback, {c.url}",
                             placer(lambda: [p.pid for p in c.procs if p is not None]), **opts)
            finally:
                CLUSTER["on"] = False
                c.stop()
    if private_redis:
        with tempfile.TemporaryDirectory(prefix="touchdown-bench-redis-") as tmp:
            r = PrivateRedis(Path(tmp))
            try:
                return _main(r.url, f"a private redis-server (no persistence) at {r.url}",
                             placer(lambda: [r.proc.pid]), **opts)
            finally:
                r.stop()
    return _main(url, f"Redis at {url}", lambda n: _placement(n, "none")[1].split(";")[0] +
                 f"; Redis at {url} was started elsewhere: not pinned by the bench", **opts)


def _main(url: str, where: str, place, quick: bool, seconds: float | None,
          confirm_s: float, start: int | None, limit: int, workers: tuple[int, ...],
          burst_spawns: int | None, label: str, retries: int) -> dict:
    print(f"machine: {machine()}; load average {os.getloadavg()[0]:.1f} at the start")
    who = (f"{WORKER['python']} {WORKER['cwd']}/cli.py serve"
           + (f" ({label})" if label else ""))
    print(f"worker: {who}")
    print(f"touchdown serve at {RATE_HZ:g} Hz (dt {DT_S} s: real time), events, 1 Hz telemetry, "
          f"flight logs, checkpoints every 5 s (50 ticks); {where}")
    seconds = seconds or (6.0 if quick else 20.0)
    if quick:
        confirm_s = min(confirm_s, 10.0)
    start = start or (1000 if quick else 12_500)
    limit = 4000 if quick else limit
    print(f"kept: tick p99 < {1e3 / RATE_HZ:.0f} ms and at most {WORKER['max_late']} late "
          f"tick(s) after a {2:g} s warm-up; search trials {seconds:g} s (a size not kept is "
          f"tried {retries} more time(s)), confirmation {confirm_s:g} s")
    t0 = time.perf_counter()
    kept: dict[int, int] = {}
    out: dict = {"kept": kept, "trials": {}}
    for n_workers in workers:
        print(f"{n_workers} worker(s) (one CPU each, {4 // n_workers} shards each); pinning: "
              f"{place(n_workers)}:")
        n, rows = largest(url, n_workers, start, seconds, limit, confirm_s, retries=retries)
        kept[n_workers] = n
        out["trials"][n_workers] = rows
        ratio = f" ({n / max(kept.get(1, 0), 1):.2f}x one worker)" if n_workers > 1 and \
            kept.get(1) else ""
        aim = " [aim: 50,000]" if n_workers == 1 else ""
        print(f"=> {n_workers} worker(s) keep {n:,} ships at 10 Hz{ratio}{aim}", flush=True)
    if burst_spawns is None:
        burst_spawns = 5000 if quick else 50_000
    if burst_spawns:
        b = burst(url, burst_spawns)
        out["burst"] = b
        print(f"burst: {b['spawns']:,} spawns at once into two idle workers (4 shards, 10 Hz, "
              f"lease 2 s): all joined in {b['join_s']:.1f} s; tick p99 "
              f"{b['p99_during_ms']:.0f} ms during it, {b['p99_after_ms']:.0f} ms in the 10 s "
              f"after (with {b['spawns']:,} ships); leases changed hands "
              f"{b['leases_changed']}, shards lost {b['shards_lost']}, spawns rejected "
              f"{b['rejected']}")
    print(f"(bench took {time.perf_counter() - t0:.0f} s)")
    return out
