"""Ticks of the envelope sweep's cases by surface state, and how many of them repeat the last
tick's state bit for bit (copied by sim.step.Resting, or stepped to the same bits), over the
README's three axes (session 27 helper sweep).

    python docs/issue36/tools/sweep27_ticks.py [N_CASES]
"""
import sys
import tomllib

import numpy as np

from touchdown import scenarios
from touchdown.sweep import fleet as F
from touchdown.sweep.cases import Axis, Sweep

n = int(sys.argv[1]) if len(sys.argv) > 1 else 1000
doc = tomllib.loads(scenarios.text("envelope"))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
        Axis("ships.initial.horizontal_speed", 0.0, 6.0),
        Axis("ships.initial.tilt_deg", 0.0, 15.0)]
sw = Sweep.of(doc, "envelope", axes, samples=n, seed=1)
counts = np.zeros((5, 2), np.int64)  # state x (new bits, same bits)
inner = F.step_ticks
last = {}


def spy(recs, state, inputs, queue, span, out, cap):
    before = state.copy()
    r = inner(recs, state, inputs, queue, span, out, cap)
    k = r[0]
    s = out.states[:k]
    w = s.view(np.uint8).reshape(k, s.shape[1], -1)
    prev = np.concatenate([before.view(np.uint8).reshape(1, s.shape[1], -1), w[:-1]])
    same = np.all(w == prev, axis=2)
    for st in range(5):
        m = s["surface_state"] == st
        counts[st, 0] += np.sum(m & ~same)
        counts[st, 1] += np.sum(m & same)
    return r


F.step_ticks = spy
cols = F.run_part(sw, list(range(n)))
names = ["flying", "contact", "landed", "tipped", "crashed"]
tot = counts.sum()
print(f"{n} cases, {tot} ship-ticks ({tot / n:.0f} a case)")
for st in range(5):
    print(f"{names[st]:<8} new bits {counts[st, 0] / n:7.1f} a case, same bits "
          f"{counts[st, 1] / n:7.1f} a case")
print("outcomes", {names[k]: int(np.sum(cols['state'] == k)) for k in range(5)})
