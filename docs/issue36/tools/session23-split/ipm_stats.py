"""Per four-foot IPM problem: Newton steps, _active_set calls/outcomes, _active_newton iterations."""
import collections, numpy as np
import touchdown.sim.friction as fr
d = np.load("/tmp/stick-problems.npz")
C = collections.Counter()
st = {}
a0 = fr._active_set
def aset(*a):
    r = a0(*a); st["calls"] += 1; st["r%d" % r] += 1; return r
fr._active_set = aset
an0 = fr._active_newton
ACT = collections.Counter()
active = np.ones(4, bool)
steps_hist = collections.Counter()
for i in range(len(d["a"])):
    st.clear(); st.update(calls=0, r0=0, r1=0, r2=0)
    lam = np.zeros((4, 2))
    s = fr._interior_point(d["a"][i], d["slip"][i], d["radius"][i], lam, active)
    assert np.array_equal(lam, d["lam_ipm"][i]), i
    steps_hist[s] += 1
    for k in ("calls", "r0", "r1", "r2"):
        C[k] += st[k]
    C["steps"] += s
    C["n"] += 1
    C["finished"] += st["r2"] > 0
print(C, sorted(steps_hist.items()))
