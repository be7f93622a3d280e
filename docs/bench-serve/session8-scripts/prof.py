"""Run `cli serve` in-process against a redis URL with a bench fleet; after WARM ticks reset
the phase sums and (optionally) cProfile the loop; print steady per-tick phases (loop CPU)."""
import sys, json, time, os, cProfile, pstats, tempfile, uuid, io
url, n, ticks, warm, mode = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
os.sched_setaffinity(0, {0})
from touchdown.bench import serve as bs
from touchdown.service import serve as sv
prefix = f"bench:prof:{uuid.uuid4().hex[:8]}"
bs._config(url, prefix, n, 4)
orig = sv.Worker.loop_once
st = {"i": 0, "prof": None, "t0": None}
def loop_once(self):
    st["i"] += 1
    if st["i"] == warm + 1:
        self.stats.phases.clear()
        st["c0"] = time.thread_time(); st["p0"] = time.process_time(); st["w0"] = time.perf_counter()
        if mode == "prof":
            st["prof"] = cProfile.Profile(time.thread_time); st["prof"].enable()
    orig(self)
    if st["i"] == ticks:
        if st["prof"]: st["prof"].disable()
        st["c1"] = time.thread_time(); st["p1"] = time.process_time()
        st["ph"] = {k: list(v) for k, v in self.stats.phases.items()}
        st["worker"] = self
sv.Worker.loop_once = loop_once
from touchdown.cli import main
with tempfile.TemporaryDirectory() as tmp:
    try:
        main(["serve", "--redis", url, "--prefix", prefix, "--rate", "10", "--ticks", str(ticks),
              "--log-dir", tmp + "/flight", "--shards", "4", "--worker-id", "w0"], standalone_mode=False)
    finally:
        bs._cleanup(url, prefix)
m = ticks - warm
print(f"N={n} steady ticks={m}: loop CPU {(st['c1']-st['c0'])/m*1e3:.2f} ms/tick "
      f"({(st['c1']-st['c0'])/m/n*1e6:.3f} us/ship-tick); process CPU {(st['p1']-st['p0'])/m*1e3:.2f} ms/tick "
      f"({(st['p1']-st['p0'])/m/n*1e6:.3f} us/ship-tick)")
print("  phases ms/tick cpu(wall): " + ", ".join(f"{k} {v[1]/m*1e3:.2f}({v[0]/m*1e3:.2f})" for k, v in sorted(
    st["ph"].items(), key=lambda kv: -kv[1][1])))
if st["prof"]:
    s = io.StringIO(); ps = pstats.Stats(st["prof"], stream=s); ps.sort_stats("tottime").print_stats(35); ps.print_callees("write_block"); ps.print_callees("_rotate_if|LogWriter.write_block|_space_ok")
    print(s.getvalue())
