"""mapcg.py CG SYMS: callgrind's Ir of the JIT code ("???:0x..." lines) summed by kernel."""
import re
import subprocess
import sys

import symmap

ranges = symmap.load(sys.argv[2])
out = subprocess.run(["callgrind_annotate", "--threshold=100", sys.argv[1]],
                     capture_output=True, text=True).stdout
tot: dict[str, int] = {}
for ln in out.splitlines():
    m = re.match(r"\s*([\d,]+) \([\s\d.]+%\)\s+\?\?\?:0x([0-9a-f]+)", ln)
    if m:
        name = symmap.name_at(ranges, int(m.group(2), 16))
        tot[name] = tot.get(name, 0) + int(m.group(1).replace(",", ""))
total = int(re.search(r"([\d,]+) \(100.0%\)\s+PROGRAM TOTALS", out).group(1).replace(",", ""))
print("total", total)
for k, v in sorted(tot.items(), key=lambda x: -x[1]):
    print(f"{v:12,d} {100 * v / total:5.1f}%  {k}")
