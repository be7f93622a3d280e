# session 18 (serve): the step kernel's CPU, tick by tick, for one 30,000-ship shard of bench
# serve's fleet (World.blocks one tick at a time, as the service steps it), twice over the same
# ticks: a slow tick that is slow both times is the simulation's work; one that is not is the
# machine. usage: taskset -c 0 PY serve18_kernel.py SHIPS TICKS
import sys, time
import numpy as np
from touchdown.bench.speed import fleet_doc
from touchdown.sim.scenario import parse
from touchdown.sim.world import World
import touchdown.sim.world as WO
n, ticks = int(sys.argv[1]), int(sys.argv[2])
doc = fleet_doc(n, 3600.0); doc["sim"] = {"dt": 0.1}
scn = parse(doc, "bench-serve")
kt = [0]
orig = WO.step_ticks
def st(*a):
    t = time.thread_time_ns(); r = orig(*a); kt[0] = time.thread_time_ns() - t; return r
WO.step_ticks = st
runs = []
for rep in range(2):
    w = World.of(scn)
    out = []
    keep = []
    for t in range(1, ticks + 1):
        bl = list(w.blocks(t))
        out.append((kt[0] / 1e6, sum(len(b.events) for b in bl)))
        keep.append(bl); del keep[:-20]  # as the writer's queue would hold some
    runs.append(out)
a, b = np.array([x[0] for x in runs[0]]), np.array([x[0] for x in runs[1]])
ev = np.array([x[1] for x in runs[0]])
print(f"{n} ships, ticks 1..{ticks}: kernel ms median {np.median(a):.2f} / {np.median(b):.2f}")
for t in np.argsort(-np.maximum(a, b))[:20]:
    print(f"  tick {t+1}: {a[t]:.1f} / {b[t]:.1f} ms, events {ev[t]}")
print("ticks over 2x median:", int(np.sum(a > 2 * np.median(a))), int(np.sum(b > 2 * np.median(b))),
      "both:", int(np.sum((a > 2 * np.median(a)) & (b > 2 * np.median(b)))))
