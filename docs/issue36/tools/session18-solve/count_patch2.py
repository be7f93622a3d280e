import sys
p = sys.argv[1]
s = open(p).read()
s = s.replace("from touchdown.sim._count import bump", "from touchdown.sim._count import bump, peek")
old = """    if _gauss_seidel(a_mat, slip, radius, lam, active, n_active >= 3):
        return 1"""
assert old in s
s = s.replace(old, """    if not (peek(60) == 1 and n_active >= 3):
        if _gauss_seidel(a_mat, slip, radius, lam, active, n_active >= 3):
            return 1""")
old = """        elif tries < 2 and gap < FINISH_GAPS[tries] * gap_0:
            tried = _active_set(a_loc, u0, rho, x, z, n_feet, dx)
            if tried == 2:"""
assert old in s
s = s.replace(old, """        elif tries < 2 and gap < (FINISH_GAPS[tries] * 10.0 ** peek(61)) * gap_0:
            tried = _active_set(a_loc, u0, rho, x, z, n_feet, dx)
            bump(11 + tried, 1)
            if tried == 2:""")
open(p, "w").write(s)
