import sys, re, subprocess, collections
exec(open('/tmp/flying-x/instr.py').read().split("cat = collections")[0].replace("cg, mp, obj, div = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])","cg, mp, obj, div = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])"))
fname = sys.argv[5]
for o, s, n in syms:
    if fname in n and s > 1000 and "7cpython" not in n:
        break
print(n[:80], hex(o), s)
# walk instructions in order, group runs of straight-line code with equal count
offs = sorted(k for k in ins if o <= k < o + s)
runs = []
cur = None
for off in offs:
    c = costs.get(off + base, 0)
    if cur and cur[2] == c:
        cur[1] = off; cur[3] += 1; cur[4].append(ins[off])
    else:
        cur = [off, off, c, 1, [ins[off]]]; runs.append(cur)
tot = sum(r[2]*r[3] for r in runs)
print("total", tot/div)
top = sorted(runs, key=lambda r: -r[2]*r[3])[:int(sys.argv[6])]
for r in sorted(top):
    nstack = sum(1 for t in r[4] if "mov" in t and "%rsp" in t)
    print(f"{r[0]:x}-{r[1]:x} n={r[3]} per-call-count={r[2]/div:.2f} Ir={r[2]*r[3]/div:.0f} stackmov={nstack}")
