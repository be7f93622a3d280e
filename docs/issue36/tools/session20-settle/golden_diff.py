import tomllib, sys
import numpy as np
from pathlib import Path
from touchdown.sim.run import run
from touchdown.sim.scenario import parse
from touchdown.sim.enums import EventKind
G = Path("tests/data/golden")
for name in ("tilted", "slope", "fleet", "bounce", "trip"):
    p = G / f"{name}.toml" if name in ("tilted", "slope", "fleet") else Path("scenarios") / f"{name}.toml"
    out = {}
    for k, v in (("new", None), ("old", 0.0)):
        doc = tomllib.loads(p.read_text())
        if v is not None:
            doc.setdefault("sim", {})["coarse_held"] = v
        recs = list(run(parse(doc, name)))
        ev = [(r.tick, e.ship, EventKind(e.kind).topic, float(e.t_event_s)) for r in recs for e in r.events]
        pos = [np.array(r.state.rows["pos_m"]) for r in recs]
        out[k] = (ev, pos)
    (e1, p1), (e0, p0) = out["new"], out["old"]
    same = [x[:3] for x in e1] == [x[:3] for x in e0]
    dt = max((abs(a[3] - b[3]) for a, b in zip(e1, e0)), default=0.0)
    dp = max(float(np.max(np.linalg.norm(a - b, axis=-1))) if a.shape == b.shape else float("nan") for a, b in zip(p1, p0))
    bits = any(a.shape != b.shape or np.any(a != b) for a, b in zip(p1, p0))
    print(f"{name}: events same {same} ({len(e1)}), max |dt| {dt:.3g} s, max |dpos| {dp:.3g} m, positions differ {bits}; "
          f"last events new {e1[-3:]} old {e0[-3:]}")
