"""Four-foot interior-point solves per envelope touchdown (uncompiled copy), sim.coarse_held 0.1 vs 0."""
import collections, sys, tomllib
import numpy as np
from touchdown import scenarios
from touchdown.sweep.cases import Axis, Sweep
from touchdown.sweep.fleet import run_part
import touchdown.sim.friction as fr
import touchdown.sim.flight as fl
C = collections.Counter()
f0 = fr._interior_point
def ipm(a_mat, slip, radius, lam, active):
    C[f"ipm{int(np.sum(active))}"] += 1
    return f0(a_mat, slip, radius, lam, active)
fr._interior_point = ipm
s0 = fr._solve_feet
def sf(a_mat, slip, radius, lam, active, try_pairs=True):
    C[f"solve{int(np.sum(active))}"] += 1
    return s0(a_mat, slip, radius, lam, active, try_pairs)
fr._solve_feet = sf
c0 = fl.coarse_tick
def ct(*a):
    r = c0(*a); C["coarse_yes" if r else "coarse_no"] += 1; return r
fl.coarse_tick = ct
cases = list(range(0, 300, int(sys.argv[1])))
for held in (0.1, 0.0):
    doc = tomllib.loads(scenarios.text("envelope"))
    doc.setdefault("sim", {})["coarse_held"] = held
    axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
            Axis("ships.initial.horizontal_speed", 0.0, 6.0),
            Axis("ships.initial.tilt_deg", 0.0, 15.0)]
    sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)
    C.clear()
    res = run_part(sw, cases)
    n = len(cases)
    print(f"coarse_held {held}: {n} cases; per touchdown " + ", ".join(
        f"{k} {v / n:.2f}" for k, v in sorted(C.items())), flush=True)
