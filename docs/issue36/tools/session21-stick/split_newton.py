import numpy as np
import touchdown.sim.friction as fr
d = np.load("/tmp/stick-problems.npz")
def resid(a, s, r, o):
    lam = o.reshape(4, 2); return fr._residual(a.reshape(4,2,4,2), s, lam, r, np.ones(4, bool))
fails = 0
for k in range(len(d["a"])):
    a = d["a"][k].reshape(8, 8); s = d["slip"][k]; r = d["radius"][k]
    li, lp = d["lam_in"][k], d["lam_ipm"][k]
    rim = [np.hypot(*lp[i]) >= r[i] * (1 - 1e-6) for i in range(4)]
    res_ipm = resid(a, s, r, lp.reshape(8))
    seq = []
    for it in range(0, 8):
        o = np.zeros(8)
        for i in range(4):
            o[2*i:2*i+2] = lp[i] / np.hypot(*lp[i]) * r[i] * fr.RIM if rim[i] else li[i]
        sl = np.array(rim)
        fr._active_newton(a, s.reshape(8).copy(), r.copy(), sl, 4, o, (it, float("inf")))
        seq.append(resid(a, s, r, o))
    if seq[-1] > fr.IPM_TOL_MPS:
        fails += 1
        if fails <= 6:
            print(k, "rim", rim, "ipm res %.2e" % res_ipm, " ".join("%.1e" % x for x in seq))
print("fails", fails)
