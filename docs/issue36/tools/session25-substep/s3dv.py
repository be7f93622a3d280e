"""The 142 in-scope 3-D starts (test_edges3d's reference sweep) under named sim overrides:
worst ratio of error to the test's tolerance (temporary; not committed)."""
import sys, json, time
sys.path.insert(0, "/work/wt-substep/tests")
import numpy as np
from touchdown.bench import edges3d as E
import test_edges3d as T
variants = json.loads(sys.argv[1])
res = {k: [] for k in variants}
for i, start in enumerate(T._sampled_starts(35, 200)):
    sc = T._start(**start)
    ref = E.run_reference(sc)
    til = E.tilt_deg(ref)
    if not (ref.first("tipped") is None and ref.first("liftoff") is None
            and abs(float(til.max()) - T._edge_limit_deg(start["com"], start["leg"])) > 3.0
            and (til[-1] < til.max() - 0.5 or til.max() < 5.0)):
        continue
    peak_ref = E.peak_tilt(ref)
    way = float(np.linalg.norm(E.horizontal_m(ref)[-1]))
    for k, sim in variants.items():
        s = E.run_sim(sc, 0.05, sim=sim)
        off = float(np.linalg.norm(E.horizontal_m(s)[-1] - E.horizontal_m(ref)[-1]))
        res[k].append((i, abs(E.peak_tilt(s) - peak_ref) / max(0.01 * peak_ref, 0.1),
                       off / (0.01 * way + 0.01), off, way))
for k, rows in res.items():
    miss = [(x[0], round(max(x[1], x[2]), 2)) for x in rows if x[1] > 1 or x[2] > 1]
    print(f"{k}: n={len(rows)} worst peak {max(x[1] for x in rows):.3f} worst slide "
          f"{max(x[2] for x in rows):.3f} p90 slide {np.percentile([x[2] for x in rows], 90):.3f}"
          f" misses {miss}", flush=True)
