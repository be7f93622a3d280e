# steady-state per-thread CPU of one serve worker in-process (bench serve's fleet, 4 shards, 10 Hz)
# usage: taskset -c 0 PY steady.py REDIS_URL SHIPS LOOPS [STEADY_FROM]
# env: NOLOG=1 drops the writers' blocks (no writing), GATE=1 holds the writers off while a loop runs,
# SWI=S sys.setswitchinterval(S), NONICE=1 the writers not niced
import resource, json, sys, time, os, uuid, threading, collections, tempfile
from pathlib import Path
url, n, loops = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
frm = int(sys.argv[4]) if len(sys.argv) > 4 else 30
from touchdown.bench import serve as bs
from touchdown.service import serve as sv
# time the writer pieces (thread CPU) by wrapping
import touchdown.logs.writer as lw, touchdown.logs.encode as le, mcap.writer as mw
T = collections.Counter(); C = collections.Counter()
def timed(name, fn):
    def f(*a, **k):
        c0 = time.thread_time()
        try: return fn(*a, **k)
        finally: T[name] += time.thread_time() - c0; C[name] += 1
    return f
le._Zstandard.compress = staticmethod(timed("zstd", le._Zstandard.compress))
le._Zlib.crc32 = staticmethod(timed("crc", le._Zlib.crc32))
lw.LogWriter._take = timed("writer_take", lw.LogWriter._take)
if os.environ.get("NOLOG"):
    _t = lw.LogWriter._take
    lw.LogWriter._take = lambda self, item: _t(self, item) if not isinstance(item, tuple) else False
lw.LogWriter._write_encoded = timed("write_encoded", lw.LogWriter._write_encoded)
import touchdown.logs.encode_block as eb
eb.BlockEncoder.encode = timed("encode", eb.BlockEncoder.encode)
if os.environ.get("SWI"): sys.setswitchinterval(float(os.environ["SWI"]))
if os.environ.get("NONICE"):
    import touchdown.service.flightlog as _fl; _fl.lower_priority = lambda *a, **k: None
GATE = threading.Event(); GATE.set()  # set: writers may run
if os.environ.get("GATE"):
    _get = lw._BlockQueue.get
    def gated_get(self):
        while not GATE.is_set() and len(self._items) < 8:
            GATE.wait(0.05)
        return _get(self)
    lw._BlockQueue.get = gated_get
prefix = f"bench:serve:{uuid.uuid4().hex[:8]}"
bs._config(url, prefix, n, 4)
tmp = tempfile.mkdtemp(prefix="serve15-flight-")
cfg = sv.ServeConfig(url=url, prefix=prefix, rate_hz=10.0, ticks=loops, log_dir=Path(tmp) / "flight",
                     shards=4, worker_id="w0")
w = sv.Worker(cfg, say=lambda line: None)
def thread_cpu():
    NAMES = {t.native_id: t.name for t in threading.enumerate()}
    out = {}
    for tid in os.listdir('/proc/self/task'):
        try:
            ns = int(open(f'/proc/self/task/{tid}/schedstat').read().split()[0])
            out[f"{NAMES.get(int(tid), 'other')}/{tid}"] = ns / 1e9
        except OSError: pass
    return out
orig = w.loop_once
state = {}
walls = []
def loop_once():
    i = len(walls)
    if i == frm:
        state['tc'] = thread_cpu(); state['ph'] = {k: list(v) for k, v in w.stats.phases.items()}
        state['T'] = dict(T); state['flt'] = resource.getrusage(resource.RUSAGE_SELF).ru_minflt; state['t'] = time.perf_counter(); state['lc'] = time.thread_time()
    t0 = time.perf_counter(); GATE.clear()
    try: orig()
    finally: GATE.set()
    walls.append(time.perf_counter() - t0)
    if len(walls) == loops: state['tc1'] = thread_cpu()
w.loop_once = loop_once
st = w.run()
tc1 = state['tc1']; nl = loops - frm
d = collections.Counter()
for k, v in tc1.items():
    d[k.split('/')[0].split('_')[0]] += v - state['tc'].get(k, 0)
print("loop-thread faults", state.get('lflt'), "threads seen", len(tc1), len(state['tc']), "faults a loop", (resource.getrusage(resource.RUSAGE_SELF).ru_minflt - state['flt'])/nl)
ships_ticks = n * nl
print(f"ships {n} loops {frm}..{loops}: per loop ms, per ship-tick us")
for k, v in sorted(d.items(), key=lambda kv: -kv[1]):
    if v > 0.001: print(f"  thread {k:30s} {v/nl*1e3:8.2f} ms {v/ships_ticks*1e6:7.3f} us")
tot = sum(d.values()); print(f"  all threads {tot/nl*1e3:8.2f} ms {tot/ships_ticks*1e6:7.3f} us")
for k in T:
    v = T[k] - state['T'].get(k, 0); print(f"  writer piece {k:15s} {v/nl*1e3:8.2f} ms {v/ships_ticks*1e6:7.3f} us")
ph = w.stats.phases
for k, v in sorted(ph.items(), key=lambda kv: -(kv[1][0])):
    b = state['ph'].get(k, [0, 0])
    dw = v[0] - b[0]; dc = v[1] - b[1] if len(v) > 1 else 0
    if dw > 0.001: print(f"  phase {k:20s} wall {dw/nl*1e3:8.2f} ms cpu {dc/nl*1e3:8.2f} ms")
ws = sorted(walls[frm:]); print("  loop wall p50 %.1f p99 %.1f max %.1f ms" % (ws[len(ws)//2]*1e3, ws[int(len(ws)*.99)]*1e3, ws[-1]*1e3))
import shutil; shutil.rmtree(tmp, ignore_errors=True)
