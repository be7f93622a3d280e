"""separate.py TREEDIR: a profiling copy (edits TREEDIR in place: run it on a tree.sh copy): ~25
kernels made calls of their own (sim.compiled.separate), so that callgrind (jit.sh) counts each
one's instructions and calls; its code is not the shipped one (calls cost ~70% more a tick), so
read it for shares and calls, not for totals."""
import re, sys
T = sys.argv[1]
targets = {"flight.py": ["slip_rates", "dragged_feet", "stiff_feet", "guard_substep", "passivity_guard",
                         "in_flight_transitions", "coarse_tick", "memo_at", "with_stopping", "stopping",
                         "at_transition", "foot_events", "ship_energy_at", "holds"],
           "dynamics.py": ["contact_inline", "derivatives_held", "derivatives", "held_friction"],
           "contact.py": ["geometry", "feet"], "rest.py": ["settle_sample"],
           "integrators.py": ["rk4_held"],
           "friction.py": ["_dragged_only", "spread_over_step", "hold_footprint", "coulomb", "seed"]}
for f, names in targets.items():
    p = f"{T}/sim/{f}"
    s = open(p).read()
    for n in names:
        s = re.sub(r"@kernel\n(def %s\()" % n, r"@separate\n\1", s)
    s = s.replace("from touchdown.sim.compiled import kernel\n",
                  "from touchdown.sim.compiled import kernel, separate\n", 1)
    if "separate" not in s.split("def ")[0]:
        s = s.replace("from touchdown.sim.compiled import kernel,", "from touchdown.sim.compiled import separate, kernel,", 1)
    open(p, "w").write(s)
