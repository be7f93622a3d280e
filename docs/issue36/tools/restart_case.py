"""Envelope case C: the first tick where note 58's rule and a variant part, the model restarted
there for N ticks under each variant and the fine settings, and the 3-D reference from the same
state; end positions and velocities against the reference's (issue 36, session 14, fast42d).
On the uncompiled copy of a tree with transition_variants.patch applied:
    TD_PY=1 PYTHONPATH=/tmp/plain.pkg python restart_case.py CASE TICKS      # e.g. 173 10"""
import sys, copy, tomllib
import numpy as np
from touchdown import scenarios
from touchdown.sim.run import run
from touchdown.sim.scenario import parse
from touchdown.sim.step import step
from touchdown.sweep.cases import Axis, Sweep
from touchdown.bench.reference3d import Ground3, Lander3, Law, Start3, solve3, MOON_R
c, N = int(sys.argv[1]), int(sys.argv[2])
V = {"note58": {"transition_pairs": False}, "m5": {"transition_pairs": False, "transition_mode_x": 5.0},
     "noat": {"transition_mode_x": 2.0},
     "fine": {"max_substep": 0.005, "impact_substep": 0.001, "coarse_substep": 0.0, "stiff_substep": 0.0001}}
doc = tomllib.loads(scenarios.text("envelope"))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0), Axis("ships.initial.horizontal_speed", 0.0, 6.0), Axis("ships.initial.tilt_deg", 0.0, 15.0)]
sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)
d0 = sw.case_doc(c)
P = {}
for vn, ov in V.items():
    d = copy.deepcopy(d0); d.setdefault("sim", {}).update(ov); P[vn] = parse(d, "one")
ra = list(run(P["note58"])); rb = list(run(P["m5"]))
def key(r):
    x = r.state.rows[0]
    return np.concatenate([x["pos_m"], x["vel_mps"], x["quat"], x["omega_body_radps"]]).tobytes()
k = next(i for i, (a, b) in enumerate(zip(ra, rb)) if key(a) != key(b))
k0 = k - 1
r0 = ra[k0]; row = r0.state.rows[0]
print("case", c, "first differing state at tick", k, "restart from tick", r0.tick, "sliding", row["sliding"])
dt = P["note58"].params.sim.dt_s
out = {}
for vn in V:
    st = r0.state
    for j in range(N):
        st = step(P[vn].params, st, ra[min(k0 + j + 1, len(ra) - 1)].inputs)[0]
    rr = st.rows[0]; out[vn] = (np.array(rr["pos_m"]), np.array(rr["vel_mps"]), np.array(rr["omega_body_radps"]), int(rr["surface_state"]))
y0 = np.concatenate([np.array(row["pos_m"]) - np.array([MOON_R, 0, 0]), row["vel_mps"], row["quat"], row["omega_body_radps"]])
ab = bool(row["absorbing"])
path = solve3(Lander3(), Ground3(slope_deg=6.0, slope_azimuth_deg=90.0), Start3(state="contact", vertical_speed_mps=0.0 if ab else 20.0), N * dt, law=Law(), method="LSODA", y0=y0, stop_at_tipped=False)
y1 = path.y(N * dt); ref = (y1[0:3] + np.array([MOON_R, 0, 0]), y1[3:6], y1[10:13])
p0 = np.array(row["pos_m"])
print(f"over {N * dt:.2f} s the reference moves {1e3*np.linalg.norm(ref[0]-p0):.2f} mm")
for vn, (p, v, w, s) in out.items():
    print(f"{vn:7s} pos off {1e3*np.linalg.norm(p-ref[0]):8.3f} mm  vel off {1e3*np.linalg.norm(v-ref[1]):8.3f} mm/s  rates off {1e3*np.linalg.norm(w-ref[2]):7.3f} mrad/s  moved {1e3*np.linalg.norm(p-p0):.2f} mm state {s}")
