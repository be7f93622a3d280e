"""Dump the four-foot problems the interior-point method solves (uncompiled copy, TD_PY=1) to
/tmp/stick-problems.npz: a_mat, slip, radius, the impulses carried in, the IPM's answer.
    TD_PY=1 PYTHONPATH=/tmp/stick-plain.pkg python dump_problems.py STEP"""
import sys, tomllib
import numpy as np
from touchdown import scenarios
from touchdown.sweep.cases import Axis, Sweep
from touchdown.sweep.fleet import run_part
import touchdown.sim.friction as fr

OUT = {"a": [], "slip": [], "radius": [], "lam_in": [], "lam_ipm": []}
STATE = {"ipm": False}
f0 = fr._interior_point


def ipm(a_mat, slip, radius, lam, active):
    STATE["ipm"] = True
    return f0(a_mat, slip, radius, lam, active)


fr._interior_point = ipm
s0 = fr._solve_feet


def sf(a_mat, slip, radius, lam, active, try_pairs=True):
    lam_in = lam.copy()
    STATE["ipm"] = False
    out = s0(a_mat, slip, radius, lam, active, try_pairs)
    if int(np.sum(active)) == 4 and STATE["ipm"]:
        for k, v in (("a", a_mat), ("slip", slip), ("radius", radius), ("lam_in", lam_in),
                     ("lam_ipm", lam)):
            OUT[k].append(np.array(v, copy=True))
    return out


fr._solve_feet = sf
doc = tomllib.loads(scenarios.text("envelope"))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
        Axis("ships.initial.horizontal_speed", 0.0, 6.0),
        Axis("ships.initial.tilt_deg", 0.0, 15.0)]
run_part(Sweep.of(doc, "envelope", axes, samples=300, seed=1), list(range(0, 300, int(sys.argv[1]))))
np.savez("/tmp/stick-problems.npz", **{k: np.array(v) for k, v in OUT.items()})
print({k: len(v) for k, v in OUT.items()})
