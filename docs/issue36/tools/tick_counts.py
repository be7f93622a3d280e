"""Per tick of envelope touchdowns (flying near the ground and in contact): sub-steps, pieces,
method steps, friction solves by active feet, coarse_tick's answers and contact evaluations,
counted by wrapping the uncompiled copy's functions (issue 36, session 12):

    docs/issue35/tools/uncompiled/make.sh /tmp/plain
    TD_PY=1 PYTHONPATH=/tmp/plain.pkg python tick_counts.py [STRIDE]   # cases 0, STRIDE, ... of 300
"""
import collections, copy, sys, tomllib
import numpy as np
from touchdown import scenarios
from touchdown.sim.run import run
from touchdown.sim.scenario import parse
from touchdown.sim.state import Inputs, State
from touchdown.sim.step import step
from touchdown.sweep.cases import Axis, Sweep
import touchdown.sim.flight as fl
import touchdown.sim.friction as fr

C = collections.Counter()
def wrap(mod, name, key):
    f = getattr(mod, name)
    def g(*a, **k):
        C[key] += 1
        r = f(*a, **k)
        if name == "coarse_tick" and r: C["coarse_yes"] += 1
        if name == "_solve_feet": C[f"solve{int(np.sum(a[4]))}"] += 1
        return r
    setattr(mod, name, g)
wrap(fl, "coarse_tick", "coarse_asked")
wrap(fl, "step_piece", "pieces")
wrap(fl, "substep", "substep")
wrap(fl, "guard_substep", "subs")
wrap(fr, "_solve_feet", "solves")
wrap(fl, "contact_inline", "contact_inline")
wrap(fl, "contact_at", "contact_at")

stride = int(sys.argv[1]) if len(sys.argv) > 1 else 30
doc = tomllib.loads(scenarios.text("envelope"))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0), Axis("ships.initial.horizontal_speed", 0.0, 6.0), Axis("ships.initial.tilt_deg", 0.0, 15.0)]
sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)
groups = collections.defaultdict(collections.Counter)
for c in range(0, 300, stride):
    one = sw.case_doc(c)
    batch = parse(one, "one")
    recs = list(run(batch))
    for r0, r1 in zip(recs[:-1], recs[1:]):
        row = r0.state.rows[0]
        if int(row["surface_state"]) not in (0, 1): continue
        C.clear()
        step(batch.params, r0.state, r1.inputs)
        sliding = "".join(str(int(b)) for b in row["sliding"])
        key = (int(row["surface_state"]), sliding)
        groups[key]["ticks"] += 1
        groups[key].update(C)
n = len(range(0, 300, stride))
keys = ["ticks", "subs", "pieces", "substep", "solves", "solve1", "solve2", "solve3", "solve4", "coarse_asked", "coarse_yes", "contact_inline", "contact_at"]
print("state slide " + " ".join(f"{k[:8]:>8s}" for k in keys) + "   (per case; ticks, then per tick)")
for key, g in sorted(groups.items(), key=lambda kv: -kv[1]["ticks"]):
    t = g["ticks"]
    print(f"{key[0]:5d} {key[1]:>5s} {t/n:8.1f} " + " ".join(f"{g[k]/t:8.2f}" for k in keys[1:]))
