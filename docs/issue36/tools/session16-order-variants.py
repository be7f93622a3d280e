import sys, time
sys.path.insert(0, "/tmp/order-x/cols")
from envelope_columns import run
V = {"rk4": {}, "midP": {"strike_method": "midpoint"}, "midT": {"strike_method": "midpoint", "strike_scope": "ticks"},
     "heunT": {"strike_method": "heun", "strike_scope": "ticks"}, "rk3T": {"strike_method": "rk3", "strike_scope": "ticks"},
     "heunP": {"strike_method": "heun"}, "rk3P": {"strike_method": "rk3"}}
for name in sys.argv[1:]:
    t = time.process_time()
    run(f"/tmp/order-x/cols/{name}.npz", V[name])
    print(name, "cpu", round(time.process_time() - t, 2), flush=True)
