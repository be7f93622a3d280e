"""Offline look at /tmp/stick-problems.npz (dump_problems.py): the IPM answers' slips, the carried
impulses' fill of their disks, A's spectrum, the direct sticking solve's need, and the active-set
Newton iterations from the IPM's own split (TD_PY=1, uncompiled copy)."""
import numpy as np
import touchdown.sim.friction as fr

d = np.load("/tmp/stick-problems.npz")
n = len(d["a"])
q = lambda x: "p50 %.3g p90 %.3g max %.3g" % (np.percentile(x, 50), np.percentile(x, 90), np.max(x))
slip_rim, slip_stick, fill_c_rim, fill_c_stick, eig, need, rims = [], [], [], [], [], [], []
conv = {it: 0 for it in (3, 6, 10, 20, 30)}
for k in range(n):
    a = d["a"][k].reshape(8, 8); s = d["slip"][k]; r = d["radius"][k]
    li, lp = d["lam_in"][k], d["lam_ipm"][k]
    post = (s.reshape(8) + a @ lp.reshape(8)).reshape(4, 2)
    w = np.linalg.eigvalsh(a); eig.append(w / w[-1])
    rim = [np.hypot(*lp[i]) >= r[i] * (1 - 1e-6) for i in range(4)]
    rims.append(sum(rim))
    for i in range(4):
        (slip_rim if rim[i] else slip_stick).append(np.hypot(*post[i]))
        (fill_c_rim if rim[i] else fill_c_stick).append(np.hypot(*li[i]) / r[i])
    rr = s.reshape(8) + a @ li.reshape(8)
    dd = (-np.linalg.pinv(a, rcond=1e-10, hermitian=True) @ rr).reshape(4, 2)
    need.append(np.max(np.hypot(dd[:, 0], dd[:, 1]) / r))
    for it in conv:
        o = np.zeros(8)
        for i in range(4):
            o[2 * i:2 * i + 2] = lp[i] / np.hypot(*lp[i]) * r[i] * fr.RIM if rim[i] else li[i]
        conv[it] += fr._active_newton(a, s.reshape(8).copy(), r.copy(), np.array(rim), 4, o,
                                      (it, float("inf"))) == 2
eig = np.array(eig)
print(n, "problems; rim feet in the IPM's answer:", np.bincount(rims))
print("rim feet's slip after (m/s):", q(slip_rim))
print("sticking feet's slip after (m/s):", q(slip_stick))
print("carried fill |lam_in|/radius, the IPM's rim feet:", q(fill_c_rim))
print("carried fill, the IPM's sticking feet:", q(fill_c_stick))
for j in range(6):
    print(f"A's eigenvalue {j + 1} / largest:", q(eig[:, j]))
print("direct sticking solve: largest |lam_i| / radius:", q(np.array(need)))
print("active-set Newton from the IPM's own split converged within k iterations:", conv)
