# the writer's work a tick (LogWriter._take on the calling thread), min over reps per tick
import sys, time, tempfile, os
from pathlib import Path
n, K, reps = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
from touchdown.bench.speed import fleet_doc
from touchdown.sim.scenario import parse
from touchdown.sim.world import World
from touchdown.logs.header import scenario_message
from touchdown.logs.writer import LogWriter
import touchdown.logs.writer as lw
doc = fleet_doc(n, 3600.0); doc["sim"] = {"dt": 0.1}
scn = parse(doc, "x")
w = World.of(scn)
first = w.first_block()
blocks = []
for t in range(K):
    blocks.extend(w.blocks(w.tick + 1))
best = [1e9] * K
tmp = tempfile.mkdtemp()
for r in range(reps):
    wr = LogWriter(Path(tmp) / f"r{r}.mcap", scenario_message(scn, "x", keyframe_interval=10), zstd_level=-8)
    wr.write_block(first); wr.flush()
    keys = wr.ships.keys(first.ship_ids)
    for k, b in enumerate(blocks):
        inputs = wr._inputs(b)
        item = (b, keys, False, {}, inputs)
        c0 = time.thread_time()
        wr._take(item)
        best[k] = min(best[k], time.thread_time() - c0)
        wr.last_tick = b.last_tick
    wr.close(); os.unlink(Path(tmp) / f"r{r}.mcap")
print(f"{os.environ.get('TAG','')} writer per tick (min of {reps}): {sum(best)/K*1e3:.3f} ms, {sum(best)/K/n*1e9:.1f} ns a ship-tick")
