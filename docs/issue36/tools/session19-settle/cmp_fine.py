"""cmp_fine.py FINE.npz A.npz [B.npz ...]: each run's |x - fine| by column (p50, p90, mean, max)
and its outcomes differing from the fine run's (envelope_columns.py's files)."""
import sys

import numpy as np

COLS = ("t_outcome", "max_tilt_deg", "slide_distance", "max_penetration", "peak_normal_force",
        "energy_dissipated_j")
ref = np.load(sys.argv[1], allow_pickle=True)
for path in sys.argv[2:]:
    a = np.load(path, allow_pickle=True)
    print(f"{path}: outcomes differing from fine {int(np.sum(a['state'] != ref['state']))}")
    for c in COLS:
        x, r = a[c].astype(float), ref[c].astype(float)
        ok = np.isfinite(x) & np.isfinite(r)
        e = np.abs(x[ok] - r[ok])
        print(f"  {c:20s} p50 {np.percentile(e, 50):10.4g} p90 {np.percentile(e, 90):10.4g}"
              f" mean {e.mean():10.4g} max {e.max():10.4g}")
