"""A (note 46's start), B (sample 164), and the 142-start follow check, under sim variants."""
import sys, time, functools
sys.path.insert(0, "/work/wt-order/tests")
import numpy as np
from touchdown.bench import edges3d as E
import test_edges3d as T
V = {"rk4": {}, "midP": {"strike_method": "midpoint"}, "midT": {"strike_method": "midpoint", "strike_scope": "ticks"},
     "heunT": {"strike_method": "heun", "strike_scope": "ticks"}, "rk3T": {"strike_method": "rk3", "strike_scope": "ticks"},
     "heunP": {"strike_method": "heun"}, "rk3P": {"strike_method": "rk3"}}
names = sys.argv[2:]
full = sys.argv[1] == "full"
orig = E.run_sim
A = T._start(12.82672, 206.26773, 62.72895, 6.80023, 2.49824, 0.25, 0.033447, 1e4, 2.00001, 2.61494, 0.0, 0.0)
starts = list(T._sampled_starts(35, 200))
B = T._start(**starts[164])
for name in names:
    t0 = time.time()
    ov = V[name]
    def rs(sc, dt, sim=None, contact=None, _ov=ov):
        s = dict(_ov); s.update(sim or {})
        return orig(sc, dt, s, contact)
    T.E.run_sim = rs
    a = E.distance_m(rs(A, 0.05)); ra = E.distance_m(T._ref(A))
    b = E.distance_m(rs(B, 0.05)); rb = E.distance_m(T._ref(B))
    print(f"{name}: A {a:.5f} (ref {ra:.5f}, {100*(a/ra-1):+.2f}%)  B {b:.5f} (ref {rb:.5f})", flush=True)
    if full:
        checked, misses = 0, []
        for st in starts:
            v = T._follows_the_reference(st)
            if v is None: continue
            checked += 1
            if v: misses.append(v)
        print(f"{name}: checked {checked}, misses {len(misses)}", *misses, sep="\n  ", flush=True)
        m13 = T._follows_the_reference(T.SHORT_SLIDE_ON_13_DEG)
        m14 = T._follows_the_reference(T.ROCKING_STRIKE_ON_14_DEG)
        print(f"{name}: 13deg {m13!r} 14deg {m14!r}", flush=True)
    print(name, "wall", round(time.time() - t0), flush=True)
