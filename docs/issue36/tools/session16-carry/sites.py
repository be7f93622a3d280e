import collections, sys
sys.path.insert(0, "/work/wt-carry/bench")
import touchdown.sim.flight as fl
import touchdown.sim.integrators as ig
import touchdown.sim.phases as ph
C = collections.Counter()
def wrap(mod, name):
    f = getattr(mod, name)
    def g(*a, **k):
        fr = sys._getframe(1)
        C[(mod.__name__.split('.')[-1], name, fr.f_code.co_name, fr.f_lineno)] += 1
        return f(*a, **k)
    setattr(mod, name, g)
for n in ("contact_inline", "contact_at", "contact_memo"):
    wrap(fl, n)
for n in ("contact_inline", "contact_at", "contact_forces"):
    wrap(ig, n)
wrap(fl, "kept_contact"); wrap(ph, "free_flight")
from touchdown.sim.run import run_blocks
from touchdown.sim.scenario import parse
if sys.argv[1] == "env":
    import tomllib
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
for k, v in sorted(C.items(), key=lambda kv: -kv[1]):
    print(v, k)
