import sys, json
sys.path.insert(0, "/work/wt-substep/tests")
import numpy as np
from touchdown.bench import edges3d as E
import test_edges3d as T
starts = list(T._sampled_starts(35, 200))
variants = {"5ms": {}, "1ms": {"impact_substep": 0.001},
            "1ms,stiff0.1ms": {"impact_substep": 0.001, "stiff_substep": 0.0001},
            "fine(max5,imp1,coarse0,stiff0.1)": {"max_substep": 0.005, "impact_substep": 0.001, "coarse_substep": 0.0, "stiff_substep": 0.0001},
            "2.5ms": {"impact_substep": 0.0025}, "6.25ms": {"impact_substep": 0.00625},
            "8.33ms": {"impact_substep": 0.00833334}}
for i in [int(a) for a in sys.argv[1].split(",")]:
    sc = T._start(**starts[i]); ref = E.run_reference(sc)
    way = float(np.linalg.norm(E.horizontal_m(ref)[-1]))
    for name, sim in variants.items():
        s = E.run_sim(sc, 0.05, sim=sim)
        off = float(np.linalg.norm(E.horizontal_m(s)[-1] - E.horizontal_m(ref)[-1]))
        print(f"start {i} {name:34s} peak {E.peak_tilt(s):.3f} (ref {E.peak_tilt(ref):.3f}) off {off*100:.2f} cm of {way:.3f} m: {off/(0.01*way+0.01):.2f} of tol", flush=True)
