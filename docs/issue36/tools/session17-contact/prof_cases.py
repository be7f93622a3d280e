"""ir_states.py plus a symbol map of the cached kernels' object code: /tmp/contact-x/syms-PID.txt"""
import os, subprocess, sys, tempfile
from numba.core import codegen as cg
SAVED = []
orig = cg.CPUCodeLibrary._set_compiled_object
def hook(self, value):
    SAVED.append(bytes(value))
    return orig(self, value)
cg.CPUCodeLibrary._set_compiled_object = hook
orig2 = cg.CPUCodeLibrary._object_compiled_hook.__func__
def hook2(cls, ll_module, buf):
    SAVED.append(bytes(buf))
    return orig2(cls, ll_module, buf)
cg.CPUCodeLibrary._object_compiled_hook = classmethod(hook2)
import tomllib
from touchdown import scenarios
from touchdown.sweep.cases import Axis, Sweep
from touchdown.sweep.fleet import run_part
n = int(sys.argv[1])
doc = tomllib.loads(scenarios.text("envelope"))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
        Axis("ships.initial.horizontal_speed", 0.0, 6.0),
        Axis("ships.initial.tilt_deg", 0.0, 15.0)]
sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)
run_part(sw, list(range(n)))
from numba.core.registry import cpu_target
eng = cpu_target.target_context.codegen()._engine
lines = []
for buf in SAVED:
    with tempfile.NamedTemporaryFile(suffix=".o", delete=False, dir="/tmp/contact-x") as f:
        f.write(buf); name = f.name
    out = subprocess.run(["nm", "-S", "--defined-only", name], capture_output=True, text=True).stdout
    keep = f"/tmp/contact-x/objs/{os.getpid()}-{len(os.listdir('/tmp/contact-x/objs'))}.o"
    os.rename(name, keep); name = keep
    syms = []
    for ln in out.splitlines():
        parts = ln.split()
        if len(parts) == 4 and parts[2] in "tTwW":
            syms.append((int(parts[0], 16), int(parts[1], 16), parts[2], parts[3]))
    base = None
    for off, size, kind, s in syms:
        if kind in "TW" and "touchdown" in s:
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
open(f"/tmp/contact-x/syms-{os.getpid()}.txt", "w").write("\n".join(lines) + "\n")
print("objects", len(SAVED), "syms", len(lines), file=sys.stderr)
vg = "vgpreload" in os.environ.get("LD_PRELOAD", "")
if vg:
    subprocess.run(["callgrind_control", "-i", "on", str(os.getpid())], check=True, capture_output=True)
cols = run_part(sw, list(range(n)))
if vg:
    subprocess.run(["callgrind_control", "-i", "off", str(os.getpid())], check=True, capture_output=True)
