"""Restart the reference from the model's own state every T inside the impact: local error per stretch."""
import sys, time, numpy as np
sys.path.insert(0, "tests")
from touchdown.bench import edges3d as E
from touchdown.bench.reference3d import solve3, Start3, Law, feet_state, params_array
from test_edges3d import _start, SHORT_SLIDE_ON_13_DEG as S
sc = _start(**S)
ld, gr = sc.lander(), sc.ground()
par = params_array(ld, gr, Law(), True, False)
which = sys.argv[1]; T = float(sys.argv[2]); t_hi = float(sys.argv[3])
cfgs = {"def": (0.005, None), "i1": (0.001, {"max_substep": 0.001}), "i.25": (0.00025, {"max_substep": 0.00025}),
        "s0": (0.005, {"stiff_substep": 0.0})}
dt, sim = cfgs[which]
tr = E.run_sim(sc, dt, sim=sim)
ystate = np.hstack([tr.d, tr.v, tr.q, tr.w])
k_per = int(round(T / dt))
# slide direction: horizontal velocity direction at start ... use the model's overall displacement
disp = E.horizontal_m(tr)[-1]; u = disp / np.linalg.norm(disp)
tot = np.zeros(3); totw = np.zeros(3)
print("t  dv_along(mm/s) dv_up dw(mrad/s)  | model feet N(kN) slip(mm/s) | ref end slip")
k = 0
while tr.t[k] < t_hi - 1e-12:
    y0 = ystate[k].copy(); y0[6:10] /= np.linalg.norm(y0[6:10])
    p = solve3(ld, gr, Start3(state="contact"), T, method="LSODA", y0=y0, stop_at_tipped=False)
    yr = p.y(T)
    ym = ystate[k + k_per]
    dv = ym[3:6] - yr[3:6]
    dw = ym[10:13] - yr[10:13]
    tot += dv; totw += dw
    fm = feet_state(ym, par); fr = feet_state(yr, par)
    print("%.3f %+8.3f %+8.3f %+8.3f | %s | %s | %s | %s" % (tr.t[k], 1e3*(dv[1]*u[0]+dv[2]*u[1]), 1e3*dv[0], 1e3*np.linalg.norm(dw),
          " ".join("%6.1f" % (x/1e3) for x in fm[3]), " ".join("%7.2f" % (1e3*x) for x in fm[4]),
          " ".join("%6.1f" % (x/1e3) for x in fr[3]), " ".join("%7.2f" % (1e3*x) for x in fr[4])), flush=True)
    k += k_per
print("sum dv along %.3f mm/s, dv %s, dw %s" % (1e3*(tot[1]*u[0]+tot[2]*u[1]), tot*1e3, totw*1e3))
