"""What each tick of envelope touchdowns costs, tick by tick (issue 36, session 10).

    python tick_costs.py [STRIDE [COSTS.pkl]]   # cases 0, STRIDE, 2 STRIDE, ... of the 300 (default
                                                # 15); COSTS.pkl: {(case, tick): us} for strike_join.py

The step is a pure function of state and inputs: each tick of a case is restarted from its
recorded state in a batch of 100 copies of the ship (sim.step.step, one call) and timed, least of
three; the cost a ship-tick is the call's time over 100 (the call's own overhead spread thin).
Prints the cases' ticks grouped by state and the feet sliding at the tick's start, and the 40
dearest ticks (case, tick, state, sliding feet, speed, us), which is where docs/issue36's session
10 found micro-slips near rest cut into 20-40 pieces a sub-step (MODEL-NOTES 61). CPU time: run it
on an idle machine (under load the figures inflate unevenly)."""
import collections
import copy
import sys
import time
import tomllib

import numpy as np

from touchdown import scenarios
from touchdown.sim.run import run
from touchdown.sim.scenario import parse
from touchdown.sim.state import Inputs, State
from touchdown.sim.step import step
from touchdown.sweep.cases import Axis, Sweep

COPIES = 100
stride = int(sys.argv[1]) if len(sys.argv) > 1 else 15
doc = tomllib.loads(scenarios.text("envelope"))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
        Axis("ships.initial.horizontal_speed", 0.0, 6.0),
        Axis("ships.initial.tilt_deg", 0.0, 15.0)]
sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)
cases = list(range(0, 300, stride))
groups = collections.defaultdict(lambda: [0, 0.0])
ticks = []
for c in cases:
    one = sw.case_doc(c)
    many = copy.deepcopy(one)
    many["ships"] = [dict(copy.deepcopy(one["ships"][0]), id=f"s{i}") for i in range(COPIES)]
    batch = parse(many, "batch")
    recs = list(run(parse(one, "one")))
    for r0, r1 in zip(recs[:-1], recs[1:]):
        row = r0.state.rows[0]
        states = State(rows=np.repeat(r0.state.rows, COPIES), tick=r0.state.tick)
        inputs = Inputs(rows=np.repeat(r1.inputs.rows, COPIES))
        best = float("inf")
        for _ in range(3):
            t0 = time.perf_counter()
            step(batch.params, states, inputs)
            best = min(best, time.perf_counter() - t0)
        us = best / COPIES * 1e6
        sliding = "".join(str(int(b)) for b in row["sliding"])
        key = (int(row["surface_state"]), sliding)
        groups[key][0] += 1
        groups[key][1] += us
        ticks.append((us, c, r0.tick, key, float(np.linalg.norm(row["vel_mps"]))))
total = sum(us for us, *_ in ticks)
print(f"{len(cases)} cases, {total / len(cases):.0f} us a touchdown (ticks restarted in batches)")
print("state sliding   ticks/case   us a tick   share")
for (state, sliding), (n, us) in sorted(groups.items(), key=lambda kv: -kv[1][1]):
    print(f"{state:5d} {sliding:>7s} {n / len(cases):12.1f} {us / n:11.1f} {100 * us / total:6.1f}%")
print("the dearest ticks: us, case, tick, (state, sliding), speed m/s")
for t in sorted(ticks, reverse=True)[:40]:
    print(f"{t[0]:8.1f} {t[1]:4d} {t[2]:4d} {t[3]} {t[4]:.3f}")
if len(sys.argv) > 2:
    import pickle
    with open(sys.argv[2], "wb") as f:
        pickle.dump({(c, int(tk)): us for us, c, tk, key, sp in ticks}, f)
