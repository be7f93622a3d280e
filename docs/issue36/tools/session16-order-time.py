import sys, time
sys.path.insert(0, "/tmp/order-x/cols")
from envelope_columns import run, FINE
from touchdown.sim import compiled
print("cache", compiled.numba.config.CACHE_DIR, flush=True)
t = time.process_time(); run("/tmp/order-x/cols/fine.npz", dict(FINE)); print("fine cpu", round(time.process_time() - t, 2), flush=True)
V = {"rk4": {}, "midT": {"strike_method": "midpoint", "strike_scope": "ticks"}, "rk3T": {"strike_method": "rk3", "strike_scope": "ticks"}, "midP": {"strike_method": "midpoint"}, "heunT": {"strike_method": "heun", "strike_scope": "ticks"}}
import os
for r in range(3):
    line = []
    for name, ov in V.items():
        t = time.process_time(); run(f"/tmp/order-x/cols/t_{name}.npz", ov); line.append(f"{name} {time.process_time() - t:.3f}")
    print("round", r, os.getloadavg()[0], " | ".join(line), flush=True)
