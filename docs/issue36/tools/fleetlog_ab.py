"""One A/B sample: MuJoCo's fleet and Touchdown's fleet with its full log, as mujoco_side times
them (CPU time, every thread; least of 3), in this process."""
import json, os, sys, tempfile, time
import touchdown
from touchdown.bench import mujoco_side as m
label = sys.argv[1]
with tempfile.TemporaryDirectory() as tmp:
    mj = m.mujoco_fleet(10000, 100)
    td = m.touchdown_fleet(10000, 20, log_dir=tmp)
    size = os.path.getsize(os.path.join(tmp, "bench.mcap"))
print(json.dumps({"label": label, "src": os.path.dirname(touchdown.__file__), "mujoco": mj,
                  "touchdown_log": td, "ratio": td / mj, "us_per_ship_tick": 1e6 / td,
                  "file_mb": size / 1e6, "load1": os.getloadavg()[0],
                  "utc": time.strftime("%H:%M:%S", time.gmtime())}), flush=True)
