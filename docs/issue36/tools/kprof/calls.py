"""calls.py CG SYMS DIV: calls per unit (DIV: ship-ticks or touchdowns) of each kernel that is a
call of its own, from callgrind's calls= lines."""
import collections
import re
import sys

import symmap

cg, ranges, div = sys.argv[1], symmap.load(sys.argv[2]), float(sys.argv[3])
names: dict[str, str] = {}
count: collections.Counter = collections.Counter()
cur = None
for ln in open(cg):
    m = re.match(r"cfn=\((\d+)\)(?: (.*))?", ln)
    if m:
        if m.group(2):
            names[m.group(1)] = m.group(2).strip()
        cur = names.get(m.group(1))
        continue
    m = re.match(r"calls=(\d+) ", ln)
    if m and cur:
        mm = re.match(r"0x([0-9a-f]+)", cur)
        if mm:
            n = symmap.name_at(ranges, int(mm.group(1), 16))
            if n != "?":
                count[n] += int(m.group(1))
for k, v in count.most_common(30):
    print(f"{v / div:8.2f}  {k}")
