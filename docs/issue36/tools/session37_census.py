"""Where a sweep case's CPU goes (session 37): each of K envelope cases stepped alone as a fleet of
R copies of itself (so a tick's time over R is that case's cost of that tick, the interpreter's
share spread thin), every tick classed by the ship's state at its start: flying; in contact with
the settle thresholds holding (settling), with a foot sliding (sliding: impacts too), with every
foot holding (held); landed or tipped and stepped (pinned); at a fixed point, copied (fixed).
Then a histogram of the contact ticks' costs over 10 of the cases.

    .venv/bin/python docs/issue36/tools/session37_census.py 40
"""
import sys, time, numpy as np, tomllib
from touchdown.sweep.cases import Sweep, Axis
import touchdown.sweep.fleet as F
n = 2000; R = 200; K = int(sys.argv[1]) if len(sys.argv) > 1 else 30
from pathlib import Path
doc = tomllib.loads((Path(__file__).resolve().parents[3] / "scenarios" / "envelope.toml")
                   .read_text())
sw = Sweep.of(doc, "envelope", [Axis("ships.initial.vertical_speed", -12, -1),
    Axis("ships.initial.horizontal_speed", 0, 6), Axis("ships.initial.tilt_deg", 0, 15)],
    samples=n, seed=1)
F.BLOCK_SHIP_TICKS = R
orig_st = F.step_ticks
rows = []
def st(recs, state, inputs, q, span, out, cap):
    before = state[0].copy(); fixed = bool(out.rest.fixed[0])
    t0 = time.perf_counter()
    r = orig_st(recs, state, inputs, q, span, out, cap)
    rows.append((time.perf_counter() - t0, before, fixed))
    return r
F.step_ticks = st
def build(i):
    fl = F.Fleet.build(sw, [i])
    for f in ("cases", "ships", "state", "inputs", "fuel0", "initial_state", "acc", "group",
              "rot_index"):
        setattr(fl, f, np.repeat(getattr(fl, f), R, axis=0))
    return fl
fl = build(0); fl.step(); rows.clear()
names = ["flying", "settling", "sliding", "held", "pinned", "fixed"]
tot = np.zeros(6); cnt = np.zeros(6)
per_case = []
for i in np.random.default_rng(5).choice(n, K, replace=False):
    fl = build(i); rows.clear(); fl.step()
    ct = 0.0
    for dt, b, fixed in rows:
        ss = b["surface_state"]
        if fixed: c = 5
        elif ss == 0: c = 0
        elif ss == 1: c = 1 if b["settle_ticks"] > 0 else (2 if b["sliding"].any() else 3)
        else: c = 4
        tot[c] += dt / R; cnt[c] += 1; ct += dt / R
    per_case.append(ct)
print(f"{K} cases: mean {np.mean(per_case)*1e3:.3f} ms/case "
      f"(median {np.median(per_case)*1e3:.3f}, max {np.max(per_case)*1e3:.3f})")
for k in range(6):
    if cnt[k]:
        print(f"  {names[k]:9s} {cnt[k]/K:7.1f} ticks/case {tot[k]/cnt[k]*1e6:8.2f} us/tick"
              f" -> {tot[k]/K*1e3:.3f} ms/case")
# distribution of stepped contact tick costs
allc = []
for i in np.random.default_rng(5).choice(n, 10, replace=False):
    fl = build(i); rows.clear(); fl.step()
    for dt, b, fixed in rows:
        if not fixed and b["surface_state"] == 1:
            allc.append(dt / R * 1e6)
allc = np.array(allc)
edges = [0, 5, 10, 20, 40, 80, 160, 320, 640, 1e9]
h, _ = np.histogram(allc, edges)
for lo, hi, k in zip(edges, edges[1:], h):
    m = (allc >= lo) & (allc < hi)
    print(f"  {lo:5.0f}-{hi:<5.0f} us: {k:5d} ticks, "
          f"{allc[m].sum()/allc.sum()*100:5.1f}% of contact time")
