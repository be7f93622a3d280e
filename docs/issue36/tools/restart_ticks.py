"""Contact ticks of envelope touchdowns with two opposite feet sliding at the tick's start (1010 /
0101), each restarted from the model's own state and stepped one tick by variants of
transition_variants.patch (note 58's rule, mode 5 = MODEL-NOTES 70's, no at_transition), the fine
settings, and the 3-D reference (bench.reference3d, LSODA) from the same state (absorbed as the
model's footing is). Prints each tick's end-state distance from the reference's (position, um;
velocity, mm/s; body rates, mrad/s), at_transition's fires and the pieces (issue 36, session 14,
fast42d). On the uncompiled copy of a tree with the patch applied:
    TD_PY=1 PYTHONPATH=/tmp/plain.pkg python restart_ticks.py STRIDE OUT.pkl"""
import collections, copy, sys, tomllib, pickle, time
import numpy as np
from touchdown import scenarios
from touchdown.sim.run import run
from touchdown.sim.scenario import parse
from touchdown.sim.step import step
from touchdown.sweep.cases import Axis, Sweep
import touchdown.sim.flight as fl
from touchdown.bench.reference3d import Ground3, Lander3, Law, Start3, solve3, MOON_R

C = collections.Counter()
for name in ("step_piece", "substep"):
    f0 = getattr(fl, name)
    def g(*a, _f=f0, _n=name, **k):
        C[_n] += 1
        return _f(*a, **k)
    setattr(fl, name, g)
fat = fl.at_transition
def atw(*a, **k):
    r = fat(*a, **k)
    if r: C["at_fire"] += 1
    return r
fl.at_transition = atw

VARIANTS = {"old": {"transition_pairs": False}, "m5": {"transition_pairs": False, "transition_mode_x": 5.0},
            "noat": {"transition_mode_x": 2.0},
            "fine": {"max_substep": 0.005, "impact_substep": 0.001, "coarse_substep": 0.0,
                     "stiff_substep": 0.0001}}
stride = int(sys.argv[1]) if len(sys.argv) > 1 else 30
pats = ("1010", "0101")
doc = tomllib.loads(scenarios.text("envelope"))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0), Axis("ships.initial.horizontal_speed", 0.0, 6.0), Axis("ships.initial.tilt_deg", 0.0, 15.0)]
sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)
ld, gr = Lander3(), Ground3(slope_deg=6.0, slope_azimuth_deg=90.0)
out = []
for c in range(0, 300, stride):
    d0 = sw.case_doc(c)
    batch = parse(d0, "one")
    params = {}
    for vn, ov in VARIANTS.items():
        d = copy.deepcopy(d0); d.setdefault("sim", {}).update(ov)
        params[vn] = parse(d, "one").params
    dt = batch.params.sim.dt_s
    recs = list(run(batch))
    for r0, r1 in zip(recs[:-1], recs[1:]):
        row = r0.state.rows[0]
        if int(row["surface_state"]) != 1: continue
        pat = "".join(str(int(b)) for b in row["sliding"])
        if pat not in pats: continue
        res = {}
        for vn, p in params.items():
            C.clear()
            r = step(p, r0.state, r1.inputs)
            st = (r[0] if isinstance(r, tuple) else r)
            rr = st.rows[0] if hasattr(st, "rows") else st.state.rows[0]
            res[vn] = (np.array(rr["pos_m"]), np.array(rr["vel_mps"]), np.array(rr["omega_body_radps"]),
                       np.array(rr["quat"]), dict(C))
        y0 = np.concatenate([np.array(row["pos_m"]) - np.array([MOON_R, 0, 0]), row["vel_mps"], row["quat"], row["omega_body_radps"]])
        t0 = time.time()
        absorbing = bool(row["absorbing"])
        path = solve3(ld, gr, Start3(state="contact", vertical_speed_mps=0.0 if absorbing else 20.0),
                      dt, law=Law(), method="LSODA", y0=y0, stop_at_tipped=False)
        y1 = path.y(dt)
        ref = (y1[0:3] + np.array([MOON_R, 0, 0]), y1[3:6], y1[10:13], y1[6:10])
        out.append(dict(case=c, tick=int(r0.tick), pat=pat, res=res, ref=ref, t_ref=time.time() - t0))
        e = {vn: (1e3 * np.linalg.norm(v[0] - ref[0]), 1e3 * np.linalg.norm(v[1] - ref[1]), 1e3 * np.linalg.norm(v[2] - ref[2]), v[4].get("at_fire", 0), v[4].get("step_piece", 0)) for vn, v in res.items()}
        print(c, int(r0.tick), pat, " ".join(f"{vn}: {x[0]:.3f}mm {x[1]:.2f}mm/s {x[2]:.3f}mrad/s at{x[3]} pc{x[4]}" for vn, x in e.items()), flush=True)
pickle.dump(out, open(sys.argv[2] if len(sys.argv) > 2 else "/tmp/restart_ticks.pkl", "wb"))
