import math
import numpy as np
from touchdown.sim.friction import _gauss_seidel
def three_feet(rng, tilt_max):
    mass, inertia = 15000.0, np.array([6e4, 6e4, 4e4])
    tilt, az = rng.uniform(0.0, tilt_max), rng.uniform(0.0, 2.0 * math.pi)
    axis = np.array([math.cos(az), math.sin(az), 0.0])
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    rot = np.eye(3) + math.sin(tilt) * k + (1.0 - math.cos(tilt)) * k @ k
    feet = np.array([[2.5, 0.0, -1.6], [0.0, 2.5, -1.6], [-2.5, 0.0, -1.6], [0.0, -2.5, -1.6]])
    offsets = feet @ rot.T
    t1, t2 = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    pressing = rng.permutation(4)[:3]
    jac = np.array([np.concatenate([t / math.sqrt(mass), np.cross(offsets[i], t) / np.sqrt(inertia)])
                    for i in pressing for t in (t1, t2)])
    motion = rng.normal(0.0, 1.0, 6) * rng.choice([1e-2, 1e-1, 1.0])
    mu_j = rng.choice([0.4, 0.6, 1.0]) * rng.uniform(100.0, 5000.0, 3)
    return jac @ jac.T, jac @ motion, mu_j
for tm in (0.0, 0.05, 0.3):
    rng = np.random.default_rng(69); out = []
    for _ in range(40):
        a2, s2, r = three_feet(rng, tm)
        a = np.zeros((4, 2, 4, 2)); a[:3, :, :3, :] = a2.reshape(3, 2, 3, 2)
        slip = np.zeros((4, 2)); slip[:3] = s2.reshape(3, 2)
        radius = np.zeros(4); radius[:3] = r
        out.append(bool(_gauss_seidel(a, slip, radius, np.zeros((4, 2)), radius > 0, True)))
    print(tm, sum(out), np.linalg.cond(a2))
from touchdown.sim.friction import _solve_feet
worst = 0.0
for tm in (0.0, 0.3):
    rng = np.random.default_rng(69)
    for _ in range(40):
        a2, s2, r = three_feet(rng, tm)
        a = np.zeros((4, 2, 4, 2)); a[:3, :, :3, :] = a2.reshape(3, 2, 3, 2)
        slip = np.zeros((4, 2)); slip[:3] = s2.reshape(3, 2)
        radius = np.zeros(4); radius[:3] = r
        res = []
        for sw in (True, False):
            lam = np.zeros((4, 2)); m = _solve_feet(a, slip, radius, lam, radius > 0, True, sw)
            res.append((m, a2 @ lam[:3].reshape(-1) + s2, np.linalg.norm(lam, axis=1).sum()))
        d = np.abs(res[0][1] - res[1][1]).max()
        worst = max(worst, d)
        if tm == 0.0 and _ < 8 or abs(res[0][2] - res[1][2]) > 1e-6 * res[0][2]:
            print(tm, res[0][0], res[1][0], "slip diff %.2e" % d, "sum|lam| %.6g %.6g" % (res[0][2], res[1][2]))
print("worst", worst)
print("== warm from a carried impulse near the solution (every foot carrying one)")
for tm in (0.0, 0.3):
    rng = np.random.default_rng(7); rows = []
    for _ in range(40):
        a2, s2, r = three_feet(rng, tm)
        a = np.zeros((4, 2, 4, 2)); a[:3, :, :3, :] = a2.reshape(3, 2, 3, 2)
        slip = np.zeros((4, 2)); slip[:3] = s2.reshape(3, 2)
        radius = np.zeros(4); radius[:3] = r
        lam0 = np.zeros((4, 2)); _solve_feet(a, slip, radius, lam0, radius > 0, True, True)
        carried = lam0 * (1.0 + 0.05 * rng.normal(size=(4, 2)))
        n = np.linalg.norm(carried, axis=1); f = np.minimum(1.0, 0.98 * radius / np.maximum(n, 1e-300))
        carried = carried * f[:, None]
        out = []
        for sw in (True, False):
            lam = carried.copy(); m = _solve_feet(a, slip, radius, lam, radius > 0, True, sw)
            out.append((m, a2 @ lam[:3].reshape(-1) + s2, np.linalg.norm(lam, axis=1).sum()))
        rows.append((out[0][0], out[1][0], np.abs(out[0][1] - out[1][1]).max(), out[0][2], out[1][2]))
    rows = np.array(rows)
    print(tm, "GS-first methods", np.bincount(rows[:, 0].astype(int)), "slip diff max %.2e" % rows[:, 2].max(),
          "sum|lam| ratio skip/GS: max %.3g median %.3g" % ((rows[:, 4] / rows[:, 3]).max(), np.median(rows[:, 4] / rows[:, 3])))
