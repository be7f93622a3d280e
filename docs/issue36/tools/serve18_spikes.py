# session 18 (serve): what the loop thread's slow "step" phases are. One worker in-process, bench
# serve's fleet, 4 shards, 10 Hz (as serve16_split.py). Every "step" call on the loop thread:
# its wall split by the loop thread's own /proc/self/task/TID/schedstat into CPU + run-queue wait +
# sleep, the minor faults (/proc/self/task/TID/stat), the other threads' CPU in that wall (by
# name), the block's ticks and events. Prints the slowest step calls and the medians.
# usage: taskset -c 0 PY serve18_spikes.py REDIS_URL SHIPS LOOPS FROM [out.json]
import json, sys, time, os, uuid, threading, collections, tempfile
from pathlib import Path
from contextlib import contextmanager
url, n, loops, frm = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
out_json = sys.argv[5] if len(sys.argv) > 5 else None
if os.environ.get("NOHUGE"):
    import numpy as np
    np._core.multiarray._set_madvise_hugepage(False)
if os.environ.get("MALLOPT"):  # trim threshold, mmap threshold (bytes), at run time
    import ctypes
    libc = ctypes.CDLL("libc.so.6")
    a, b, *c = os.environ["MALLOPT"].split(",")
    print("mallopt", libc.mallopt(-1, int(a)), libc.mallopt(-3, int(b)), [libc.mallopt(-4, int(x)) for x in c])
from touchdown.bench import serve as bs
from touchdown.service import serve as sv
from touchdown.service import phases as P
if os.environ.get("KEEP") == "0":  # the worker as before service.memory: glibc's own trimming
    sv.keep_freed_memory = lambda: False

tid = threading.get_native_id()
me = open(f"/proc/self/task/{tid}/schedstat", "rb", buffering=0)
mestat = open(f"/proc/self/task/{tid}/stat", "rb", buffering=0)


def ss():
    me.seek(0); a = me.read().split(); return int(a[0]), int(a[1])


def minflt():
    mestat.seek(0); s = mestat.read(); s = s[s.rindex(b")") + 2:].split(); return int(s[7]), int(s[9])


def threads():
    """name -> cpu ns, of every thread but the loop thread (named by its Python thread)"""
    names = {t.native_id: t.name for t in threading.enumerate()}
    d = collections.Counter()
    for t in os.listdir("/proc/self/task"):
        if int(t) == tid:
            continue
        try:
            cpu = int(open(f"/proc/self/task/{t}/schedstat").read().split()[0])
        except OSError:
            continue
        d[f"{names.get(int(t), '?')}/{t}"] += cpu
    return d


# the step's parts on the loop thread: the kernel, the transitions, the rest
import touchdown.sim.world as WO
parts = collections.Counter()
def timed(fn, key):
    def f(*a, **k):
        t = time.thread_time_ns()
        try:
            return fn(*a, **k)
        finally:
            if threading.get_native_id() == tid:
                parts[key] += time.thread_time_ns() - t
    return f
WO.step_ticks = timed(WO.step_ticks, "kernel")
WO.transitions = timed(WO.transitions, "transitions")
WO.resting = timed(WO.resting, "resting")
import gc
gcs = []
gct = [0]
def gccb(phase, info):
    if phase == "start":
        gct[0] = time.perf_counter_ns()
    else:
        gcs.append((loopno[0], threading.current_thread().name, info.get("generation"), (time.perf_counter_ns() - gct[0]) / 1e6))
gc.callbacks.append(gccb)


loopno = [0]
rec = []  # step calls
orig_call = P.Phases.__call__


@contextmanager
def call(self, name):
    if name != "step" or threading.get_native_id() != tid:
        with orig_call(self, name):
            yield
        return
    parts.clear(); th0 = threads(); w = time.perf_counter_ns(); c, r = ss(); f0 = minflt()
    with orig_call(self, name):
        yield
    c1, r1 = ss(); w1 = time.perf_counter_ns(); f1 = minflt(); th1 = threads()
    other = {k: (th1[k] - th0.get(k, 0)) / 1e6 for k in th1 if th1[k] - th0.get(k, 0) > 2e5}
    rec.append(dict(loop=loopno[0], wall=(w1 - w) / 1e6, cpu=(c1 - c) / 1e6, rq=(r1 - r) / 1e6,
                    sleep=((w1 - w) - (c1 - c) - (r1 - r)) / 1e6, minflt=f1[0] - f0[0],
                    majflt=f1[1] - f0[1], other=other, parts={k: v / 1e6 for k, v in parts.items()}))


P.Phases.__call__ = call
import touchdown.service.shard as SH
orig_step = SH.Shard.step


