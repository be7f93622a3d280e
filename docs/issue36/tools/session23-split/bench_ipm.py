"""Compiled: the four-foot IPM solves of the dump, N rounds; process_time least of 7; checks bits.
   PYTHONPATH=<tree>.pkg python bench_ipm.py [which]   which: ipm (default) | solve"""
import sys, time, numpy as np, numba
import touchdown.sim.friction as fr
d = np.load("/tmp/stick-problems.npz")
A, S, R = d["a"], d["slip"], d["radius"]
n = len(A)
ipm = fr._interior_point
solve = fr._solve_feet

@numba.njit(cache=False)
def run_ipm(A, S, R, out, rounds):
    active = np.ones(4, np.bool_)
    tot = 0
    for _ in range(rounds):
        for i in range(A.shape[0]):
            lam = out[i]
            tot += ipm(A[i], S[i], R[i], lam, active)
    return tot

@numba.njit(cache=False)
def run_solve(A, S, R, L, out, rounds):
    active = np.ones(4, np.bool_)
    tot = 0
    for _ in range(rounds):
        for i in range(A.shape[0]):
            lam = out[i]
            lam[:, :] = L[i]
            tot += solve(A[i], S[i], R[i], lam, active, True)
    return tot

which = sys.argv[1] if len(sys.argv) > 1 else "ipm"
rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 20
out = np.zeros((n, 4, 2))
f = (lambda r: run_ipm(A, S, R, out, r)) if which == "ipm" else (
    lambda r: run_solve(A, S, R, d["lam_in"], out, r))
f(1)
if which == "ipm":
    same = sum(np.array_equal(out[i], d["lam_ipm"][i]) for i in range(n))
    print("bits equal to the dump's IPM answers:", same, "of", n)
import os, subprocess
if "vgpreload" in os.environ.get("LD_PRELOAD", ""):
    subprocess.run(["callgrind_control", "-i", "on", str(os.getpid())], check=True, capture_output=True)
    f(1)
    subprocess.run(["callgrind_control", "-i", "off", str(os.getpid())], check=True, capture_output=True)
    sys.exit(0)
best = 1e9
for _ in range(7):
    t = time.process_time(); f(rounds); best = min(best, time.process_time() - t)
print("%s: %.3f us a solve (least of 7, %d rounds of %d)" % (which, best / rounds / n * 1e6, rounds, n))
