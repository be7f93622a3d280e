"""Contact evaluations a free-flight tick, with the kept hits (uncompiled copy):
TD_PY=1 PYTHONPATH=/tmp/carry-x/plain.pkg python counts.py ROW NSHIPS | env STRIDE"""
import collections, sys, tomllib
sys.path.insert(0, "/work/wt-carry/bench")
import numpy as np
import touchdown.sim.flight as fl
import touchdown.sim.integrators as ig
C = collections.Counter()
def wrap(mod, name, key):
    f = getattr(mod, name)
    def g(*a, **k):
        C[key] += 1
        return f(*a, **k)
    setattr(mod, name, g)
for n in ("contact_inline", "contact_at"):
    wrap(fl, n, "eval")
for n in ("contact_inline", "contact_at", "contact_forces"):
    wrap(ig, n, "eval")
wrap(fl, "kept_contact", "kept_hit")
import touchdown.sim.phases as ph
wrap(ph, "free_flight", "ff_ticks")
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
t = C["ff_ticks"]
print(sys.argv[1:], dict(C), "per free-flight tick: evals %.3f, kept hits %.3f (START's evals %.3f)"
      % (C["eval"] / t, C["kept_hit"] / t, (C["eval"] + C["kept_hit"]) / t))
