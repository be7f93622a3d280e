"""Offline: the four-foot IPM problems with FINISH_GAPS variants (uncompiled copy): steps, finish
tries, Newton iterations of the finish, the answer's residual and its slips against main's."""
import collections, sys, numpy as np
import touchdown.sim.friction as fr
d = np.load("/tmp/stick-problems.npz")
n = len(d["a"])
active = np.ones(4, bool)
an0 = fr._active_newton
st = collections.Counter()
def an(a_loc, u0, rho, slips, n_feet, out, limits):
    st["newton_calls"] += 1
    r = an0(a_loc, u0, rho, slips, n_feet, out, limits)
    return r
fr._active_newton = an
as0 = fr._active_set
def aset(*a):
    st["aset_calls"] += 1
    return as0(*a)
fr._active_set = aset
cf0 = fr._cholesky_factor
def cf(h, m, l, semi):
    st["chol_semi" if semi else "chol_ipm"] += 1
    return cf0(h, m, l, semi)
fr._cholesky_factor = cf
for gaps in [(1e-4, 1e-6), (1e-3, 1e-5), (1e-2, 1e-4), (1e-1, 1e-3), (3e-1, 1e-2)]:
    fr.FINISH_GAPS = gaps
    st.clear()
    worst = 0.0; dslip = 0.0; steps = 0
    for i in range(n):
        lam = np.zeros((4, 2))
        steps += fr._interior_point(d["a"][i], d["slip"][i], d["radius"][i], lam, active)
        worst = max(worst, fr._residual(d["a"][i], d["slip"][i], lam, d["radius"][i], active))
        a = d["a"][i].reshape(8, 8)
        v1 = d["slip"][i].reshape(8) + a @ lam.reshape(8)
        v0 = d["slip"][i].reshape(8) + a @ d["lam_ipm"][i].reshape(8)
        dslip = max(dslip, np.abs(v1 - v0).max())
    print(gaps, "steps/solve %.2f" % (steps / n), {k: round(v / n, 2) for k, v in st.items()},
          "worst residual %.2e max |dslip| %.2e" % (worst, dslip), flush=True)
