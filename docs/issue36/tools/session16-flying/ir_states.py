"""Ir of bench/states.py's row ROW over N ships, 40 ticks: callgrind on around the run_blocks loop.
   python ir_states.py ROW N   (outside valgrind: compiles/loads only)"""
import os, subprocess, sys
sys.path.insert(0, os.path.join(os.getcwd(), "bench"))
import states
from touchdown.sim.run import run_blocks
from touchdown.sim.scenario import parse
row, n = int(sys.argv[1]), int(sys.argv[2])
ticks = int(sys.argv[3]) if len(sys.argv) > 3 else 40
label, ini, inputs = states.SCENES[row]
scn = parse({"name": "cost", "duration": ticks * 0.05,
             "ships": states.ships_in_state(ini, inputs, n), "sim": {"dt": 0.05}}, "bench")
next(iter(run_blocks(scn, last_tick=1)))
vg = "vgpreload" in os.environ.get("LD_PRELOAD", "")
if vg:
    subprocess.run(["callgrind_control", "-i", "on", str(os.getpid())], check=True, capture_output=True)
for _b in run_blocks(scn):
    pass
if vg:
    subprocess.run(["callgrind_control", "-i", "off", str(os.getpid())], check=True, capture_output=True)
print(label, n, "done")
