# docs/issue36/tools/serve_early.py (session 14, fast42c): one serve worker in-process on the
# bench fleet; per-loop wall, loop-thread CPU, process CPU, per-thread CPU (schedstat), phases.
# Run pinned: taskset -c 0 PYTHON serve_early.py redis://127.0.0.1:PORT/0 50000 30 out.json
# (a private redis-server on CPU 1). SPY=out.spy: py-spy (pip install py-spy) from loop 1.
"""One serve worker in-process: per-loop wall, loop-thread CPU, process CPU, phases (wall) for the
first LOOPS loops. usage: python early.py REDIS_URL SHIPS LOOPS OUT.json"""
import json, sys, time, os, uuid, threading
from pathlib import Path
import tempfile
url, n, loops, out = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
from touchdown.bench import serve as bs
from touchdown.service import serve as sv
prefix = f"bench:serve:{uuid.uuid4().hex[:8]}"
bs._config(url, prefix, n, 4)
tmp = tempfile.mkdtemp(prefix="fast42c-flight-")
cfg = sv.ServeConfig(url=url, prefix=prefix, rate_hz=10.0, ticks=loops, log_dir=Path(tmp) / "flight",
                     shards=4, worker_id="w0")
w = sv.Worker(cfg, say=lambda line: None)
rows = []
TCK = os.sysconf('SC_CLK_TCK')
def thread_cpu():
    NAMES = {t.native_id: t.name.split('_')[0].split('-w')[0] for t in threading.enumerate()}
    out = {}
    for tid in os.listdir('/proc/self/task'):
        try:
            ns = int(open(f'/proc/self/task/{tid}/schedstat').read().split()[0])
            name = NAMES.get(int(tid), 'other')
            out[f"{name}/{tid}"] = ns / 1e9
        except OSError:
            pass
    return out
orig = w.loop_once
SPY = os.environ.get("SPY")
def loop_once():
    if SPY and len(rows) == 1:
        import subprocess
        subprocess.Popen(["taskset", "-c", "1", "/work/wt-fast42c/.venv/bin/py-spy", "record", "--pid", str(os.getpid()),
                          "-r", "250", "--threads", "-f", "raw", "-d", os.environ.get("SPY_S", "2"), "-o", SPY],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    before = {k: (v[0], v[1]) for k, v in w.stats.phases.items()}
    tc0 = thread_cpu()
    t0, c0, p0 = time.perf_counter(), time.thread_time(), time.process_time()
    orig()
    ph = {k: round((v[0] - before.get(k, (0, 0))[0]) * 1e3, 2) for k, v in w.stats.phases.items()
          if v[0] - before.get(k, (0, 0))[0] > 5e-4}
    rows.append({"wall_ms": round((time.perf_counter() - t0) * 1e3, 1),
                 "loop_cpu_ms": round((time.thread_time() - c0) * 1e3, 1),
                 "proc_cpu_ms": round((time.process_time() - p0) * 1e3, 1),
                 "lag_ms": round(w.stats.lag_s * 1e3, 1), "phases": ph,
                 "threads": {k.split('/')[0]: 0 for k in []} or _thr(tc0, thread_cpu()),
                 "entries": sum(len(o.unsent) for o in w.owned.values())})
def _thr(a, b):
    d = collections.Counter()
    for k, v in b.items():
        d[k.split('/')[0].replace('touchdown-', '')] += round((v - a.get(k, 0)) * 1e3)
    return {k: v for k, v in d.items() if v}
import collections
w.loop_once = loop_once
t0 = time.time()
st = w.run()
json.dump({"rows": rows, "late_starts": list(st.late_starts), "late": st.late,
           "start_late": list(st.start_late_s)}, open(out, "w"))
for i, r in enumerate(rows[:40]):
    top = sorted(r["phases"].items(), key=lambda kv: -kv[1])[:6]
    print(i, r["wall_ms"], r["loop_cpu_ms"], r["proc_cpu_ms"], "lag", r["lag_ms"], top, r["threads"])
print("late", st.late, "late_starts", list(st.late_starts)[:10])
import shutil; shutil.rmtree(tmp, ignore_errors=True)
