"""Quiet contact ticks ("1 0000": in contact, no foot sliding at the start) of envelope cases, split by the path step_ship took (strike: impact sub-steps; coarse: coarse_tick said yes; fine: it said no), counted in the uncompiled copy (docs/issue35/tools/uncompiled/make.sh /tmp/plain):
    TD_PY=1 PYTHONPATH=/tmp/plain.pkg python quiet_counts.py 15     # cases 0, 15, ... (or a list 0,105)
Writes /tmp/settle/quiet_detail.pkl ((case, tick, path, counts, speed, margin) per tick; quiet_ticks.json is its (case, tick, path) list for cases 0, 15, ..., 285 at fb6b644)."""
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
import touchdown.sim.phases as ph
import touchdown.sim.integrators as ig

C = collections.Counter()
def wrap(mod, name, key):
    f = getattr(mod, name)
    def g(*a, **k):
        C[key] += 1
        r = f(*a, **k)
        if name == "coarse_tick": C["coarse_yes" if r else "coarse_no"] += 1
        if name == "striking" and r:
            C["strikes"] += 1
            here, st = a[0], a[1]
            from touchdown.sim.vec import unit, dot, sub
            from touchdown.sim.frames import surface_velocity
            m = st.motion
            v_rad = dot(sub(m.v, surface_velocity(here.cfg.omega_radps, m.p)), unit(m.p))
            C["why_centre" if abs(v_rad) > 1.0 else "why_foot"] += 1
        if name == "_solve_feet": C[f"solve{int(np.sum(a[4]))}"] += 1
        return r
    setattr(mod, name, g)
wrap(fl, "coarse_tick", "coarse_asked")
wrap(ph, "striking", "strike_asked")
wrap(fl, "step_piece", "pieces")
wrap(fl, "substep", "substep")
wrap(fl, "guard_substep", "subs")
wrap(fr, "_solve_feet", "solves")
wrap(fr, "_dragged_only", "dragged_only")
wrap(fr, "coulomb", "coulomb")
wrap(ig, "rk4_held", "rk4_held")
wrap(ig, "rk4", "rk4")
wrap(fl, "contact_inline", "contact_inline")
wrap(fl, "contact_at", "contact_at")
wrap(fl, "to_event", "to_event")
wrap(fl, "vertical_flight", "vertical_flight")
wrap(fl, "free_flight", "free_flight")

cases = ([int(x) for x in sys.argv[1].split(",")] if "," in sys.argv[1] else list(range(0, 300, int(sys.argv[1])))) if len(sys.argv) > 1 else [0, 105]
doc = tomllib.loads(scenarios.text("envelope"))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0), Axis("ships.initial.horizontal_speed", 0.0, 6.0), Axis("ships.initial.tilt_deg", 0.0, 15.0)]
sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)
groups = collections.defaultdict(collections.Counter)
detail = []
for c in cases:
    one = sw.case_doc(c)
    batch = parse(one, "one")
    recs = list(run(batch))
    for r0, r1 in zip(recs[:-1], recs[1:]):
        row = r0.state.rows[0]
        if int(row["surface_state"]) != 1: continue
        sliding = "".join(str(int(b)) for b in row["sliding"])
        if sliding != "0000": continue
        C.clear()
        step(batch.params, r0.state, r1.inputs)
        path = "strike" if C["strikes"] else ("coarse" if C["coarse_yes"] else ("fine" if C["coarse_no"] else "other"))
        g = groups[path]; g["ticks"] += 1; g.update(C)
        detail.append((c, r0.tick, path, dict(C), float(np.linalg.norm(row["vel_mps"])), float(row["settle_margin"]) if "settle_margin" in row.dtype.names else None))
n = len(cases)
keys = ["ticks", "subs", "pieces", "rk4_held", "rk4", "coulomb", "solves", "solve1", "solve2", "solve3", "solve4", "dragged_only", "contact_inline", "contact_at", "to_event", "why_centre", "why_foot"]
print("path   " + " ".join(f"{k[:8]:>8s}" for k in keys))
tot = collections.Counter()
for path, g in sorted(groups.items()):
    tot.update(g)
    t = g["ticks"]
    print(f"{path:6s} {t/n:8.1f} " + " ".join(f"{g[k]/t:8.2f}" for k in keys[1:]))
t = tot["ticks"]
print(f"{'all':6s} {t/n:8.1f} " + " ".join(f"{tot[k]/t:8.2f}" for k in keys[1:]))
import pickle; pickle.dump(detail, open("/tmp/settle/quiet_detail.pkl", "wb"))
