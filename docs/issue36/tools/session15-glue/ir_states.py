"""callgrind Ir of a bench/states.py scene row: python ir_states.py ROW NSHIPS [MAP]
instrumentation on around the run_blocks loop only (after a warm one-tick run). With MAP: a perf-style
map of the cached kernels' symbols written to MAP (the perfmap_run.py hook)."""
import os, sys, subprocess, tempfile
SAVED = []
want_map = len(sys.argv) > 3
if want_map:
    from numba.core import codegen as cg
    orig = cg.CPUCodeLibrary._object_getbuffer_hook.__func__
    def hook(cls, ll_module):
        buf = orig(cls, ll_module)
        if buf:
            SAVED.append(bytes(buf))
        return buf
    cg.CPUCodeLibrary._object_getbuffer_hook = classmethod(hook)
sys.path.insert(0, "/work/wt-glue/bench")
import states
from touchdown.sim.run import run_blocks
from touchdown.sim.scenario import parse
row = int(sys.argv[1]); n = int(sys.argv[2])
name, ini, inputs = (states.SCENES + [None])[row] if row < len(states.SCENES) else (None, None, None)
dt = 0.05; n_ticks = 40
scn = parse({"name": "cost", "duration": n_ticks * dt,
             "ships": states.ships_in_state(ini, inputs, n), "sim": {"dt": dt}}, "bench")
next(iter(run_blocks(scn, last_tick=1)))
for _b in run_blocks(scn):
    pass
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
    open(sys.argv[3], "w").write("\n".join(lines) + "\n")
    print("map lines", len(lines), "objects", len(SAVED), file=sys.stderr)
vg = "vgpreload" in os.environ.get("LD_PRELOAD", "")
if vg:
    subprocess.run(["callgrind_control", "-i", "on", str(os.getpid())], check=True, capture_output=True)
for _b in run_blocks(scn):
    pass
if vg:
    subprocess.run(["callgrind_control", "-i", "off", str(os.getpid())], check=True, capture_output=True)
print(name, file=sys.stderr)
