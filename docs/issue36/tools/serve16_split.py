# session 16 (serve): per phase of the loop thread, wall = cpu + run-queue wait (runnable, not running;
# /proc/self/task/TID/schedstat) + sleep (GIL, locks, Redis replies). One worker in-process, bench serve's
# fleet, 4 shards, 10 Hz. env WNICE=N|idle: the background threads' nice (or SCHED_IDLE) instead of +10.
# usage: taskset -c 0 PY split.py REDIS_URL SHIPS LOOPS FROM
import json, sys, time, os, uuid, threading, collections, tempfile
from pathlib import Path
from contextlib import contextmanager
url, n, loops, frm = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
from touchdown.bench import serve as bs
from touchdown.service import serve as sv
from touchdown.service import phases as P
import touchdown.service.flightlog as FL
WN = os.environ.get("WNICE")
if WN:
    def lp(native_id, by=10):
        if not native_id: return
        if WN == "idle":
            os.sched_setscheduler(native_id, os.SCHED_IDLE, os.sched_param(0))
        else:
            os.setpriority(os.PRIO_PROCESS, native_id, int(WN))
    FL.lower_priority = lp; sv.lower_priority = lp
if os.environ.get("SWI"): sys.setswitchinterval(float(os.environ["SWI"]))
tid = threading.get_native_id(); open("/tmp/serve-x/h/pid", "w").write(str(os.getpid()))
f = open(f"/proc/self/task/{tid}/schedstat", "rb", buffering=0)
def ss():
    f.seek(0); a = f.read().split(); return int(a[0]), int(a[1])
acc = collections.defaultdict(lambda: [0, 0, 0, 0])  # wall ns, cpu ns, rq ns, count
on = [False]
depth = [0]
orig_call = P.Phases.__call__
@contextmanager
def call(self, name):
    w = time.perf_counter_ns(); c, r = ss(); depth[0] += 1
    try:
        with orig_call(self, name):
            yield
    finally:
        depth[0] -= 1
        if on[0] and threading.get_native_id() == tid:
            c1, r1 = ss(); a = acc[name]
            a[0] += time.perf_counter_ns() - w; a[1] += c1 - c; a[2] += r1 - r; a[3] += 1
P.Phases.__call__ = call
prefix = f"bench:serve:{uuid.uuid4().hex[:8]}"
bs._config(url, prefix, n, 4)
tmp = tempfile.mkdtemp(prefix="serve16-flight-")
cfg = sv.ServeConfig(url=url, prefix=prefix, rate_hz=10.0, ticks=loops, log_dir=Path(tmp) / "flight",
                     shards=4, worker_id="w0")
w = sv.Worker(cfg, say=lambda line: None)
orig = w.loop_once
tot = [0, 0, 0, 0]; walls = []
allcpu = [0.0, 0.0]
def loop_once():
    i = len(walls)
    on[0] = i >= frm
    if i == frm: allcpu[0] = time.process_time()
    wn = time.perf_counter_ns(); c, r = ss()
    orig()
    c1, r1 = ss(); d = time.perf_counter_ns() - wn
    walls.append(d / 1e6)
    if on[0]:
        tot[0] += d; tot[1] += c1 - c; tot[2] += r1 - r; tot[3] += 1
    if i == loops - 1: allcpu[1] = time.process_time()
w.loop_once = loop_once
w.run()
nl = tot[3]
print(f"ships {n} loops {frm}..{loops} SWI={os.environ.get('SWI')} WNICE={WN} load={os.getloadavg()[0]:.1f}")
print(f"  loop: wall {tot[0]/nl/1e6:.2f} ms = cpu {tot[1]/nl/1e6:.2f} + runq {tot[2]/nl/1e6:.2f} + sleep {(tot[0]-tot[1]-tot[2])/nl/1e6:.2f}")
print(f"  process cpu a loop {(allcpu[1]-allcpu[0])/nl*1e3:.2f} ms = {(allcpu[1]-allcpu[0])/nl/n*1e6:.3f} us a ship-tick")
for k, a in sorted(acc.items(), key=lambda kv: -kv[1][0]):
    if a[0] / nl > 2e5:
        print(f"  {k:14s} wall {a[0]/nl/1e6:6.2f} cpu {a[1]/nl/1e6:6.2f} runq {a[2]/nl/1e6:6.2f} sleep {(a[0]-a[1]-a[2])/nl/1e6:6.2f} ms/loop")
ws = sorted(walls[frm:]); print("  loop wall p50 %.1f p90 %.1f max %.1f ms" % (ws[len(ws)//2], ws[int(len(ws)*.9)], ws[-1]))
import shutil; shutil.rmtree(tmp, ignore_errors=True)
