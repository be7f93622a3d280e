"""tests/test_edges3d.py's 200 sampled starts (142 in scope) under variants of at_transition
(transition_variants.patch's modes): each start's peak tilt and end against the reference, the
test's measure and its 1% bound (issue 36, session 14, fast42d). References cached in /tmp.
    PYTHONPATH=TREE.pkg python edges_variants.py OUT.pkl [VARIANT,...]"""
import sys, pickle, os, time
import pathlib
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[3] / "tests"))
import numpy as np
from touchdown.bench import edges3d as E
import test_edges3d as T
VARS = {"old": {"transition_pairs": False}, "noat": {"transition_mode_x": 2.0},
        "broken": {"transition_pairs": False, "transition_mode_x": 3.0},
        "m5": {"transition_pairs": False, "transition_mode_x": 5.0},
        "m6": {"transition_pairs": False, "transition_mode_x": 6.0}}
if len(sys.argv) > 2:
    VARS = {k: v for k, v in VARS.items() if k in sys.argv[2].split(",")}
starts = list(T._sampled_starts(35, 200))
order = [118, 48] + [i for i in range(200) if i not in (118, 48)]
refp = "/tmp/edges_variants_refs.pkl"
refs = pickle.load(open(refp, "rb")) if os.path.exists(refp) else {}
out = {}
outp = sys.argv[1]
for n, i in enumerate(order):
    start = starts[i]
    sc = T._start(**start)
    if i not in refs:
        ref = E.run_reference(sc)
        til = E.tilt_deg(ref)
        scope = (ref.first("tipped") is None and ref.first("liftoff") is None
                 and abs(float(til.max()) - T._edge_limit_deg(start["com"], start["leg"])) > 3.0
                 and (til[-1] < til.max() - 0.5 or til.max() < 5.0))
        refs[i] = (scope, E.peak_tilt(ref), E.horizontal_m(ref)[-1]) 
        if n % 10 == 0: pickle.dump(refs, open(refp, "wb"))
    scope, peak_ref, end_ref = refs[i]
    if not scope: continue
    way = float(np.linalg.norm(end_ref))
    row = {}
    for vn, ov in VARS.items():
        t0 = time.process_time()
        sim = E.run_sim(sc, 0.05, sim=ov)
        row[vn] = (E.peak_tilt(sim), float(np.linalg.norm(E.horizontal_m(sim)[-1] - end_ref)), time.process_time() - t0)
    out[i] = (peak_ref, way, row)
    ok = {vn: (abs(r[0] - peak_ref) <= max(0.01 * peak_ref, 0.1) and r[1] <= 0.01 * way + 0.01) for vn, r in row.items()}
    print(i, f"way {way:.4f}", " ".join(f"{vn}: off {1e3*r[1]:.2f}mm peak {r[0]-peak_ref:+.4f} {'ok' if ok[vn] else 'MISS'}" for vn, r in row.items()), flush=True)
    pickle.dump(out, open(outp, "wb"))
pickle.dump(refs, open(refp, "wb"))
print("in scope", len(out))
