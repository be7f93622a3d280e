"""callgrind Ir of a bench/states.py scene row: python ir_states.py ROW NSHIPS (instrumentation on
around a second run_blocks loop only). Adapted from docs/issue36/tools/session15-glue/ir_states.py."""
import os, sys, subprocess
sys.path.insert(0, "/work/wt-carry/bench")
import states
from touchdown.sim.run import run_blocks
from touchdown.sim.scenario import parse
row = int(sys.argv[1]); n = int(sys.argv[2])
name, ini, inputs = states.SCENES[row]
dt = 0.05; n_ticks = 40
scn = parse({"name": "cost", "duration": n_ticks * dt,
             "ships": states.ships_in_state(ini, inputs, n), "sim": {"dt": dt}}, "bench")
next(iter(run_blocks(scn, last_tick=1)))
for _b in run_blocks(scn):
    pass
vg = "vgpreload" in os.environ.get("LD_PRELOAD", "")
if vg:
    subprocess.run(["callgrind_control", "-i", "on", str(os.getpid())], check=True, capture_output=True)
for _b in run_blocks(scn):
    pass
if vg:
    subprocess.run(["callgrind_control", "-i", "off", str(os.getpid())], check=True, capture_output=True)
print(name, file=sys.stderr)
