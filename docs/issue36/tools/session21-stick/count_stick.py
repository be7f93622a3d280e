"""Four-foot interior-point solves per envelope touchdown (uncompiled copy, TD_PY=1): how many end
with every foot inside its disk (all stick), and what the direct sticking solve (the carried
impulses plus the min-norm correction in the Delassus matrix's range) would give beside them.
    TD_PY=1 PYTHONPATH=/tmp/stick-plain.pkg python count_stick.py STEP   (cases 0, STEP, ... < 300)
"""
import collections, sys, tomllib
import numpy as np
from touchdown import scenarios
from touchdown.sweep.cases import Axis, Sweep
from touchdown.sweep.fleet import run_part
import touchdown.sim.friction as fr

C = collections.Counter()
WORST = collections.defaultdict(float)
STATE = {"ipm": False}
f0 = fr._interior_point


def ipm(a_mat, slip, radius, lam, active):
    STATE["ipm"] = True
    return f0(a_mat, slip, radius, lam, active)


fr._interior_point = ipm


def direct(a_mat, slip, radius, lam_in):
    a = a_mat.reshape(8, 8)
    r = slip.reshape(8) + a @ lam_in.reshape(8)
    d = -np.linalg.pinv(a, rcond=1e-10, hermitian=True) @ r
    lam = lam_in.reshape(8) + d
    return lam.reshape(4, 2)


def inside(lam, radius):
    return all(lam[i, 0] ** 2 + lam[i, 1] ** 2 < radius[i] ** 2 * (1.0 - 1e-9) for i in range(4))


s0 = fr._solve_feet


def sf(a_mat, slip, radius, lam, active, try_pairs=True):
    n = int(np.sum(active))
    lam_in = lam.copy()
    STATE["ipm"] = False
    if n == 4:  # the carried try, to its last iteration (rate inf), on copies
        lc = lam.copy()
        STATE["fc_ok"] = bool(fr._from_carried(a_mat, slip, radius, lc, active, float("inf")))
        STATE["fc_lam"] = lc
    out = s0(a_mat, slip, radius, lam, active, try_pairs)
    if n == 4 and STATE["ipm"]:
        C["ipm4"] += 1
        a = a_mat.reshape(8, 8)
        post_ipm = slip.reshape(8) + a @ lam.reshape(8)
        ipm_in = inside(lam, radius)
        C["ipm4_all_inside"] += ipm_in
        ld = direct(a_mat, slip, radius, lam_in)
        post_d = slip.reshape(8) + a @ ld.reshape(8)
        d_in = inside(ld, radius)
        res_d = fr._residual(a_mat, slip, ld, radius, active)
        ok = d_in and res_d <= fr.IPM_TOL_MPS
        C["direct_ok"] += ok
        C["direct_ok_ipm_inside"] += ok and ipm_in
        C["direct_inside_res_fail"] += d_in and not ok
        C["ipm_inside_direct_out"] += ipm_in and not d_in
        C["carried_zero"] += not np.any(lam_in)
        rim = sum(lam[i, 0] ** 2 + lam[i, 1] ** 2 >= radius[i] ** 2 * (1.0 - 1e-9)
                  for i in range(4))
        C[f"ipm_rim_feet_{rim}"] += 1
        slip_max = float(np.max(np.hypot(post_ipm[0::2], post_ipm[1::2])))
        C["ipm_slip_max_over_1e-7"] += slip_max > 1e-7
        C["ipm_slip_max_over_1e-9"] += slip_max > 1e-9
        # the slips' part the ship's 6 freedoms can stop (range of A) and the part they cannot
        w, v = np.linalg.eigh(a)
        big = w > 1e-10 * w[-1]
        C[f"rank_{int(np.sum(big))}"] += 1
        r_in = slip.reshape(8) + a @ lam_in.reshape(8)
        WORST["smallest_kept_eig_rel"] = max(WORST["smallest_kept_eig_rel"],
                                             float(np.min(w[big]) / w[-1]))
        d_need = np.hypot(*((-np.linalg.pinv(a, rcond=1e-10, hermitian=True) @ r_in)
                            .reshape(4, 2).T))
        C["direct_over_10x_disk"] += bool(np.max(d_need / radius) > 10)
        if STATE["fc_ok"]:
            C["carried_try_ok"] += 1
            post_c = slip.reshape(8) + a @ STATE["fc_lam"].reshape(8)
            WORST["carried_slip_diff"] = max(WORST["carried_slip_diff"],
                                             float(np.max(np.abs(post_c - post_ipm))))
        # the IPM's own split (its rim feet slipping) given to the active-set Newton iterations
        idx_rim = [lam[i, 0] ** 2 + lam[i, 1] ** 2 >= radius[i] ** 2 * (1.0 - 1e-6)
                   for i in range(4)]
        out8 = np.zeros(8)
        for i in range(4):
            ln = np.hypot(lam_in[i, 0], lam_in[i, 1])
            if idx_rim[i]:
                l = lam[i] / np.hypot(*lam[i]) * radius[i] * fr.RIM  # (the IPM's direction)
                out8[2 * i:2 * i + 2] = l
            else:
                out8[2 * i:2 * i + 2] = lam_in[i]
        for iters, key in ((6, "oracle_split_6"), (3, "oracle_split_3")):
            o = out8.copy()
            got = fr._active_newton(a, slip.reshape(8).copy(), radius.copy(),
                                    np.array(idx_rim), 4, o, (iters, float("inf")))
            C[key] += got == 2
        # the carried split alone (which carried feet read as on their rims)
        c_rim = [np.hypot(*lam_in[i]) >= fr.CARRIED_RIM * radius[i] for i in range(4)]
        C["carried_split_is_ipm_split"] += c_rim == idx_rim
        if ok:
            WORST["slip_diff"] = max(WORST["slip_diff"], float(np.max(np.abs(post_d - post_ipm))))
            WORST["res_direct"] = max(WORST["res_direct"], res_d)
            WORST["res_ipm"] = max(WORST["res_ipm"],
                                   fr._residual(a_mat, slip, lam, radius, active))
            rel = np.max(np.abs(ld - lam)) / max(radius)
            WORST["lam_diff_rel"] = max(WORST["lam_diff_rel"], float(rel))
            WORST["sum_norm_diff_rel"] = max(WORST["sum_norm_diff_rel"], float(
                abs(np.sum(np.hypot(ld[:, 0], ld[:, 1])) - np.sum(np.hypot(lam[:, 0], lam[:, 1])))
                / np.sum(radius)))
            # the ship's change: J^T lam, seen through A (the slips' change) is slip_diff
            fill = max(np.hypot(ld[i, 0], ld[i, 1]) / radius[i] for i in range(4))
            WORST["direct_fill"] = max(WORST["direct_fill"], float(fill))
    return out


fr._solve_feet = sf
cases = list(range(0, 300, int(sys.argv[1])))
doc = tomllib.loads(scenarios.text("envelope"))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
        Axis("ships.initial.horizontal_speed", 0.0, 6.0),
        Axis("ships.initial.tilt_deg", 0.0, 15.0)]
sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)
res = run_part(sw, cases)
n = len(cases)
print(f"{n} cases; per touchdown " + ", ".join(f"{k} {v / n:.2f}" for k, v in sorted(C.items())))
print("totals", dict(C))
print("worst over accepted", dict(WORST), flush=True)
