import sys
import numpy as np
import pyarrow.parquet as pq
a = pq.read_table(sys.argv[1]).to_pydict(); b = pq.read_table(sys.argv[2]).to_pydict()
print("rows", len(next(iter(a.values()))), len(next(iter(b.values()))))
for c in a:
    x, y = a[c], b[c]
    try:
        xa, ya = np.asarray(x, float), np.asarray(y, float)
    except (TypeError, ValueError):
        nd = sum(1 for p, q in zip(x, y) if p != q)
        print(f"{c:28s} differ {nd:5d} (non-numeric)")
        continue
    both_nan = np.isnan(xa) & np.isnan(ya)
    d = np.abs(xa - ya)[~both_nan]
    nd = int((d != 0).sum())
    if len(d) == 0:
        continue
    print(f"{c:28s} differ {nd:5d}  max {np.nanmax(d):.3g}  p99 {np.nanpercentile(d, 99):.3g}  p90 {np.nanpercentile(d, 90):.3g}")
