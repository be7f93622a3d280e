import sys, json, os, time
from touchdown.bench import serve as bs
url = "redis://127.0.0.1:16391/0"
n = int(sys.argv[1]); rounds = int(sys.argv[2])
who = {"main": ("/tmp/serve-x/MAIN.py", "/tmp/serve-x/MAIN"),
       "serve": ("/work/wt-serve/.venv/bin/python", "/work/wt-serve"),
       "0.7.0": ("/tmp/serve-x/A070.py", "/tmp/serve-x/A070")}
for r in range(rounds):
    for tag in sys.argv[3].split(","):
        py, cwd = who[tag]
        bs.WORKER.update(python=py, cwd=cwd, cpus=[0])
        t0 = time.strftime("%H:%M:%S", time.gmtime()); l0 = os.getloadavg()[0]
        res = bs.trial(url, n, 20.0)
        print(f"{tag:6s} {t0} load {l0:.1f}: p50 {res['p50_ms']:.1f} p99 {res['p99_ms']:.1f} ms late {res['late_ticks']}; "
              f"CPU us a ship-tick after warm-up: all {res['steady_cpu_us_per_ship_tick']:.3f} loop {res.get('steady_loop_cpu_us_per_ship_tick', float('nan')):.3f}", flush=True)
