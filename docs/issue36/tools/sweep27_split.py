"""Timing splits of a sweep part in one process (session 27 helper sweep): CPU seconds of the
imports, the kernels' load, Fleet.build (parse), the step (step_ticks), the fold, and the table.

    python docs/issue36/tools/sweep27_split.py [N_CASES]
"""
import sys
import time

t00 = time.process_time()
import tomllib  # noqa: E402

import numpy as np  # noqa: E402

from touchdown import scenarios  # noqa: E402
from touchdown.sweep import fleet as F  # noqa: E402
from touchdown.sweep.cases import Axis, Sweep  # noqa: E402
from touchdown.sweep.run import Result, _gather  # noqa: E402

T = {}


def timed(name, fn):
    def wrap(*a, **k):
        t0 = time.process_time()
        try:
            return fn(*a, **k)
        finally:
            T[name] = T.get(name, 0.0) + time.process_time() - t0
    return wrap


T["import"] = time.process_time() - t00
n = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
doc = tomllib.loads(scenarios.text("envelope"))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
        Axis("ships.initial.horizontal_speed", 0.0, 6.0),
        Axis("ships.initial.tilt_deg", 0.0, 15.0)]
t0 = time.process_time()
sw = Sweep.of(doc, "envelope", axes, samples=n, seed=1)
T["Sweep.of"] = time.process_time() - t0
t0 = time.process_time()
F.run_part(sw, [0])
T["load kernels (1 case)"] = time.process_time() - t0
F.step_ticks = timed("step_ticks", F.step_ticks)
F._fold_block = timed("_fold_block", F._fold_block)
F.resting = timed("resting", F.resting)
F.Fleet.build = classmethod(timed("Fleet.build", F.Fleet.build.__func__))
F.Fleet._start = timed("Fleet._start", F.Fleet._start)
F._energy_into = timed("_energy_into", F._energy_into)
t0 = time.process_time()
cols = F.run_part(sw, list(range(n)))
T["run_part"] = time.process_time() - t0
t0 = time.process_time()
cols["case"] = np.asarray(cols["case"])
res = Result(sw, _gather(sw, [cols]))
res.write("/tmp/sweep27-split.parquet")
T["table + parquet"] = time.process_time() - t0
for k, v in T.items():
    print(f"{k:<24}{v:8.3f} s  {v / n * 1e6:9.1f} us a case")
