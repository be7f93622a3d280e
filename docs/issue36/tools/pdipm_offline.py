"""offline (issue 36, session 3): a primal-dual interior-point method (NT scaling, Mehrotra's
predictor-corrector) for the feet's friction problem  min lam.A lam / 2 + s.lam, |lam_k| <= r_k,
against the barrier method of sim/friction.py (14 x 3 Newton steps) on the lander-like problems of
barrier_offline.py; both measured by their slips' largest error against 20,000 Gauss-Seidel sweeps
and a long barrier solve (18 x 10 steps). Run: python pdipm_offline.py [seed] [n_problems]."""
import math, sys, os
import numpy as np, numba

sys.argv, _argv = sys.argv[:1], sys.argv  # barrier_offline runs its own study at import
_here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, _here)
_out = sys.stdout
sys.stdout = open(os.devnull, "w")
import barrier_offline as bo  # noqa: E402
sys.stdout = _out
sys.argv = _argv


@numba.njit(cache=False, error_model="numpy")
def max_step(x0, x1, x2, d0, d1, d2):
    """the largest t with x + t d in the second-order cone (x inside it): the first positive
    root of (x0 + t d0)^2 - |x_bar + t d_bar|^2 (inf if none)"""
    a = d0 * d0 - d1 * d1 - d2 * d2
    b = 2.0 * (x0 * d0 - x1 * d1 - x2 * d2)
    c = x0 * x0 - x1 * x1 - x2 * x2
    disc = b * b - 4.0 * a * c
    if disc < 0.0:
        return math.inf  # (a > 0 here: q stays positive)
    sq = math.sqrt(disc)
    q = -0.5 * (b + sq) if b >= 0.0 else -0.5 * (b - sq)
    t = math.inf
    if q != 0.0:
        r1 = c / q
        if r1 > 0.0:
            t = r1
        if a != 0.0:
            r2 = q / a
            if r2 > 0.0 and r2 < t:
                t = r2
    return t


