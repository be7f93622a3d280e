import re, sys, glob
syms = []
for ln in open(sys.argv[2]):
    a, s, n = ln.split()[:3]
    a, s = int(a, 16), int(s, 16)
    m = re.search(r"sim\d*(\w+?)B\d+v", n)
    short = re.sub(r"^_ZN(7cpython)?9touchdown3sim", "", n)
    short = re.sub(r"B\d+v\d+.*", "", short)
    short = re.sub(r"\d+", ".", short).strip(".")
    syms.append((a, a + s, short))
import subprocess
out = subprocess.run(["callgrind_annotate", "--threshold=100", sys.argv[1]], capture_output=True, text=True).stdout
tot = {}
for ln in out.splitlines():
    m = re.match(r"\s*([\d,]+) \([\s\d.]+%\)\s+\?\?\?:0x([0-9a-f]+)", ln)
    if not m: continue
    ir = int(m.group(1).replace(",", "")); addr = int(m.group(2), 16)
    name = "?"
    for a, b, n in syms:
        if a <= addr < b: name = n; break
    tot[name] = tot.get(name, 0) + ir
T = int(re.search(r"([\d,]+) \(100.0%\)\s+PROGRAM TOTALS", out).group(1).replace(",", ""))
print("total", T)
for k, v in sorted(tot.items(), key=lambda x: -x[1]):
    print(f"{v:12,d} {100*v/T:5.1f}%  {k}")
