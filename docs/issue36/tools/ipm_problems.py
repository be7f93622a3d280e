"""The interior-point method's problems of N envelope touchdowns, captured, and its instructions on
them (issue 36, session 8). Three steps:

  1. capture (a scratch copy of the tree, never committed): in sim/friction.py's _solve_feet, copy
     a_mat, slip, radius, active before _interior_point and lam after it, and hand their
     addresses and the step count to a ctypes callback (numba calls a ctypes.CFUNCTYPE object
     from compiled code; numba.objmode fails in these kernels: no environment):
        _REC = ctypes.CFUNCTYPE(None, *[ctypes.c_int64] * 6)(record)   # record appends copies
        _REC(a_c.ctypes.data, s_c.ctypes.data, r_c.ctypes.data, act_c.ctypes.data,
             l_c.ctypes.data, steps)
     then run_part(sweep, cases) as ir_cases.py does and pickle the list:
     (a_mat (4,2,4,2), slip (4,2), radius (4,), active (4,), lam (4,2), steps).
     Cases 0-39 of ir_cases.py's sweep: 3,395 problems.
  2. count (any tree on PYTHONPATH, its own NUMBA_CACHE_DIR):
        python ipm_problems.py PROBS.pkl OUT.npy            # once: compiled into the cache
        valgrind --tool=callgrind --instr-atstart=no --callgrind-out-file=CG \\
            python ipm_problems.py PROBS.pkl OUT.npy        # prints Newton steps a solve
     CG's "totals" / problems = instructions a solve (sim.friction._interior_point only).
  3. compare two OUT.npy: the slips after, A lam + slip, on each problem's active feet."""
import os
import pickle
import subprocess
import sys

import numba
import numpy as np

from touchdown.sim import friction

probs = pickle.load(open(sys.argv[1], "rb"))
A = np.stack([p[0] for p in probs])
S = np.stack([p[1] for p in probs])
R = np.stack([p[2] for p in probs])
ACT = np.stack([p[3] for p in probs])
ipm = friction._interior_point


@numba.njit
def run(a, s, r, act, out):
    tot = 0
    lam = np.zeros((4, 2))
    for p in range(a.shape[0]):
        tot += ipm(a[p], s[p], r[p], lam, act[p])
        out[p] = lam
    return tot


out = np.zeros((len(probs), 4, 2))
run(A[:2], S[:2], R[:2], ACT[:2], out)
under_valgrind = "vgpreload" in os.environ.get("LD_PRELOAD", "")
if under_valgrind:
    subprocess.run(["callgrind_control", "-i", "on", str(os.getpid())], check=True,
                   capture_output=True)
tot = run(A, S, R, ACT, out)
if under_valgrind:
    subprocess.run(["callgrind_control", "-i", "off", str(os.getpid())], check=True,
                   capture_output=True)
print(f"{len(probs)} problems, {tot / len(probs):.3f} Newton steps a solve")
np.save(sys.argv[2], out)
