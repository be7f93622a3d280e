"""Every kept hit equals a fresh evaluation from the same inputs, bit for bit (uncompiled copy)."""
import struct, sys, tomllib
sys.path.insert(0, "/work/wt-carry/bench")
import numpy as np
import touchdown.sim.flight as fl
last = {}
f_at = fl.kept_contact_at
def at(log, fb, ground, m, absorbing, engage):
    last["args"] = (fb, ground, m, absorbing, engage)
    return f_at(log, fb, ground, m, absorbing, engage)
fl.kept_contact_at = at
f_k = fl.kept_contact
n = [0, 0]
def flat(x):
    if isinstance(x, (tuple, list)):
        return [y for e in x for y in flat(e)]
    return [struct.pack("<d", float(x))]
def kc(log):
    ce = f_k(log)
    fresh = fl.contact_inline(*last["args"])
    n[0] += 1
    if flat(ce) != flat(fresh):
        n[1] += 1
    return ce
fl.kept_contact = kc
from touchdown.sim.run import run_blocks
from touchdown.sim.scenario import parse
if sys.argv[1] == "env":
    from touchdown import scenarios
    from touchdown.sweep.cases import Axis, Sweep
    from touchdown.sweep.fleet import run_part
    doc = tomllib.loads(scenarios.text("envelope"))
    axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
            Axis("ships.initial.horizontal_speed", 0.0, 6.0),
            Axis("ships.initial.tilt_deg", 0.0, 15.0)]
    sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)
    run_part(sw, list(range(0, 300, int(sys.argv[2]))))
else:
    import states
    name, ini, inputs = states.SCENES[int(sys.argv[1])]
    scn = parse({"name": "cost", "duration": 40 * 0.05,
                 "ships": states.ships_in_state(ini, inputs, int(sys.argv[2])), "sim": {"dt": 0.05}}, "bench")
    for _b in run_blocks(scn):
        pass
print(sys.argv[1:], "kept hits", n[0], "differing from a fresh evaluation", n[1])
