"""Compare sweep tables: outcomes changed between A and B, and against fine tables."""
import sys
from collections import Counter
import numpy as np
import pyarrow.parquet as pq
def load(p):
    t = pq.read_table(p).to_pydict()
    return {k: (np.array(v, dtype=object) if k == "outcome" else np.array(v, dtype=float)) for k, v in t.items()}
a, b = load(sys.argv[1]), load(sys.argv[2])
fines = [(p, load(p)) for p in sys.argv[3:]]
ch = np.nonzero(a["outcome"] != b["outcome"])[0]
print(f"{sys.argv[2]}: outcomes changed vs A: {len(ch)} of {len(ch) and len(a['outcome']) or len(a['outcome'])} "
      f"{dict(Counter(zip(a['outcome'][ch], b['outcome'][ch])))}")
for p, f in fines:
    ea = int((a["outcome"] != f["outcome"]).sum()); eb = int((b["outcome"] != f["outcome"]).sum())
    agA = int((a["outcome"][ch] == f["outcome"][ch]).sum()); agB = int((b["outcome"][ch] == f["outcome"][ch]).sum())
    print(f"  vs {p.split('/')[-1]}: A differs in {ea}, B in {eb}; of the {len(ch)} changed, fine sides with A {agA}, B {agB}, neither {len(ch)-agA-agB}")
    same = (a["outcome"] == f["outcome"]) & (b["outcome"] == f["outcome"])
    for c in ("t_outcome", "max_tilt_deg", "slide_distance", "max_penetration", "energy_dissipated_j"):
        da = np.abs(a[c][same] - f[c][same]); db = np.abs(b[c][same] - f[c][same])
        ok = np.isfinite(da) & np.isfinite(db)
        print(f"    {c:20s} |A-fine| mean {da[ok].mean():.3g} p90 {np.percentile(da[ok],90):.3g} max {da[ok].max():.3g}"
              f" | |B-fine| mean {db[ok].mean():.3g} p90 {np.percentile(db[ok],90):.3g} max {db[ok].max():.3g}")
