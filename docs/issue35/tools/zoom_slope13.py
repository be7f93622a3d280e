import sys, numpy as np
sys.path.insert(0, "tests")
from touchdown.bench import edges3d as E
from touchdown.bench.reference3d import solve3, Start3, Law, feet_state, params_array
from test_edges3d import _start, SHORT_SLIDE_ON_13_DEG as S
sc = _start(**S)
ld, gr = sc.lander(), sc.ground()
par = params_array(ld, gr, Law(), True, False)
t0, t1, dt = float(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
step = float(sys.argv[4]) if len(sys.argv) > 4 else 0.0005
tr = E.run_sim(sc, dt, sim={"max_substep": dt} if dt < 0.005 else None)
k = int(round(t0 / dt))
y0 = np.hstack([tr.d[k], tr.v[k], tr.q[k], tr.w[k]])
p = solve3(ld, gr, Start3(state="contact"), t1 - t0, method="LSODA", y0=y0, stop_at_tipped=False)
for t in np.arange(t0, t1 + 1e-9, step):
    yr = p.y(t - t0); fr = feet_state(yr, par)
    line = "%.4f ref N %s slip %s" % (t, " ".join("%6.1f" % (x/1e3) for x in fr[3]), " ".join("%8.3f" % (1e3*x) for x in fr[4]))
    kk = t / dt
    if abs(kk - round(kk)) < 1e-6:
        kk = int(round(kk)); ym = np.hstack([tr.d[kk], tr.v[kk], tr.q[kk], tr.w[kk]]); fm = feet_state(ym, par)
        line += " | model slip %s" % " ".join("%8.3f" % (1e3*x) for x in fm[4])
    print(line)
