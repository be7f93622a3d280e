"""Per tick of envelope touchdowns (flying near the ground and in contact), split by whether the
tick takes the impact's sub-steps (sim.phases.striking at its start: "S"): sub-steps, pieces (cut
short where Coulomb's law is stiff, or at an event), at_transition's fires, method steps, located
events, friction solves by active feet and by path (Gauss-Seidel's give-ups, the carried try, the
interior-point method), contact evaluations; counted by wrapping the uncompiled copy's functions
(issue 36, session 13, fast41c; tick_counts.py's, with the striking flag and the paths):

    docs/issue35/tools/uncompiled/make.sh /tmp/plain
    TD_PY=1 PYTHONPATH=/tmp/plain.pkg python strike_counts.py [STRIDE [PER.pkl]]

OVR='{"KEY": VALUE, ...}' in the environment sets sim keys of the envelope scene (session 15,
strike: e.g. OVR='{"stiff_carry": true, "impact_stiff_substep": 0.003}' with session15-stiff-carry.patch).

PER.pkl keeps each (case, tick)'s key and counts for strike_join.py, which joins them with
tick_costs.py's per-tick CPU times."""
import collections, sys, tomllib
import numpy as np
from touchdown import scenarios
from touchdown.sim.run import run
from touchdown.sim.scenario import parse
from touchdown.sim.step import step
from touchdown.sweep.cases import Axis, Sweep
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
def solve_post(a, r):
    n = int(np.sum(a[4])); C[f"solve{n}"] += 1
def fc_post(a, r):
    n = int(np.sum(a[4])); C[f"try{n}_{'ok' if r else 'no'}"] += 1
def ipm_post(a, r):
    n = int(np.sum(a[4])); C[f"ipm{n}"] += 1
def gs_post(a, r):
    n = int(np.sum(a[4])); C[f"gs{n}_{'ok' if r else 'no'}"] += 1
def piece_post(a, r):
    if r.split:
        if r.refined and r.tau_s < a[3]*(1-1e-9) and not any(r.onset) and not any(r.stopped):
            C["p_refined"] += 1
        else:
            C["p_event"] += 1
def at_post(a, r):
    if r: C["at_fire"] += 1
def strike_post(a, r):
    if r: C["strikes"] += 1
wrap(fl, "step_piece", "pieces", piece_post)
wrap(fl, "substep", "substep")
wrap(fl, "to_event", "to_event")
wrap(fl, "guard_substep", "subs")
wrap(fl, "at_transition", "at_asked", at_post)
wrap(fr, "_solve_feet", "solves", solve_post)
wrap(fr, "_gauss_seidel", "gs", gs_post)
wrap(fr, "_from_carried", "tries", fc_post)
wrap(fr, "_interior_point", "ipm", ipm_post)
wrap(fl, "contact_inline", "c_inl")
wrap(fl, "contact_at", "c_at")
wrap(ph, "striking", "strk_asked", strike_post)
import touchdown.sim.integrators as ig
wrap(ig, "contact_inline", "c_stage")
wrap(ig, "derivatives_held", "d_held")
wrap(ig, "derivatives", "d_plain")
stride = int(sys.argv[1]) if len(sys.argv) > 1 else 30
doc = tomllib.loads(scenarios.text("envelope")); import os, json; doc.setdefault("sim", {}).update(json.loads(os.environ.get("OVR", "{}")))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0), Axis("ships.initial.horizontal_speed", 0.0, 6.0), Axis("ships.initial.tilt_deg", 0.0, 15.0)]
sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)
groups = collections.defaultdict(collections.Counter)
per = {}
for c in range(0, 300, stride):
    batch = parse(sw.case_doc(c), "one")
    recs = list(run(batch))
    for r0, r1 in zip(recs[:-1], recs[1:]):
        row = r0.state.rows[0]
        if int(row["surface_state"]) not in (0, 1): continue
        C.clear()
        step(batch.params, r0.state, r1.inputs)
        sliding = "".join(str(int(b)) for b in row["sliding"])
        key = (int(row["surface_state"]), sliding, "S" if C["strikes"] else "-")
        groups[key]["ticks"] += 1
        per[(c, int(r0.tick))] = (key, dict(C))
        groups[key].update(C)
n = len(range(0, 300, stride))
keys = ["ticks","subs","pieces","p_refined","p_event","at_fire","substep","to_event","solves","solve1","solve2","solve3","solve4","gs2_no","gs3_no","gs4_no","try2_ok","try2_no","try3_ok","ipm2","ipm3","ipm4","c_inl","c_at","c_stage","d_held","d_plain"]
tot = collections.Counter(); totS = collections.Counter()
for key, g in groups.items():
    tot.update(g)
    if key[2] == "S": totS.update(g)
print("per touchdown, all ticks:", {k: round(tot[k]/n, 1) for k in keys})
print("per touchdown, striking ticks:", {k: round(totS[k]/n, 1) for k in keys})
print("st slide S " + " ".join(f"{k[:7]:>7s}" for k in keys))
for key, g in sorted(groups.items(), key=lambda kv: -kv[1]["ticks"]):
    t = g["ticks"]
    print(f"{key[0]:2d} {key[1]:>5s} {key[2]} {t/n:7.1f} " + " ".join(f"{g[k]/t:7.2f}" for k in keys[1:]))

import pickle; pickle.dump(per, open(sys.argv[2] if len(sys.argv) > 2 else "/tmp/f41c/per.pkl", "wb"))
