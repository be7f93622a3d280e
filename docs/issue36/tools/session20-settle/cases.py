import sys; sys.path.insert(0, "tests")
import numpy as np
from scenes import records, scene
from touchdown.sim.enums import EventKind
CASES = {"252": ({"altitude": 0.5, "vertical_speed": -4.189924582420963,
      "horizontal_speed": 4.892093374164177, "heading_deg": 90.0,
      "tilt_deg": 7.945431338442698}, 15.0),
 "base": ({"altitude": 0.5, "vertical_speed": -2.0, "horizontal_speed": 1.0, "heading_deg": 90.0}, 12.0)}
body = {"terrain": {"slope_deg": 6.0, "slope_azimuth_deg": 90.0}}
for name, (initial, dur) in CASES.items():
    runs = {k: records(scene(initial, body=body, duration=dur, sim=sim)) for k, sim in (
        ("new", {}), ("old", {"coarse_held": 0.0}), ("fine", {"coarse_substep": 0.0}),
        ("h25", {"coarse_held": 0.25}))}
    ev = {k: [(r.tick, EventKind(e.kind).topic, float(e.t_event_s)) for r in runs[k]
              for e in r.events] for k in runs}
    pos = {k: np.array([r.state.rows[0]["pos_m"] for r in runs[k]]) for k in runs}
    print(name, ev["new"])
    for o in ("old", "fine", "h25"):
        same = [(a, b) for a, b, _ in ev["new"]] == [(a, b) for a, b, _ in ev[o]]
        d = max(abs(x[2] - y[2]) for x, y in zip(ev["new"], ev[o]))
        dp = np.max(np.linalg.norm(pos["new"] - pos[o], axis=1)) if pos["new"].shape == pos[o].shape else None
        print(f"  new vs {o}: same ticks {same} max |dt| {d:.3g} s, max |dpos| {dp:.3g} m, bits differ {np.any(pos['new'] != pos[o])}")
    d = max(abs(x[2] - y[2]) for x, y in zip(ev["old"], ev["fine"]))
    print(f"  old vs fine: max |dt| {d:.3g} s")
