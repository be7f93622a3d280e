"""session33_unchanged_rows.py: of bench/mujoco_side.py's arriving landers (1,000, 100 ticks), the share of ship-ticks
whose state (and outputs) is bit-identical to the tick before (issue 36, session 33)."""
import numpy as np
from touchdown.sim.run import run_blocks
from touchdown.sim.scenario import parse
n = 1000
rng = np.random.default_rng(7)
ships = [{"id": f"s{i}", "initial": {"altitude": float(h), "vertical_speed": -float(v), "east": float(10.0 * i)}}
         for i, (h, v) in enumerate(zip(rng.uniform(0.5, 30.0, n), rng.uniform(2.0, 49.0, n)))]
scn = parse({"name": "arrivals", "duration": 100 * 0.05, "ships": ships}, "bench")
prev = None; same = tot = 0; same_out = 0
for b in run_blocks(scn):
    for k in range(len(b)):
        s = b.states[k].view(np.uint8).reshape(len(b.ship_ids), -1)
        o = b.outputs[k].view(np.uint8).reshape(len(b.ship_ids), -1)
        if prev is not None:
            eq = (s == prev[0]).all(axis=1); eqo = (o == prev[1]).all(axis=1)
            same += int(eq.sum()); same_out += int((eq & eqo).sum()); tot += len(eq)
        prev = (s.copy(), o.copy())
print(f"ship-ticks whose state is bit-identical to the tick before: {same / tot:.1%}; state and outputs: {same_out / tot:.1%}")
