import sys, time, numpy as np
sys.path.insert(0, "tests")
from touchdown.bench import edges3d as E
from test_edges3d import _start, SHORT_SLIDE_ON_13_DEG as S
sc = _start(**S)
ref = E.run_reference(sc)
runs = {}
for name, sim in [("def", None), ("i2.5", {"impact_substep": 0.0025}), ("i1", {"impact_substep": 0.001}),
                  ("i1s.25", {"impact_substep": 0.001, "stiff_substep": 0.00025}),
                  ("i.5", {"impact_substep": 0.0005,"stiff_substep": 0.0005}), ("i.25", {"impact_substep": 0.00025,"stiff_substep": 0.00025}),
                  ("s0", {"stiff_substep": 0.0}), ("s0i1", {"stiff_substep": 0.0, "impact_substep": 0.001})]:
    tr = E.run_sim(sc, 0.05, sim=sim); runs[name] = tr
    print(name, "dist %.4f peak %.4f" % (E.distance_m(tr), E.peak_tilt(tr)), flush=True)
print("t   ref  " + " ".join(runs))
for t in [0.05,0.1,0.15,0.2,0.25,0.3,0.4,0.5,0.75,1.0,1.5,2,3]:
    hr = E.horizontal_m(ref); 
    line = "%.2f %.4f " % (t, np.linalg.norm([E.at(ref, hr[:,0], t), E.at(ref, hr[:,1], t)]))
    for n, tr in runs.items():
        h = E.horizontal_m(tr); line += "%.4f " % np.linalg.norm([E.at(tr, h[:,0], t), E.at(tr, h[:,1], t)])
    print(line)
