"""run N envelope cases with a perf map of the cached numba kernels written to /tmp/perf-PID.map"""
import os, sys, subprocess, tempfile
from numba.core import codegen as cg
SAVED = []
orig = cg.CPUCodeLibrary._object_getbuffer_hook.__func__
def hook(cls, ll_module):
    buf = orig(cls, ll_module)
    if buf:
        SAVED.append(bytes(buf))
    return buf
cg.CPUCodeLibrary._object_getbuffer_hook = classmethod(hook)
import time, tomllib
import numpy as np
from touchdown import scenarios
from touchdown.sweep.cases import Axis, Sweep
from touchdown.sweep.fleet import run_part
from touchdown.sim.compiled import numba
n = int(sys.argv[1])
doc = tomllib.loads(scenarios.text("envelope"))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
        Axis("ships.initial.horizontal_speed", 0.0, 6.0),
        Axis("ships.initial.tilt_deg", 0.0, 15.0)]
sw = Sweep.of(doc, "envelope", axes, samples=n, seed=1)
run_part(sw, [0])
# the engine
from numba.core.registry import cpu_target
eng = cpu_target.target_context.codegen()._engine
lines = []
for buf in SAVED:
    with tempfile.NamedTemporaryFile(suffix=".o", delete=False, dir="/tmp/s2/objs") as f:
        f.write(buf); name = f.name
    out = subprocess.run(["nm", "-S", "--defined-only", name], capture_output=True, text=True).stdout
    syms = []
    for ln in out.splitlines():
        parts = ln.split()
        if len(parts) == 4 and parts[2] in "tTwW":
            syms.append((int(parts[0], 16), int(parts[1], 16), parts[2], parts[3]))
    base = None
    for off, size, kind, s in syms:
        if kind == "T":
            try:
                a = eng.get_function_address(s)
            except Exception:
                a = 0
            if a:
                base = a - off; break
    if base is None:
        continue
    for off, size, kind, s in syms:
        lines.append(f"{base+off:x} {size:x} {s}")
    pass
open(f"/tmp/perf-{os.getpid()}.map", "w").write("\n".join(lines) + "\n")
print("map lines", len(lines), "objects", len(SAVED), file=sys.stderr)
t0 = time.process_time()
res = run_part(sw, list(range(n)))
print(f"{n} cases {time.process_time()-t0:.3f} s CPU", file=sys.stderr)