@numba.njit(cache=False, error_model="numpy")
def pdipm(A, s, r, max_iter, tol, sigma_exp, start):
    n = A.shape[0]; nf = n // 2
    x = np.zeros(n); z = np.zeros((nf, 3))
    H = np.zeros((n, n)); L = np.zeros((n, n)); y = np.zeros(n)
    rhs = np.zeros(n); dxa = np.zeros(n); dx = np.zeros(n)
    eta = np.zeros(nf); w = np.zeros((nf, 3)); dets = np.zeros(nf); lsc = np.zeros((nf, 3))
    dza = np.zeros((nf, 3)); dz = np.zeros((nf, 3)); wdsa = np.zeros((nf, 3)); wdza = np.zeros((nf, 3))
    smax = 0.0
    for k in range(nf):
        smax = max(smax, math.sqrt(s[2*k]**2 + s[2*k+1]**2))
    if smax == 0.0:
        return x, 0
    for k in range(nf):
        z[k, 0] = math.sqrt(s[2*k]**2 + s[2*k+1]**2) + start * smax
        z[k, 1] = s[2*k]; z[k, 2] = s[2*k+1]
    it = 0
    sigma = 0.0
    moved = math.inf
    for it in range(1, max_iter + 1):
        # residual r_x = A x + s - v, gap
        gap = 0.0
        worst = 0.0
        for k in range(nf):
            gk = r[k] * z[k, 0] + x[2*k] * z[k, 1] + x[2*k+1] * z[k, 2]
            gap += gk
            worst = max(worst, gk / r[k])
        mu = gap / nf
        for a in range(n):
            acc = s[a] - z[a // 2, 1 + a % 2]
            for b in range(n):
                acc += A[a, b] * x[b]
            rhs[a] = -acc
        # NT scaling of each foot's cone pair, s_k = (r, x_k), z_k
        for k in range(nf):
            s0, s1, s2 = r[k], x[2*k], x[2*k+1]
            z0, z1, z2 = z[k, 0], z[k, 1], z[k, 2]
            sj2 = (s0 - math.sqrt(s1*s1 + s2*s2)) * (s0 + math.sqrt(s1*s1 + s2*s2))
            zj2 = (z0 - math.sqrt(z1*z1 + z2*z2)) * (z0 + math.sqrt(z1*z1 + z2*z2))
            if not (sj2 > 0.0 and zj2 > 0.0):
                return x, it - 1
            sj, zj = math.sqrt(sj2), math.sqrt(zj2)
            s0, s1, s2 = s0 / sj, s1 / sj, s2 / sj
            z0, z1, z2 = z0 / zj, z1 / zj, z2 / zj
            g = math.sqrt(0.5 * (1.0 + s0*z0 + s1*z1 + s2*z2))
            w0, w1, w2 = (s0 + z0) / (2*g), (s1 - z1) / (2*g), (s2 - z2) / (2*g)
            et = math.sqrt(zj / sj)
            # H = [[w0, wb'], [wb, I + wb wb'/(1+w0)]]; W = eta H^-1? (chosen below)
            eta[k] = et; w[k, 0], w[k, 1], w[k, 2] = w0, w1, w2
            dets[k] = sj * zj  # det_J of the scaled point l = W s
        # check/choose: W s = W^-1 z with W = eta Hinv(w) where Hinv = [[w0,-wb'],[-wb, I+wbwb'/(1+w0)]]
        for k in range(nf):
            et, w0, w1, w2 = eta[k], w[k, 0], w[k, 1], w[k, 2]
            v0, v1, v2 = r[k], x[2*k], x[2*k+1]
            # l = W s = eta Hinv s
            t = w1 * v1 + w2 * v2
            l0 = et * (w0 * v0 - t)
            c = -v0 + t / (1.0 + w0)
            lsc[k, 0], lsc[k, 1], lsc[k, 2] = l0, et * (v1 + c * w1), et * (v2 + c * w2)
        # the matrix A + sum_k B_k, B_k = (W^2)_[12][12] = eta^2 (I + 2 wb wb')
        for a in range(n):
            for b in range(n):
                H[a, b] = A[a, b]
        for k in range(nf):
            e2 = eta[k] * eta[k]
            w1, w2 = w[k, 1], w[k, 2]
            H[2*k, 2*k] += e2 * (1.0 + 2.0 * w1 * w1)
            H[2*k+1, 2*k+1] += e2 * (1.0 + 2.0 * w2 * w2)
            H[2*k, 2*k+1] += e2 * 2.0 * w1 * w2
            H[2*k+1, 2*k] += e2 * 2.0 * w1 * w2
        if it > 1 and moved <= tol and np.abs(rhs).max() <= tol:
            return x, it - 1
        ok = True
        for phase in range(2):
            # c_k = sigma mu e - l o l - (corrector); xi = l \ c
            rr = np.zeros(n)
            for a in range(n):
                rr[a] = rhs[a]
            xi = np.zeros((nf, 3))
            for k in range(nf):
                l0, l1, l2 = lsc[k, 0], lsc[k, 1], lsc[k, 2]
                c0 = -(l0*l0 + l1*l1 + l2*l2)
                c1 = -2.0 * l0 * l1
                c2 = -2.0 * l0 * l2
                if phase == 1:
                    a0, a1, a2 = wdsa[k, 0], wdsa[k, 1], wdsa[k, 2]
                    b0, b1, b2 = wdza[k, 0], wdza[k, 1], wdza[k, 2]
                    c0 += sigma * mu - (a0*b0 + a1*b1 + a2*b2)
                    c1 -= a0 * b1 + b0 * a1
                    c2 -= a0 * b2 + b0 * a2
                det = dets[k]
                x0 = (l0 * c0 - l1 * c1 - l2 * c2) / det
                x1 = (c1 - x0 * l1) / l0
                x2 = (c2 - x0 * l2) / l0
                xi[k, 0], xi[k, 1], xi[k, 2] = x0, x1, x2
                # W xi = eta Hinv xi ; rhs += (W xi)_[12]
                et, w0, w1, w2 = eta[k], w[k, 0], w[k, 1], w[k, 2]
                t = w1 * x1 + w2 * x2
                cc = -x0 + t / (1.0 + w0)
                rr[2*k] += et * (x1 + cc * w1)
                rr[2*k+1] += et * (x2 + cc * w2)
            d = dxa if phase == 0 else dx
            if not bo.chol_solve(H, rr, n, d, L, y):
                ok = False
                break
            # W ds (ds = (0, d_k)) and W^-1 dz = xi - W ds; dz = W (W^-1 dz)
            alpha = 1.0
            for k in range(nf):
                et, w0, w1, w2 = eta[k], w[k, 0], w[k, 1], w[k, 2]
                d1, d2 = d[2*k], d[2*k+1]
                t = w1 * d1 + w2 * d2
                a0, a1, a2 = et * (-t), et * (d1 + t / (1.0 + w0) * w1), et * (d2 + t / (1.0 + w0) * w2)
                b0, b1, b2 = xi[k, 0] - a0, xi[k, 1] - a1, xi[k, 2] - a2
                # dz = W b = eta Hinv b
                t = w1 * b1 + w2 * b2
                cc = -b0 + t / (1.0 + w0)
                dz0, dz1, dz2 = et * (w0 * b0 - t), et * (b1 + cc * w1), et * (b2 + cc * w2)
                if phase == 0:
                    wdsa[k, 0], wdsa[k, 1], wdsa[k, 2] = a0, a1, a2
                    wdza[k, 0], wdza[k, 1], wdza[k, 2] = b0, b1, b2
                dz[k, 0], dz[k, 1], dz[k, 2] = dz0, dz1, dz2
                alpha = min(alpha, max_step(r[k], x[2*k], x[2*k+1], 0.0, d1, d2))
                alpha = min(alpha, max_step(z[k, 0], z[k, 1], z[k, 2], dz0, dz1, dz2))
            if phase == 0:
                # mu after the affine step
                ga = 0.0
                for k in range(nf):
                    ga += (r[k] * (z[k, 0] + alpha * dz[k, 0])
                           + (x[2*k] + alpha * d[2*k]) * (z[k, 1] + alpha * dz[k, 1])
                           + (x[2*k+1] + alpha * d[2*k+1]) * (z[k, 2] + alpha * dz[k, 2]))
                sigma = max(0.0, min(1.0, ga / gap)) ** sigma_exp
            else:
                step = min(1.0, 0.99 * alpha)
                if not step > 0.0 or not np.all(np.isfinite(dz)) or not np.all(np.isfinite(d)):
                    break
                moved = 0.0
                for k in range(nf):
                    moved = max(moved, step * max(abs(dz[k, 1]), abs(dz[k, 2])))
                for a in range(n):
                    x[a] += step * d[a]
                for k in range(nf):
                    for j in range(3):
                        z[k, j] += step * dz[k, j]
        if not ok:
            break
    return x, it


def check_scaling(rng):
    """W s = W^-1 z for the formulas above"""
    for _ in range(5):
        s = np.array([1.0, *rng.normal(0, 0.3, 2)]); z = np.array([2.0, *rng.normal(0, 0.6, 2)])
        J = np.diag([1.0, -1, -1])
        sj, zj = math.sqrt(s @ J @ s), math.sqrt(z @ J @ z)
        sh, zh = s / sj, z / zj
        g = math.sqrt(0.5 * (1 + sh @ zh))
        w = (sh + J @ zh) / (2 * g)
        Hinv = np.block([[np.array([[w[0]]]), -w[None, 1:]], [-w[1:, None], np.eye(2) + np.outer(w[1:], w[1:]) / (1 + w[0])]])
        W = math.sqrt(zj / sj) * Hinv
        print("Ws - W^-1 z:", np.abs(W @ s - np.linalg.solve(W, z)).max(), " W^2 block vs formula:",
              np.abs((W @ W)[1:, 1:] - (zj / sj) * (np.eye(2) + 2 * np.outer(w[1:], w[1:]))).max())


if __name__ == "__main__":
    seed = int(sys.argv[1]) if len(sys.argv) > 1 else 0
    count = int(sys.argv[2]) if len(sys.argv) > 2 else 300
    rng = np.random.default_rng(seed)
    check_scaling(rng)
    def err(A, s, x, y):
        return np.abs(bo.slips(A, s, x) - bo.slips(A, s, y)).max()
    probs = [bo.problem(rng) for _ in range(count)]
    gsr = [bo.gs(A, s, r, 20000) for A, s, r in probs]
    lng = [bo.ipm(A, s, r, 18, 10, 0.0, 0.1)[0] for A, s, r in probs]
    e = np.array([err(A, s, x, y) for (A, s, r), x, y in zip(probs, gsr, lng)])
    print(f"GS20000 vs long barrier: median {np.median(e):.1e} 99% {np.quantile(e, .99):.1e} max {e.max():.1e}")
    for name, refs in (("GS20000", gsr), ("long barrier", lng)):
        e, st = [], []
        for (A, s, r), ref in zip(probs, refs):
            x, k = bo.ipm(A, s, r, 14, 3, 0.0, 0.1)
            e.append(err(A, s, x, ref)); st.append(k)
        e = np.array(e)
        print(f"barrier 14x3 vs {name}: steps {np.mean(st):.1f}  err median {np.median(e):.1e} 99% {np.quantile(e, .99):.1e} max {e.max():.1e}")
    for iters in (8, 10, 12, 14, 16, 20):
        e = []
        for (A, s, r), ref in zip(probs, lng):
            x, k = pdipm(A, s, r, iters, 0.0, 3.0, 1.0)
            e.append(err(A, s, x, ref))
        e = np.array(e)
        print(f"pdipm {iters} fixed steps vs long barrier: err median {np.median(e):.1e} 90% {np.quantile(e, .9):.1e} 99% {np.quantile(e, .99):.1e} max {e.max():.1e}")
    gs30 = [bo.gs(A, s, r, 30) for A, s, r in probs]
    hard = np.array([err(A, s, x, y) > 1e-11 for (A, s, r), x, y in zip(probs, gs30, lng)])
    print("hard (GS 30 sweeps off by > 1e-11):", hard.sum(), "of", len(probs))
    for tol in (1e-9, 1e-10, 1e-11, 1e-12):
        e, st = [], []
        for (A, s, r), ref in zip(probs, lng):
            x, k = pdipm(A, s, r, 30, tol, 3.0, 1.0)
            e.append(err(A, s, x, ref)); st.append(k)
        e, st = np.array(e), np.array(st)
        for nm, m in (("all", np.ones(len(e), bool)), ("hard", hard)):
            print(f"pdipm stop on slip change {tol:.0e} [{nm}]: steps mean {st[m].mean():.1f} max {st[m].max()}  err median {np.median(e[m]):.1e} 99% {np.quantile(e[m], .99):.1e} max {e[m].max():.1e}")
