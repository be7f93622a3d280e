"""Where a touchdown's contact work is asked for, by call site (issue 36, session 10): on the
uncompiled copy of the step (docs/issue35/tools/uncompiled/make.sh), each of sim.flight's calls
of substep, contact_at, coulomb, to_event, slip_rates and held_friction counted by its caller's
function and line, a touchdown's average over envelope cases 0, 15, ..., 285.

    docs/issue35/tools/uncompiled/make.sh /tmp/plain
    TD_PY=1 PYTHONPATH=/tmp/plain.pkg python call_sites.py

(Session 10 found a step taken again at every piece where a micro-slipping foot's friction was
an impulse after all: 39.8 a touchdown, now 0.1.)"""
import collections
import os
import sys
import tomllib

from touchdown import scenarios
from touchdown.sim import flight
from touchdown.sim.run import run
from touchdown.sweep.cases import Axis, Sweep

assert os.environ.get("TD_PY"), "run on the uncompiled copy with TD_PY=1 (see the docstring)"
counts = collections.Counter()


def counted(name):
    f = getattr(flight, name)

    def call(*a, **k):
        caller = sys._getframe(1)
        counts[(name, caller.f_code.co_name, caller.f_lineno)] += 1
        return f(*a, **k)
    setattr(flight, name, call)


for name in ("substep", "contact_at", "coulomb", "to_event", "slip_rates", "held_friction"):
    counted(name)
doc = tomllib.loads(scenarios.text("envelope"))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
        Axis("ships.initial.horizontal_speed", 0.0, 6.0),
        Axis("ships.initial.tilt_deg", 0.0, 15.0)]
sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)
cases = range(0, 300, 15)
for c in cases:
    list(run(sw.case_scenario(c)))
print("a touchdown   (call, caller, line)")
for key, n in sorted(counts.items(), key=lambda kv: -kv[1]):
    print(f"{n / len(cases):10.1f}   {key}")
