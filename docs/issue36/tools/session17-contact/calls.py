"""calls.py CG SYMS DIV: calls per unit of each mapped JIT function (callgrind's calls= lines)"""
import re, sys, collections
cg, symsf, div = sys.argv[1], sys.argv[2], float(sys.argv[3])
syms = []
for ln in open(symsf):
    a, s, n = ln.split()[:3]
    short = re.sub(r"^_ZN(7cpython)?9touchdown3sim", "", n); short = re.sub(r"B\d+v\d+.*", "", short)
    syms.append((int(a, 16), int(a, 16) + int(s, 16), re.sub(r"\d+", ".", short).strip(".")))
names = {}; cnt = collections.Counter(); cur = None
for ln in open(cg):
    m = re.match(r"cfn=\((\d+)\)(?: (.*))?", ln)
    if m:
        if m.group(2): names[m.group(1)] = m.group(2).strip()
        cur = names.get(m.group(1)); continue
    m = re.match(r"calls=(\d+) ", ln)
    if m and cur:
        mm = re.match(r"0x([0-9a-f]+)", cur)
        if mm:
            a = int(mm.group(1), 16)
            for lo, hi, n in syms:
                if lo <= a < hi: cnt[n] += int(m.group(1)); break
for k, v in cnt.most_common(30): print(f"{v/div:8.2f}  {k}")
