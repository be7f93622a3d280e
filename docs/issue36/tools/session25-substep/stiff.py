import sys, copy
sys.path.insert(0, "/work/wt-substep/tests")
import numpy as np
import test_edges3d as T
from touchdown.bench.reference3d import Ground3, Lander3, Law, MOON_R, Start3, solve3
from touchdown.sim.run import run
from touchdown.sim.scenario import parse
for v in (0.005, 0.00625, 0.00833334, 0.0125, 0.025):
    doc = T.STIFF_STOP_BESIDE_A_HOLDING_PAIR
    if isinstance(doc, str):
        import tomllib; doc = tomllib.loads(doc)
    doc = copy.deepcopy(doc); doc.setdefault("sim", {})["impact_substep"] = v
    params = parse(doc, "case 173")
    records = list(run(params))
    k = next(i for i, r in enumerate(records) if r.tick == 7)
    start, end = records[k].state.rows[0], records[k + 10].state.rows[0]
    c = np.array([MOON_R, 0.0, 0.0])
    y0 = np.concatenate([np.array(start["pos_m"]) - c, start["vel_mps"], start["quat"], start["omega_body_radps"]])
    ref = solve3(Lander3(), Ground3(slope_deg=6.0, slope_azimuth_deg=90.0), Start3(state="contact", vertical_speed_mps=0.0),
                 0.5, law=Law(), method="LSODA", y0=y0, stop_at_tipped=False).y(0.5)
    way = np.linalg.norm(ref[0:3] + c - np.array(start["pos_m"]))
    dp = np.linalg.norm(np.array(end["pos_m"]) - ref[0:3] - c); dv = np.linalg.norm(np.array(end["vel_mps"]) - ref[3:6])
    print(f"{v}: sliding {list(start['sliding'])} pos off {dp*1000:.2f} mm (tol {10*way:.2f} mm: {dp/(0.01*way):.2f}) vel off {dv*1000:.1f} mm/s (tol 10: {dv/0.01:.2f})", flush=True)
