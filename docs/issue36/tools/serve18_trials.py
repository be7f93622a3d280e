# session 18 (serve): bench serve's trial() (fixed fleet, 20 s, worker on CPU 0, a private
# redis-server on CPU 1), alternating START (35f8018) and this branch.
# usage: PY serve18_trials.py REDIS_URL SHIPS ROUNDS start,serve
import sys, json, os, time
from touchdown.bench import serve as bs
url, n, rounds = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
who = {"start": ("/tmp/x/START.py", "/tmp/x/START"),
       "serve": ("/work/wt-serve/.venv/bin/python", "/work/wt-serve"),
       "0.7.0": ("/tmp/x/A070.py", "/tmp/x/A070")}
for r in range(rounds):
    for tag in sys.argv[4].split(","):
        py, cwd = who[tag]
        bs.WORKER.update(python=py, cwd=cwd, cpus=[0])
        t0 = time.strftime("%H:%M:%S", time.gmtime()); l0 = os.getloadavg()[0]
        res = bs.trial(url, n, 20.0)
        slow = res.get("slowest") or res.get("slowest_ticks")
        print(f"{tag:6s} {t0} load {l0:.1f}: p50 {res['p50_ms']:.1f} p99 {res['p99_ms']:.1f} ms late {res['late_ticks']}; "
              f"CPU us a ship-tick after warm-up: all {res['steady_cpu_us_per_ship_tick']:.3f} loop {res.get('steady_loop_cpu_us_per_ship_tick', float('nan')):.3f}", flush=True)
        if r == 0 and tag == sys.argv[4].split(",")[0]:
            print("   keys:", sorted(res), flush=True)
        for k in ("phases_ms", "steady_phases_ms", "loop_phases_ms"):
            if k in res:
                print("  ", k, {a: round(b, 1) for a, b in list(res[k].items())[:8]}, flush=True)
        if slow:
            print("   slowest:", str(slow)[:300], flush=True)