def step(self, requests, phase=None):
    out = orig_step(self, requests, phase)
    if rec and rec[-1].get("loop") == loopno[0] and "ev" not in rec[-1]:
        rec[-1]["ev"] = sum(len(b.events) for b in out.blocks)
        rec[-1]["ticks"] = sum(b.states.shape[0] for b in out.blocks)
        rec[-1]["shard"] = self.index
        rec[-1]["n"] = self.world.state.n
    return out


SH.Shard.step = step
prefix = f"bench:serve:{uuid.uuid4().hex[:8]}"
bs._config(url, prefix, n, 4)
tmp = tempfile.mkdtemp(prefix="serve18-flight-")
cfg = sv.ServeConfig(url=url, prefix=prefix, rate_hz=float(os.environ.get("RATE", "10")), ticks=loops, log_dir=Path(tmp) / "flight",
                     shards=4, worker_id="w0")
w = sv.Worker(cfg, say=lambda line: None)
orig = w.loop_once
walls = []


pflt = []  # per loop: the process's minor faults (every thread), thp faults (machine-wide)
def pstat():
    s = open("/proc/self/stat", "rb").read(); s = s[s.rindex(b")") + 2:].split(); return int(s[7])
def thp():
    for line in open("/proc/vmstat"):
        if line.startswith("thp_fault_alloc "):
            return int(line.split()[1])
cpu0 = [0.0]
def loop_once():
    loopno[0] = len(walls)
    if loopno[0] == frm: cpu0[0] = time.process_time()
    t = time.perf_counter_ns(); f = pstat(); h = thp()
    orig()
    walls.append((time.perf_counter_ns() - t) / 1e6)
    pflt.append((pstat() - f, thp() - h))
    if loopno[0] == loops - 1: cpu0.append(time.process_time())


w.loop_once = loop_once
w.run()
print(f"ships {n} loops {frm}..{loops} load={os.getloadavg()[0]:.1f} KEEP={os.environ.get('KEEP')} RATE={os.environ.get('RATE')}")
st = [x for x in rec if x["loop"] >= frm]
st.sort(key=lambda x: -x["wall"])
import statistics as S
for k in ("wall", "cpu", "rq", "sleep", "minflt", "ev"):
    print(f"  step median {k} {S.median(x.get(k, 0) for x in st):.2f}")
print("  slowest step calls:")
for x in st[:15]:
    o = ", ".join(f"{k} {v:.1f}" for k, v in sorted(x["other"].items(), key=lambda kv: -kv[1]))
    o += "; parts " + ", ".join(f"{k} {v:.1f}" for k, v in x["parts"].items())
    print(f"   loop {x['loop']} shard {x.get('shard')} n {x.get('n')} ticks {x.get('ticks')} ev {x.get('ev')}: wall {x['wall']:.1f} = cpu {x['cpu']:.1f} + rq {x['rq']:.1f} + sleep {x['sleep']:.1f}; minflt {x['minflt']} majflt {x['majflt']}; others {o}")
ks = [x['parts'].get('kernel', 0) for x in st]; mk = S.median(ks)
print(f"  kernel over 2x its median: {sum(k > 2 * mk for k in ks)} of {len(ks)} step calls; kernel total {sum(ks):.0f} ms, median x count {mk * len(ks):.0f} ms")
print(f"  process faults a loop (mean): minflt {S.mean(p[0] for p in pflt[frm:]):.0f}, thp {S.mean(p[1] for p in pflt[frm:]):.2f}")
print(f"  process cpu a loop {(cpu0[1] - cpu0[0]) / (loops - frm) * 1e3:.2f} ms = {(cpu0[1] - cpu0[0]) / (loops - frm) / n * 1e6:.3f} us a ship-tick")
names = {t.native_id: t.name for t in threading.enumerate()}
tf = collections.Counter()
for t in os.listdir("/proc/self/task"):
    x = open(f"/proc/self/task/{t}/stat", "rb").read(); x = x[x.rindex(b")") + 2:].split()
    tf[names.get(int(t), "?").split("_")[0]] += int(x[7])
print("  minflt by thread (whole run):", dict(tf.most_common()))
print(f"  rss {int(open('/proc/self/statm').read().split()[1]) * 4096 / 2**20:.0f} MiB")
print("  gc over 2 ms:", [g for g in gcs if g[3] > 2][:20])
for k in ("kernel", "transitions", "resting"):
    print(f"  step median part {k} {S.median(x['parts'].get(k, 0) for x in st):.2f} ms")
ws = sorted(walls[frm:]); print("  loop wall p50 %.1f p99 %.1f max %.1f ms" % (ws[len(ws)//2], ws[int(len(ws)*.99)], ws[-1]))
if out_json:
    json.dump(dict(rec=rec, walls=walls), open(out_json, "w"))
import shutil; shutil.rmtree(tmp, ignore_errors=True)
