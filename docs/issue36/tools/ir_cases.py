"""Instructions of N envelope touchdowns, counted by valgrind's callgrind only around the sweep's
loop (perf has no hardware counters on these VMs):

    python ir_cases.py 1            # once, outside valgrind: the kernels compiled into the cache
    valgrind --tool=callgrind --instr-atstart=no --callgrind-out-file=OUT python ir_cases.py 300 [X.npz]
    # the "Collected" line (or callgrind_annotate OUT's total) is the 300 cases' instructions

The workload is bench/states.py's "300 touchdowns of 20 s": the envelope scene on a 6 degree slope,
vertical -12..-1 m/s, horizontal 0..6 m/s, tilt 0..15 deg, Latin hypercube, seed 1, run by
sweep.fleet.run_part (the sweep's own loop) after one case that loads the kernels. X.npz: the
outcome columns, to compare versions' results. Instrumentation is switched on and off with
callgrind_control, so the imports and the kernels' loading run at valgrind's uninstrumented speed."""
import os
import subprocess
import sys
import tomllib

import numpy as np

from touchdown import scenarios
from touchdown.sweep.cases import Axis, Sweep
from touchdown.sweep.fleet import run_part

n = int(sys.argv[1])
doc = tomllib.loads(scenarios.text("envelope"))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
        Axis("ships.initial.horizontal_speed", 0.0, 6.0),
        Axis("ships.initial.tilt_deg", 0.0, 15.0)]
sw = Sweep.of(doc, "envelope", axes, samples=max(n, 300), seed=1)
run_part(sw, [0])  # kernels loaded, first-call costs paid
under_valgrind = "valgrind" in os.environ.get("LD_PRELOAD", "") or "vgpreload" in os.environ.get(
    "LD_PRELOAD", "")
if under_valgrind:
    subprocess.run(["callgrind_control", "-i", "on", str(os.getpid())], check=True,
                   capture_output=True)
cols = run_part(sw, list(range(n)))
if under_valgrind:
    subprocess.run(["callgrind_control", "-i", "off", str(os.getpid())], check=True,
                   capture_output=True)
if len(sys.argv) > 2:
    np.savez(sys.argv[2], **{k: np.asarray(v) for k, v in cols.items()
                             if np.asarray(v).dtype != object})
