"""Per tick of bench/states.py's scenes (one ship, 40 ticks): sub-steps, method steps, pieces, coarse_tick's answers,
derivative and contact evaluations, friction solves by feet (issue 36, session 14, fast42b; the counters of
strike_counts.py). Uncompiled copy (docs/issue35/tools/uncompiled/make.sh /tmp/plain):

    TD_PY=1 PYTHONPATH=/tmp/plain.pkg python scene_counts.py sliding|rocking [BENCH_DIR]
"""
import collections, sys
import numpy as np
sys.path.insert(0, sys.argv[2] if len(sys.argv) > 2 else __import__("os").path.join(__import__("os").path.dirname(__file__), "../../../bench"))
import states
from touchdown.sim.run import run
from touchdown.sim.scenario import parse
from touchdown.sim.step import step
import touchdown.sim.flight as fl
import touchdown.sim.friction as fr
import touchdown.sim.phases as ph

C = collections.Counter()
def wrap(mod, name, key, post=None):
    f = getattr(mod, name)
    def g(*a, **k):
        C[key] += 1
        r = f(*a, **k)
        if post: post(a, r)
        return r
    setattr(mod, name, g)
def solve_post(a, r): C[f"solve{int(np.sum(a[4]))}"] += 1
def piece_post(a, r):
    if r.split:
        if r.refined and r.tau_s < a[3]*(1-1e-9) and not any(r.onset) and not any(r.stopped):
            C["p_refined"] += 1
        else:
            C["p_event"] += 1
def strike_post(a, r):
    if r: C["strikes"] += 1
def coarse_post(a, r):
    if r: C["coarse_yes"] += 1
wrap(fl, "step_piece", "pieces", piece_post)
wrap(fl, "substep", "substep")
wrap(fl, "to_event", "to_event")
wrap(fl, "guard_substep", "subs")
wrap(fl, "coarse_tick", "coarse_asked", coarse_post)
wrap(fr, "_solve_feet", "solves", solve_post)
wrap(fl, "contact_inline", "c_inl")
wrap(fl, "contact_at", "c_at")
wrap(fl, "slip_rates", "slip_rates")
wrap(ph, "striking", "strk_asked", strike_post)
import touchdown.sim.integrators as ig
for mod in (ig, fl):
    wrap(mod, "derivatives_held", "derivatives_held")
wrap(ig, "derivatives", "derivatives")
wrap(ig, "contact_inline", "c_inl")
wrap(ig, "contact_at", "c_at")
which = sys.argv[1]
label, ini, inputs = [sc for sc in states.SCENES if which in sc[0]][0]
scn = parse({"name": "cost", "duration": 40 * 0.05, "ships": states.ships_in_state(ini, inputs, 1),
             "sim": {"dt": 0.05}}, "bench")
recs = list(run(scn))
keys = ["subs","pieces","p_refined","p_event","substep","to_event","coarse_asked","coarse_yes","slip_rates","derivatives_held","derivatives","solves","solve1","solve2","solve3","solve4","c_inl","c_at","strikes"]
tot = collections.Counter()
print(label)
print("tick st sliding " + " ".join(f"{k[:7]:>7s}" for k in keys) + "  slips mm/s  pen mm")
for r0, r1 in zip(recs[:-1], recs[1:]):
    row = r0.state.rows[0]
    C.clear()
    step(scn.params, r0.state, r1.inputs)
    tot.update(C); tot["ticks"] += 1
    sl = "".join(str(int(b)) for b in row["sliding"])
    extra = ""
    for f in ("slip_mps", "foot_slip_mps"):
        if f in row.dtype.names: extra = " ".join(f"{1e3*x:.1f}" for x in np.ravel(row[f]))
    print(f"{int(r0.tick):4d} {int(row['surface_state']):2d} {sl:>7s} " + " ".join(f"{C[k]:7d}" for k in keys) + "  " + extra)
t = tot["ticks"]
print("mean      " + " ".join(f"{tot[k]/t:7.2f}" for k in keys))
