"""Per-state step cost at the serve bench's tick (dt 0.1 s), the serve fleet's kinds; and the
serve fleet's state census over time. Runs under either version's python."""
import sys, time, json
import numpy as np
from touchdown.sim.run import run_blocks
from touchdown.sim.scenario import parse
from touchdown.bench.speed import fleet_doc
N = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
T = int(sys.argv[2]) if len(sys.argv) > 2 else 100
rng = np.random.default_rng(7)
KINDS = {
  "flying high (500-50000 m, -5 m/s, 50 m/s across)": lambda i: {"altitude": float(rng.uniform(500, 5e4)), "vertical_speed": -5.0, "horizontal_speed": 50.0},
  "landed": lambda i: {"state": "landed"},
  "tipped": lambda i: {"state": "tipped", "tilt_deg": 90.0},
  "arriving (0.5-30 m, 2-49 m/s down), first 10 s": lambda i: {"altitude": float(rng.uniform(0.5, 30)), "vertical_speed": -float(rng.uniform(2, 49))},
}
def cost(mk, n, ticks, skip=0):
    ships = [{"id": f"s{i}", "initial": {**mk(i), "east": float(i) * 20.0}} for i in range(n)]
    scn = parse({"name": "c", "duration": (ticks + skip) * 0.1, "ships": ships, "sim": {"dt": 0.1}}, "b")
    it = iter(run_blocks(scn))
    best = None
    t0 = time.process_time(); k = 0; census = {}
    for b in it:
        k += len(b)
        ss = b.states["surface_state"][-1]
        for s, c in zip(*np.unique(ss, return_counts=True)):
            census[int(s)] = int(c)
    return (time.process_time() - t0) / (k * n) * 1e6, census
out = {}
for name, mk in KINDS.items():
    cost(mk, 50, 5)  # warm
    us, census = cost(mk, N, T)
    us2, _ = cost(mk, N, T)
    out[name] = min(us, us2)
    print(f"{name:55s} {min(us, us2):7.3f} us/ship-tick  end states {census}", flush=True)
# the serve fleet itself: census at ticks 0, 50, 200, 600 and cost per window
doc = fleet_doc(N, 61.0); doc["sim"] = {"dt": 0.1}
scn = parse(doc, "b")
t0 = time.process_time(); k = 0; marks = {1, 20, 50, 100, 200, 400, 600}; lastt = t0; lastk = 0
for b in run_blocks(scn):
    for j in range(len(b)):
        k += 1
        if k in marks:
            ss = b.states["surface_state"][j]
            u, c = np.unique(ss, return_counts=True)
            now = time.process_time()
            print(f"fleet tick {k:4d}: states {dict(zip(u.tolist(), c.tolist()))}; "
                  f"{(now - lastt) / ((k - lastk) * N) * 1e6:.3f} us/ship-tick since tick {lastk}", flush=True)
            lastt, lastk = now, k
