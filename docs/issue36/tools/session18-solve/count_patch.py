import re, sys
p = sys.argv[1]
s = open(p).read()
s = s.replace("from touchdown.sim.compiled import kernel, stack_zeros",
              "from touchdown.sim.compiled import kernel, stack_zeros\nfrom touchdown.sim._count import bump")
# gauss-seidel: classify warm/cold and n_active, count sweeps at each return
s = s.replace("""    alone = n_active == 1
    for sweep in range(MAX_SWEEPS):""", """    alone = n_active == 1
    warm = 0
    for i in range(4):
        if active[i] and (lam[i, 0] != 0.0 or lam[i, 1] != 0.0):
            warm = 1
    base = 20 + 10 * warm + 2 * n_active  # [base] solves converged, [base+1] their sweeps
    for sweep in range(MAX_SWEEPS):""")
s = s.replace("""        if res <= SLIP_TOL_MPS:
            return True
        if alone:""", """        if res <= SLIP_TOL_MPS:
            bump(base, 1)
            bump(base + 1, sweep + 1)
            return True
        if alone:
            bump(40 + n_active, 1)
            bump(45 + n_active, sweep + 1)""")
s = s.replace("""            if not res < last or res * (res / last) ** (MAX_SWEEPS - 2) > margin:
                return False""", """            if not res < last or res * (res / last) ** (MAX_SWEEPS - 2) > margin:
                bump(40 + n_active, 1)
                bump(45 + n_active, sweep + 1)
                return False""")
s = s.replace("""            if not res < checkpoint or res * (res / checkpoint) ** left > CRAWL_MARGIN * SLIP_TOL_MPS:
                return False""", """            if not res < checkpoint or res * (res / checkpoint) ** left > CRAWL_MARGIN * SLIP_TOL_MPS:
                bump(40 + n_active, 1)
                bump(45 + n_active, sweep + 1)
                return False""")
s = s.replace("""            checkpoint = res
    return False""", """            checkpoint = res
    bump(40 + n_active, 1)
    bump(45 + n_active, MAX_SWEEPS)
    return False""")
# ipm steps
s = s.replace("""    for k in range(n_feet):
        lam[idx[k], 0], lam[idx[k], 1] = x[2 * k], x[2 * k + 1]
    return steps""", """    for k in range(n_feet):
        lam[idx[k], 0], lam[idx[k], 1] = x[2 * k], x[2 * k + 1]
    bump(2, 1)
    bump(3, steps)
    bump(50 + n_feet, 1)
    bump(55 + n_feet, steps)
    return steps""")
s = s.replace("""        if _from_carried(a_mat, slip, radius, lam, active, rate):
            return 2""", """        bump(4, 1)
        if _from_carried(a_mat, slip, radius, lam, active, rate):
            bump(5, 1)
            return 2""")
s = s.replace("""    carried = stack_zeros((4, 2), np.float64)
    for i in range(4):
        carried[i, 0], carried[i, 1] = lam[i, 0], lam[i, 1]""", """    carried = stack_zeros((4, 2), np.float64)
    bump(0, 1)
    for i in range(4):
        carried[i, 0], carried[i, 1] = lam[i, 0], lam[i, 1]""")
s = s.replace("""        return _dragged_only(law, rigid, stepped, end, j_n, normals, sliding)""",
 """        bump(1, 1)
        return _dragged_only(law, rigid, stepped, end, j_n, normals, sliding)""")
s = s.replace("""        sweeps += _solve_feet(a_mat, slip, radius, lam, active, law.try_pairs)""",
"""        sweeps += _solve_feet(a_mat, slip, radius, lam, active, law.try_pairs)
        bump(6, 1)""")
s = s.replace("""    for it in range(MAX_DISK_ITERATIONS):
        d11, d22 = b11 + nu, b22 + nu""", """    bump(7, 1)
    for it in range(MAX_DISK_ITERATIONS):
        bump(8, 1)
        d11, d22 = b11 + nu, b22 + nu""")
open(p, "w").write(s)
print(s.count("bump("))
