"""Page faults and CPU of one sweep part of N cases (one chunk, as a worker steps it), with
glibc's defaults or (``keep``) with service.memory.keep_freed_memory (session 27 helper sweep).

    python docs/issue36/tools/sweep27_faults.py N_CASES [keep]
"""
import resource
import sys
import time
import tomllib

import numpy as np

from touchdown import scenarios
from touchdown.sweep import fleet as F
from touchdown.sweep.cases import Axis, Sweep

n = int(sys.argv[1])
if len(sys.argv) > 2 and sys.argv[2] == "keep":
    from touchdown.service.memory import keep_freed_memory
    print("keep_freed_memory", keep_freed_memory())
doc = tomllib.loads(scenarios.text("envelope"))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
        Axis("ships.initial.horizontal_speed", 0.0, 6.0),
        Axis("ships.initial.tilt_deg", 0.0, 15.0)]
sw = Sweep.of(doc, "envelope", axes, samples=n, seed=1)
F.run_part(sw, [0])
r0 = resource.getrusage(resource.RUSAGE_SELF)
t0 = time.perf_counter()
cols = F.run_part(sw, np.arange(n))
t1 = time.perf_counter()
r1 = resource.getrusage(resource.RUSAGE_SELF)
print(f"{n} cases: user {r1.ru_utime - r0.ru_utime:.2f} s, sys {r1.ru_stime - r0.ru_stime:.2f} s, "
      f"wall {t1 - t0:.2f} s, minor faults {r1.ru_minflt - r0.ru_minflt}, "
      f"max RSS {r1.ru_maxrss / 1024:.0f} MB")
