"""A/B: fixed fleet, alternating this branch and 0.7.0 on one private redis."""
import sys, json, os, tempfile, time
from pathlib import Path
from touchdown.bench import serve as bs

n = int(sys.argv[1]); secs = float(sys.argv[2]); rounds = int(sys.argv[3])
which = sys.argv[4].split(",") if len(sys.argv) > 4 else ["main", "070"]
V = {"serve": (sys.executable, str(bs.ROOT)), "main": ("/work/main/.venv/bin/python", "/work/main"),
     "070": ("/work/anchor-070/.venv/bin/python", "/work/anchor-070")}
with tempfile.TemporaryDirectory() as tmp:
    r = bs.PrivateRedis(Path(tmp), {1})
    bs.WORKER["cpus"] = [0]
    out = []
    try:
        for k in range(rounds):
            for w in which:
                py, cwd = V[w]
                bs.WORKER.update(python=py, cwd=cwd)
                res = bs.trial(r.url, n, secs, 1)
                res["version"] = w
                print(f"[{w}] load {os.getloadavg()[0]:.1f}" + bs._line(res), flush=True)
                out.append(res)
    finally:
        r.stop()
json.dump(out, open(f"/tmp/ab-{n}-{int(time.time())}.json", "w"))
