"""lines.py CG SYMS DIV [N] (run in $KPROF): the JIT code's Ir by source line and by inlined
source function (README.txt, session 33)."""
import re, sys, collections, subprocess, glob
cg, syms, div = sys.argv[1], sys.argv[2], float(sys.argv[3])
pid = re.search(r"==(\d+)==", open(cg + ".log").read()).group(1)
ranges = []
for ln in open(syms):
    a, s, name = ln.split(None, 2); name = name.strip()
    if not name.startswith("_ZN7cpython") and "touchdown" in name:
        ranges.append((int(a, 16), int(s, 16), name))
ranges.sort()
import bisect
starts = [r[0] for r in ranges]
ir = collections.Counter(); last = 0; skip = False
for ln in open(cg):
    if ln.startswith("calls="): skip = True; continue
    c = ln[0]
    if c in "0123456789+-*":
        parts = ln.split()
        if len(parts) < 3: continue
        a = parts[0]
        if a.startswith("0x"): addr = int(a, 16)
        elif a[0] == "+": addr = last + int(a[1:])
        elif a[0] == "-": addr = last - int(a[1:])
        elif a == "*": addr = last
        else: continue
        last = addr
        if skip: skip = False; continue
        k = bisect.bisect_right(starts, addr) - 1
        if k >= 0 and addr < ranges[k][0] + ranges[k][1]:
            ir[(k, addr - ranges[k][0])] += int(parts[2])
# object file and symbol offset of each range
objs = {}
for f in glob.glob(f"objs/{pid}-*.o"):
    out = subprocess.run(["nm", "-S", "--defined-only", f], capture_output=True, text=True).stdout
    for l in out.splitlines():
        p = l.split()
        if len(p) == 4: objs[p[3]] = (f, int(p[0], 16))
by_line = collections.Counter(); by_fn = collections.Counter(); by_self = collections.Counter()
groups = collections.defaultdict(list)
for (k, off), v in ir.items():
    groups[k].append((off, v))
for k, items in groups.items():
    name = ranges[k][2]
    if name not in objs: continue
    f, base = objs[name]
    addrs = "\n".join(hex(base + off) for off, _ in items)
    # addr2line -i prints a variable number of (function, file:line) pairs an address: -a puts
    # the address before each address's chain
    res = subprocess.run(["addr2line", "-i", "-f", "-a", "-e", f], input=addrs + "\n", capture_output=True, text=True).stdout.splitlines()
    cur = None; chains = []
    for l in res:
        if l.startswith("0x"):
            cur = []; chains.append(cur)
        else:
            cur.append(l)
    for (off, v), ch in zip(items, chains):
        pairs = [(ch[i], ch[i + 1]) for i in range(0, len(ch) - 1, 2)]
        if not pairs: continue
        fn0, loc0 = pairs[0]
        loc0 = re.sub(r".*/touchdown/", "", re.sub(r" \(discriminator.*", "", loc0))
        by_line[loc0] += v
        seen = set()
        for fn, loc in pairs:
            src = re.sub(r".*/touchdown/", "", loc).split(":")[0]
            fnm = re.sub(r"\$\d+", "", fn)
            m = re.search(r"(\w+)B\d+v\d+", fn)
            key = src + ":" + (m.group(1) if m else fnm[:60])
            if key not in seen:
                by_fn[key] += v; seen.add(key)
tot = sum(ir.values())
print("total JIT Ir per unit", round(tot / div))
print("-- by innermost source line")
for l, v in by_line.most_common(int(sys.argv[4]) if len(sys.argv) > 4 else 40):
    print(f"{v / div:9.1f} {100 * v / tot:5.1f}%  {l}")
print("-- by source function, inclusive of what is inlined into it")
for l, v in by_fn.most_common(60):
    print(f"{v / div:9.1f} {100 * v / tot:5.1f}%  {l}")
