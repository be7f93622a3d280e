"""Where the four-foot interior-point solves of envelope touchdowns fall (uncompiled copy, the
tree's defaults): by free_flight's path (strike: impact sub-steps; coarse; fine) and the settle
margin / time held at the tick's start."""
import collections, sys, tomllib
import numpy as np
from touchdown import scenarios
from touchdown.sweep.cases import Axis, Sweep
from touchdown.sweep.fleet import run_part
import touchdown.sim.friction as fr
import touchdown.sim.flight as fl
C = collections.Counter(); ST = {}
f0 = fr._interior_point
def ipm(a_mat, slip, radius, lam, active):
    r = f0(a_mat, slip, radius, lam, active)
    if int(np.sum(active)) == 4:
        k = ST.get("key", "other")
        C[k] += 1; C[k + " newton"] += int(r)
    return r
fr._interior_point = ipm
ff0 = fl.free_flight
def ff(here, fb, s, n_sub, carry, coarse, log):
    ft = s.footing
    m, held = ft.settle_margin, (ft.settle_for_s if ft.settle_ticks > 0 else 0.0)
    band = ("m<-1" if m < -1 else "-1<m<0" if m <= 0 else
            "m>0,held<0.1s" if held < 0.1 else "m in(0,.25],held>=.1" if m <= 0.25 else "m>.25,held>=.1")
    ST["band"] = band
    ST["key"] = ("strike" if n_sub > here.cfg.coarse_substeps and n_sub > 2 else "flying?") + " " + band
    C["ff " + ST["key"]] += 1
    r = ff0(here, fb, s, n_sub, carry, coarse, log)
    ST["key"] = "other"
    return r
for _m in list(sys.modules.values()):
    if getattr(_m, "free_flight", None) is ff0:
        _m.free_flight = ff
c0 = fl.coarse_tick
def ct(*a):
    r = c0(*a)
    ST["key"] = ("coarse " if r else "fine ") + ST.get("band", "?")
    C["ticks " + ST["key"]] += 1
    return r
fl.coarse_tick = ct
cases = list(range(0, 300, int(sys.argv[1])))
doc = tomllib.loads(scenarios.text("envelope"))
if len(sys.argv) > 2:
    doc.setdefault("sim", {})["coarse_held"] = float(sys.argv[2])
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
        Axis("ships.initial.horizontal_speed", 0.0, 6.0),
        Axis("ships.initial.tilt_deg", 0.0, 15.0)]
sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)
run_part(sw, cases)
n = len(cases)
for k, v in sorted(C.items()):
    if not k.startswith("ff "):
        print(f"{k:40s} {v / n:8.2f} a touchdown")
