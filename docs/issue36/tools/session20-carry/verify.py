"""Every kept hit equals a fresh evaluation from the same inputs, bit for bit (the uncompiled copy:
docs/issue35/tools/uncompiled/make.sh /tmp/plain; TD_PY=1 PYTHONPATH=/tmp/plain.pkg python
verify.py ROW N | env STEP); also the free-flight ticks' asks and hits.
ROW: a bench/states.py row (5 sliding, 6 rocking), N ships, 40 ticks; env: every STEP-th of the
300 envelope touchdowns (the sweep's loop)."""
import struct
import sys
import tomllib
from pathlib import Path

import touchdown.sim.flight as fl
from touchdown.sim.ship import ENGAGE_AT_GROUND

sys.path.insert(0, str(Path(fl.__file__).resolve().parents[1] / "bench"))
last = {}
n = {"asked": 0, "hits": 0, "differing": 0}
f_at, f_k = fl.kept_contact_at, fl.kept_contact


def at(log, fb, ground, m, absorbing):
    last["args"] = (fb, ground, m, absorbing, ENGAGE_AT_GROUND)
    n["asked"] += 1
    return f_at(log, fb, ground, m, absorbing)


def flat(x):
    if isinstance(x, (tuple, list)):
        return [y for e in x for y in flat(e)]
    return [struct.pack("<d", float(x))]


def kc(log):
    ce = f_k(log)
    fresh = fl.contact_inline(*last["args"])
    n["hits"] += 1
    if flat(ce) != flat(fresh):
        n["differing"] += 1
    return ce


fl.kept_contact_at, fl.kept_contact = at, kc
from touchdown.sim.run import run_blocks  # noqa: E402
from touchdown.sim.scenario import parse  # noqa: E402

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
                 "ships": states.ships_in_state(ini, inputs, int(sys.argv[2])),
                 "sim": {"dt": 0.05}}, "bench")
    for _b in run_blocks(scn):
        pass
print(sys.argv[1:], n)
