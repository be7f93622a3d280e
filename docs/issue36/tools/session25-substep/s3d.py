"""The 142 in-scope 3-D starts of test_edges3d's reference sweep: worst ratio of error to the
test's tolerance, per impact_substep (temporary; not committed)."""
import sys, json, time
sys.path.insert(0, "/work/wt-substep/tests")
import numpy as np
from touchdown.bench import edges3d as E
import test_edges3d as T

VALUES = [float(v) for v in sys.argv[1].split(",")]
out = sys.argv[2]
res = {str(v): [] for v in VALUES}
t0 = time.time()
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
    for v in VALUES:
        sim = E.run_sim(sc, 0.05, sim={"impact_substep": v})
        peak = E.peak_tilt(sim)
        off = float(np.linalg.norm(E.horizontal_m(sim)[-1] - E.horizontal_m(ref)[-1]))
        rp = abs(peak - peak_ref) / max(0.01 * peak_ref, 0.1)
        ro = off / (0.01 * way + 0.01)
        res[str(v)].append((i, rp, ro, off, way, peak, peak_ref))
    print(i, f"{time.time()-t0:.0f}s", flush=True)
    json.dump(res, open(out, "w"))
json.dump(res, open(out, "w"))
