import sys, tomllib
import numpy as np
from touchdown import scenarios
from touchdown.sim._count import COUNTS
from touchdown.sweep.cases import Axis, Sweep
from touchdown.sweep.fleet import run_part
n = int(sys.argv[1])
doc = tomllib.loads(scenarios.text("envelope"))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
        Axis("ships.initial.horizontal_speed", 0.0, 6.0),
        Axis("ships.initial.tilt_deg", 0.0, 15.0)]
sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)
run_part(sw, [0])
COUNTS[:] = 0
run_part(sw, list(range(n)))
c = COUNTS / n
print("per touchdown over", n)
print("solve calls %.1f  dragged-only %.1f  rounds %.1f  disk_step %.1f iters %.1f" % (c[0], c[1], c[6], c[7], c[8]))
print("ipm solves %.2f steps %.2f ; from_carried tries %.2f accepted %.2f" % (c[2], c[3], c[4], c[5]))
for warm in (0, 1):
    for na in range(1, 5):
        b = 20 + 10 * warm + 2 * na
        print("GS converged warm=%d n=%d: solves %.2f sweeps %.2f" % (warm, na, c[b], c[b + 1]))
for na in range(1, 5):
    print("GS gave up n=%d: solves %.2f sweeps %.2f ; ipm n=%d solves %.2f steps %.2f" % (na, c[40 + na], c[45 + na], na, c[50 + na], c[55 + na]))
