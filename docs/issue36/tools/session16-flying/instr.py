import sys, re, subprocess, collections
cg, mp, obj, div = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])
# address costs
costs = collections.Counter()
last = 0; skip = False
for ln in open(cg):
    if ln.startswith("calls="):
        skip = True; continue
    if not ln or not (ln[0] in "0123456789+-*"):
        continue
    parts = ln.split()
    a = parts[0]
    if a.startswith("0x"): addr = int(a, 16)
    elif a.startswith("+"): addr = last + int(a[1:], 16) if a[1:].startswith("0x") else last + int(a[1:])
    elif a.startswith("-"): addr = last - (int(a[1:], 16) if a[1:].startswith("0x") else int(a[1:]))
    elif a == "*": addr = last
    else: addr = int(a)
    last = addr
    if skip:
        skip = False; continue
    if len(parts) > 2:
        costs[addr] += int(parts[2])
# symbols in map and in obj
mapsym = {}
for ln in open(mp):
    p = ln.split()
    if len(p) == 3: mapsym[p[2]] = int(p[0], 16)
nm = subprocess.run(["nm", "-S", "--defined-only", obj], capture_output=True, text=True).stdout
base = None
syms = []
for ln in nm.splitlines():
    p = ln.split()
    if len(p) == 4:
        syms.append((int(p[0], 16), int(p[1], 16), p[3]))
        if p[3] in mapsym and base is None: base = mapsym[p[3]] - int(p[0], 16)
dis = subprocess.run(["objdump", "-d", "--no-show-raw-insn", obj], capture_output=True, text=True).stdout
ins = {}
for ln in dis.splitlines():
    m = re.match(r"\s*([0-9a-f]+):\s+(.*)", ln)
    if m: ins[int(m.group(1), 16)] = m.group(2).strip()
def fn_of(off):
    for o, s, n in syms:
        if o <= off < o + s: 
            m = re.search(r"sim\d+(\w+?)\d+(\w+?)B\d", n)
            return re.sub(r"^\d+", "", n[:0]) + (re.findall(r"\d+([a-z_]+)", n)[2:4] and ".".join(re.findall(r"(?<=\d)([a-z_][a-z_0-9]*?)(?=B\d|\d)", n)[1:3]))
    return "?"
cat = collections.defaultdict(collections.Counter)
def kind(t):
    op = t.split()[0] if t else "?"
    args = t[len(op):]
    if op.startswith("call"): return "call"
    if op in ("push", "pop"): return "push/pop"
    if "mov" in op and ("(%rsp)" in args or "(%rbp)" in args or "(%r" in args):
        if "%rsp" in args or "%rbp" in args: return "mov stack"
        return "mov mem"
    if "mov" in op: return "mov reg"
    if op.startswith("j") or op.startswith("cmp") or op.startswith("test") or op.startswith("ucomi") or op.startswith("vucomi") or op.startswith("set") or op.startswith("cmov"): return "branch/cmp"
    if any(k in op for k in ("sqrt",)): return "sqrt"
    if any(k in op for k in ("div",)): return "div"
    if any(k in op for k in ("mul","add","sub","fma")) and ("sd" in op or "pd" in op or "ss" in op): return "fp arith"
    if op.startswith("lea"): return "lea"
    return "other:" + op
tot = collections.Counter(); unk = 0
for addr, c in costs.items():
    off = addr - base
    t = ins.get(off)
    if t is None: unk += c; continue
    f = fn_of(off)
    cat[f][kind(t)] += c; tot[f] += c
print("outside obj", unk/div)
for f, c in tot.most_common(8):
    print(f"{f}: {c/div:,.0f}")
    for k, v in cat[f].most_common(14):
        print(f"   {k:14s} {v/div:8,.0f}")
