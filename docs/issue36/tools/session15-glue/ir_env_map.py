"""callgrind Ir of a bench/states.py scene row: python ir_states.py ROW NSHIPS [MAP]
instrumentation on around the run_blocks loop only (after a warm one-tick run). With MAP: a perf-style
map of the cached kernels' symbols written to MAP (the perfmap_run.py hook)."""
import os, sys, subprocess, tempfile
SAVED = []
want_map = len(sys.argv) > 2
if want_map:
    from numba.core import codegen as cg
    orig = cg.CPUCodeLibrary._object_getbuffer_hook.__func__
    def hook(cls, ll_module):
        buf = orig(cls, ll_module)
        if buf:
            SAVED.append(bytes(buf))
        return buf
    cg.CPUCodeLibrary._object_getbuffer_hook = classmethod(hook)
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
run_part(sw, [0])
if want_map:
    from numba.core.registry import cpu_target
    eng = cpu_target.target_context.codegen()._engine
    lines = []
    for buf in SAVED:
        with tempfile.NamedTemporaryFile(suffix=".o", delete=False, dir="/tmp/glue/objs") as f:
            f.write(buf); fname = f.name
        out = subprocess.run(["nm", "-S", "--defined-only", fname], capture_output=True, text=True).stdout
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
    open(sys.argv[2], "w").write("\n".join(lines) + "\n")
    print("map lines", len(lines), "objects", len(SAVED), file=sys.stderr)
vg = "vgpreload" in os.environ.get("LD_PRELOAD", "")
if vg:
    subprocess.run(["callgrind_control", "-i", "on", str(os.getpid())], check=True, capture_output=True)
cols = run_part(sw, list(range(n)))
if vg:
    subprocess.run(["callgrind_control", "-i", "off", str(os.getpid())], check=True, capture_output=True)
