"""run_part over the 300-case envelope (seed 1) with callgrind's instrumentation on only around it:
valgrind --tool=callgrind --instr-atstart=no python ir_toggled.py 300 out.npz"""
import os, subprocess, sys, tomllib, time
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
subprocess.run(["callgrind_control", "-i", "on", str(os.getpid())], check=True, capture_output=True)
cols = run_part(sw, list(range(n)))
subprocess.run(["callgrind_control", "-i", "off", str(os.getpid())], check=True, capture_output=True)
if len(sys.argv) > 2:
    np.savez(sys.argv[2], **{k: np.asarray(v) for k, v in cols.items() if np.asarray(v).dtype != object})
