"""session33_tick_kinds.py N (TD_PY=1, PYTHONPATH=an uncompiled copy, docs/issue35/tools/uncompiled):
N of the 300 envelope touchdowns: fine ticks that strike (S) or not (q), their pieces, method
steps and Python time, a touchdown's average (issue 36, session 33)."""
import sys, collections, tomllib, time
from touchdown import scenarios
from touchdown.sim import phases, flight, integrators
from touchdown.sweep.cases import Axis, Sweep
from touchdown.sweep.fleet import run_part
cnt = collections.Counter()
cur = {"strike": None}
o_str = phases.striking
def striking(here, s):
    r = o_str(here, s); cur["strike"] = r; return r
phases.striking = striking
o_ff = flight.free_flight
def free_flight(here, fb, s, n_sub, carry, coarse, log):
    key = "S" if cur["strike"] else "q"
    cnt["ticks " + key] += 1
    cur["key"] = key
    t0 = time.perf_counter()
    r = o_ff(here, fb, s, n_sub, carry, coarse, log)
    cnt["time " + key] += time.perf_counter() - t0
    cur["strike"] = None
    return r
phases.free_flight = free_flight
o_vf = flight.vertical_flight
def vertical_flight(*a):
    cnt["ticks vertical"] += 1; return o_vf(*a)
phases.vertical_flight = vertical_flight
for name in ("rk4_held", "rk4", "rk2_held", "rk2"):
    for mod in (flight, integrators):
        if hasattr(mod, name):
            f = getattr(mod, name)
            def w(*a, _f=f, _n=name):
                cnt[_n + " " + cur.get("key", "?")] += 1; return _f(*a)
            setattr(mod, name, w)
o_sp = flight.step_piece
def sp(*a):
    cnt["pieces " + cur.get("key", "?")] += 1; return o_sp(*a)
flight.step_piece = sp
doc = tomllib.loads(scenarios.text("envelope"))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0), Axis("ships.initial.horizontal_speed", 0.0, 6.0), Axis("ships.initial.tilt_deg", 0.0, 15.0)]
sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)
n = int(sys.argv[1])
run_part(sw, list(range(0, 300, 300 // n)))
for k, v in sorted(cnt.items()):
    print(k, round(v / n, 3))
