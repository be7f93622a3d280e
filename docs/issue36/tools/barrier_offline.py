"""offline: the barrier method's accuracy vs its Newton steps, on lander-like friction problems"""
import math, sys
import numpy as np, numba

@numba.njit(cache=False, error_model="numpy")
def chol_solve(h, rhs, n, out, l, y):
    for i in range(n):
        for j in range(i + 1):
            acc = h[i, j]
            for k in range(j):
                acc -= l[i, k] * l[j, k]
            if i == j:
                if not acc > 0.0:
                    return False
                l[i, i] = math.sqrt(acc)
            else:
                l[i, j] = acc / l[j, j]
    for i in range(n):
        acc = rhs[i]
        for k in range(i):
            acc -= l[i, k] * y[k]
        y[i] = acc / l[i, i]
    for i in range(n - 1, -1, -1):
        acc = y[i]
        for k in range(i + 1, n):
            acc -= l[k, i] * out[k]
        out[i] = acc / l[i, i]
    return True

@numba.njit(cache=False, error_model="numpy")
def ipm(A, s, r, outer, inner, dec_tol, factor):
    n = A.shape[0]; nf = n // 2
    x = np.zeros(n); g = np.zeros(n); dx = np.zeros(n); y = np.zeros(n)
    H = np.zeros((n, n)); L = np.zeros((n, n))
    mu = np.abs(s).max() * r.max()
    steps = 0
    for _ in range(outer):
        for it in range(inner):
            for a in range(n):
                acc = s[a]
                for b in range(n):
                    H[a, b] = A[a, b]
                    acc += A[a, b] * x[b]
                g[a] = acc
            for k in range(nf):
                l1, l2 = x[2*k], x[2*k+1]
                d = r[k]*r[k] - l1*l1 - l2*l2
                g[2*k] += mu*2*l1/d; g[2*k+1] += mu*2*l2/d
                c0, c1 = mu*2/d, mu*4/(d*d)
                H[2*k, 2*k] += c0 + c1*l1*l1; H[2*k+1, 2*k+1] += c0 + c1*l2*l2
                H[2*k, 2*k+1] += c1*l1*l2; H[2*k+1, 2*k] += c1*l1*l2
            for a in range(n):
                g[a] = -g[a]
            if not chol_solve(H, g, n, dx, L, y):
                break
            steps += 1
            dec = 0.0
            for a in range(n):
                dec += g[a] * dx[a]
            t = 1.0
            for k in range(nf):
                l1, l2 = x[2*k], x[2*k+1]; d1, d2 = dx[2*k], dx[2*k+1]
                qa = d1*d1+d2*d2; qb = 2*(l1*d1+l2*d2); qc = l1*l1+l2*l2-r[k]*r[k]
                if qa > 0:
                    tm = (-qb + math.sqrt(max(qb*qb-4*qa*qc, 0.0)))/(2*qa)
                    t = min(t, 0.99*tm)
            for a in range(n):
                x[a] += t*dx[a]
            if dec <= dec_tol * mu and t == 1.0:
                break
        mu *= factor
    return x, steps

@numba.njit(cache=False, error_model="numpy")
def disk(b11, b12, b22, c1, c2, radius):
    if not radius > 0.0:
        return 0.0, 0.0
    nu = 0.0; x1 = x2 = 0.0
    for it in range(60):
        d11, d22 = b11+nu, b22+nu
        det = d11*d22 - b12*b12
        x1 = -(d22*c1 - b12*c2)/det; x2 = -(d11*c2 - b12*c1)/det
        r2 = x1*x1+x2*x2
        if it == 0 and r2 <= radius*radius:
            return x1, x2
        r = math.sqrt(r2)
        if abs(r-radius) <= 1e-15*radius:
            break
        y1 = (d22*x1 - b12*x2)/det; y2 = (d11*x2 - b12*x1)/det
        nu = nu + (r-radius)/radius*r2/(x1*y1+x2*y2)
    r = math.sqrt(x1*x1+x2*x2)
    return x1*(radius/r), x2*(radius/r)

