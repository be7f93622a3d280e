"""The service's stepping pattern: 4 shard worlds of the bench fleet, one 1-tick block each per
tick, CPU per ship-tick after WARM ticks, by window; and the same world stepped 50 ticks a block."""
import sys, time, os
import numpy as np
os.sched_setaffinity(0, {0})
from touchdown.bench.speed import fleet_doc
from touchdown.sim.scenario import parse
from touchdown.service.serve import shard_world
N = int(sys.argv[1]); T = int(sys.argv[2])
doc = fleet_doc(N, 3600.0); doc["sim"] = {"dt": 0.1}
scn = parse(doc, "b")
worlds = [shard_world(scn, k, 4) for k in range(4)]
def run(ticks):
    t0 = time.process_time()
    for _ in range(ticks):
        for w in worlds:
            t = w.tick
            for b in w.blocks(t + 1):
                pass
    return (time.process_time() - t0) / (ticks * N) * 1e6
run(30)
print(f"1-tick blocks: " + " ".join(f"{run(T):.3f}" for _ in range(3)) + " us/ship-tick", flush=True)
t0 = time.process_time()
for w in worlds:
    for b in w.blocks(w.tick + T):
        pass
print(f"{T}-tick blocks: {(time.process_time() - t0) / (T * N) * 1e6:.3f} us/ship-tick")
ss = np.concatenate([w.state.rows["surface_state"] for w in worlds])
u, c = np.unique(ss, return_counts=True); print("states", dict(zip(u.tolist(), c.tolist())))
