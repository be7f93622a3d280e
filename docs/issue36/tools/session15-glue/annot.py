import sys, re, subprocess
cg, mp = sys.argv[1], sys.argv[2]
syms = []
for ln in open(mp):
    p = ln.split()
    if len(p) == 3:
        syms.append((int(p[0], 16), int(p[1], 16), p[2]))
def short(s):
    m = re.match(r"_ZN(?:7cpython)?(.*?)B\d", s)
    if not m:
        return s[:60]
    parts = []; t = m.group(1)
    while t:
        mm = re.match(r"(\d+)", t)
        if not mm: break
        n = int(mm.group(1)); t = t[len(mm.group(1)):]
        parts.append(t[:n]); t = t[n:]
    return ".".join(parts[1:]) + ("[py]" if "7cpython" in s[:12] else "")
out = subprocess.run(["callgrind_annotate", "--threshold=100", cg], capture_output=True, text=True).stdout
tot = None; rows = {}
for ln in out.splitlines():
    m = re.match(r"\s*([\d,]+) \(\s*[\d.]+%\)\s+(.*)", ln)
    if not m: continue
    ir = int(m.group(1).replace(",", "")); name = m.group(2)
    if "PROGRAM TOTALS" in name: tot = ir; continue
    a = re.search(r"\?\?\?:0x([0-9a-f]+) \[\?\?\?\]", name)
    if a:
        addr = int(a.group(1), 16)
        for b, sz, s in syms:
            if b <= addr < b + sz:
                name = short(s) + f" +{addr-b:x}"; break
    else:
        name = name.split(" [")[0][-70:]
    key = re.sub(r" \+[0-9a-f]+$", "", name)
    rows[key] = rows.get(key, 0) + ir
div = float(sys.argv[3]) if len(sys.argv) > 3 else 1
print(f"total {tot:,}  per unit {tot/div:,.0f}")
for k, v in sorted(rows.items(), key=lambda x: -x[1])[:int(sys.argv[4]) if len(sys.argv)>4 else 40]:
    print(f"{v/div:10,.0f} {100*v/tot:5.1f}%  {k}")