@numba.njit(cache=False, error_model="numpy")
def gs(A, s, r, sweeps):
    n = A.shape[0]; nf = n//2
    lam = np.zeros(n)
    for _ in range(sweeps):
        for i in range(nf):
            c1, c2 = s[2*i], s[2*i+1]
            for j in range(nf):
                if j != i:
                    c1 += A[2*i, 2*j]*lam[2*j] + A[2*i, 2*j+1]*lam[2*j+1]
                    c2 += A[2*i+1, 2*j]*lam[2*j] + A[2*i+1, 2*j+1]*lam[2*j+1]
            lam[2*i], lam[2*i+1] = disk(A[2*i,2*i], A[2*i,2*i+1], A[2*i+1,2*i+1], c1, c2, r[i])
    return lam

def problem(rng):
    m = 15000.0; I = np.array([6e4, 6e4, 4e4]) * rng.uniform(0.7, 1.3)
    a, h = 2.5, 1.6
    tilt = rng.uniform(0, 0.3); az = rng.uniform(0, 2*np.pi)
    feet = np.array([[a,0,-h],[0,a,-h],[-a,0,-h],[0,-a,-h]])
    # rotate body by tilt about an axis in the plane
    ax = np.array([np.cos(az), np.sin(az), 0.0])
    K = np.array([[0,-ax[2],ax[1]],[ax[2],0,-ax[0]],[-ax[1],ax[0],0]])
    R = np.eye(3) + np.sin(tilt)*K + (1-np.cos(tilt))*K@K
    off = feet @ R.T
    nf = rng.integers(2, 5)
    idx = rng.choice(4, nf, replace=False)
    n_hat = np.array([0,0,1.0]) + rng.normal(0, 1e-3, 3); n_hat /= np.linalg.norm(n_hat)
    t1 = np.cross([1.0,0,0], n_hat); t1 /= np.linalg.norm(t1); t2 = np.cross(n_hat, t1)
    J = []
    for i in idx:
        for t in (t1, t2):
            J.append(np.concatenate([t/np.sqrt(m), np.cross(off[i], t)/np.sqrt(I)]))  # I diag in world approx
    J = np.array(J)
    A = J @ J.T
    V = rng.normal(0, 1.0, 6) * rng.choice([1e-3, 1e-1, 1.0, 3.0])
    s = J @ V * rng.uniform(0.5, 2)
    s += rng.normal(0, 1e-6, s.shape) * rng.choice([0, 1])
    jn = rng.uniform(100, 5000, nf) * rng.choice([1.0, 10.0])
    mu = rng.choice([0.4, 0.6, 1.0])
    r = mu * jn
    return A, s, r

def slips(A, s, lam):
    return s + A @ lam

rng = np.random.default_rng(int(sys.argv[1]) if len(sys.argv) > 1 else 0)
probs = [problem(rng) for _ in range(300)]
refs = [ipm(A, s, r, 18, 10, 0.0, 0.1)[0] for A, s, r in probs]
gsr = [gs(A, s, r, 20000) for A, s, r in probs]
e = np.array([np.abs(slips(A, s, x) - slips(A, s, y)).max() for (A, s, r), x, y in zip(probs, refs, gsr)])
print('long IPM vs long IPM:', np.median(e), np.quantile(e, .99), e.max())
configs = [(14, 3, 0.0, 0.1), (14, 3, 1e-3, 0.1), (14, 3, 1e-2, 0.1), (14, 4, 1e-3, 0.1)]
for cfg in configs:
    errs = []; st = []
    for (A, s, r), ref in zip(probs, refs):
        x, k = ipm(A, s, r, *cfg)
        errs.append(np.abs(slips(A, s, x) - slips(A, s, ref)).max())
        st.append(k)
    errs = np.array(errs)
    print(cfg, f"steps mean {np.mean(st):.1f}  slip err vs long IPM: median {np.median(errs):.1e} 99% {np.quantile(errs, .99):.1e} max {errs.max():.1e}")
