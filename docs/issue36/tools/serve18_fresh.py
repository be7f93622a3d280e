# session 18 (serve): the step's fresh pages. One 30,000-ship shard of bench serve's fleet
# stepped a tick at a time (World.blocks, as the service does), its blocks held for a varying
# number of ticks (as the writer's queue holds them while the writer catches up: depth 0..D,
# a fixed pseudo-random pattern), the kernel's CPU and the process's minor faults a tick.
# env MALLOPT=trim,mmap[,mmap_max]: glibc's mallopt first. usage: taskset -c 0 PY serve18_fresh.py TICKS D
import os, sys, time, random
if os.environ.get("MALLOPT"):
    import ctypes
    libc = ctypes.CDLL("libc.so.6")
    a, b, *c = os.environ["MALLOPT"].split(",")
    libc.mallopt(-1, int(a)); libc.mallopt(-3, int(b)); [libc.mallopt(-4, int(x)) for x in c]
import numpy as np
from touchdown.bench.speed import fleet_doc
from touchdown.sim.scenario import parse
from touchdown.sim.world import World
import touchdown.sim.world as WO
ticks, depth = int(sys.argv[1]), int(sys.argv[2])
doc = fleet_doc(int(os.environ.get("SHIPS", "30000")), 3600.0); doc["sim"] = {"dt": 0.1}
scn = parse(doc, "bench-serve")
kt = [0]
orig = WO.step_ticks
def st(*a):
    t = time.thread_time_ns(); r = orig(*a); kt[0] = time.thread_time_ns() - t; return r
WO.step_ticks = st
def flt():
    s = open("/proc/self/stat", "rb").read(); s = s[s.rindex(b")") + 2:].split(); return int(s[7])
rng = random.Random(1)
w = World.of(scn)
held, out = [], []
for t in range(1, ticks + 1):
    f = flt()
    bl = list(w.blocks(t))
    out.append((kt[0] / 1e6, flt() - f))
    held.extend(bl)
    keep = rng.randint(0, depth)
    del held[:max(0, len(held) - keep)]
k = np.array([x[0] for x in out[30:]]); fl = np.array([x[1] for x in out[30:]])
print(f"MALLOPT={os.environ.get('MALLOPT')} depth 0..{depth}: ticks 30..{ticks}: kernel median {np.median(k):.2f} mean {k.mean():.2f} max {k.max():.1f} ms; faults a tick mean {fl.mean():.0f}, ticks with >100 faults {int((fl > 100).sum())}; rss {int(open('/proc/self/statm').read().split()[1]) * 4096 / 2**20:.0f} MiB")
