"""sites.py CG SYMS DIV: calls of NRT_incref/NRT_decref per unit, by calling kernel and call site
(callgrind run with --compress-strings=no --compress-pos=no --dump-instr=yes)."""
import collections, os, re, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import symmap
cg, ranges, div = sys.argv[1], symmap.load(sys.argv[2]), float(sys.argv[3])
nrt = {n: (lo, hi) for lo, hi, n in ranges if n.startswith("NRT_")}
def nrt_name(addr):
    for n, (lo, hi) in nrt.items():
        if lo <= addr < hi:
            return n
    return None
by_fn = collections.Counter(); by_site = collections.Counter()
cfn = None; want = None
lines = open(cg)
for ln in lines:
    if ln.startswith("cfn="):
        m = re.search(r"0x([0-9a-f]+)", ln)
        cfn = nrt_name(int(m.group(1), 16)) if m else None
        continue
    if ln.startswith("calls="):
        n = int(ln.split("=")[1].split()[0])
        nxt = next(lines)
        if cfn:
            addr = int(nxt.split()[0], 16)
            caller = symmap.name_at(ranges, addr)
            by_fn[(cfn, caller)] += n
            by_site[(cfn, caller, addr)] += n
        continue
tot = collections.Counter()
for (c, f), n in by_fn.items():
    tot[c] += n
for c, n in tot.items():
    print(f"{c}: {n/div:10.1f} a unit")
for (c, f), n in by_fn.most_common(40):
    print(f"{n/div:10.1f}  {c:11s} {f}")
print("-- sites")
for (c, f, a), n in by_site.most_common(40):
    print(f"{n/div:10.1f}  {c:11s} {f} {a:x}")
