# session 16 (serve): the block encoder's variants side by side: CPU a tick (min of reps) and the bytes
# against the first's. usage: PY serve16_gx.py SHIPS TICKS REPS orig,variant1,...  (variantN = the
# file /tmp/serve-x/eb/variantN.py, a copy of logs/encode_block.py with a change; orig = the tree's)
import sys, time, importlib.util, os
import numpy as np
n, K, reps = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]); Gs = sys.argv[4].split(",")
from touchdown.bench.speed import fleet_doc
from touchdown.sim.scenario import parse
from touchdown.sim.world import World
from touchdown.sim.state import STATE_DTYPE, OUTPUTS_DTYPE, INPUTS_DTYPE
import touchdown.logs.writer as lw
import touchdown.logs.encode_block as eb0
print("record bytes", STATE_DTYPE.itemsize, OUTPUTS_DTYPE.itemsize, INPUTS_DTYPE.itemsize, flush=True)
doc = fleet_doc(n, 3600.0); doc["sim"] = {"dt": 0.1}
w = World.of(parse(doc, "x")); w.first_block()
blocks = []
for t in range(K):
    blocks.extend(w.blocks(w.tick + 1))
keys = np.arange(n, dtype=np.int64)
src = open(os.environ.get("SRC", eb0.__file__)).read()
ref = None
for G in Gs:
    s = open(eb0.__file__ if G == "orig" else f"/tmp/serve-x/eb/{G}.py").read()
    G = G + str(len(ref or []) and Gs.index(G))
    p = f"/tmp/serve-x/eb/eb_{G}_{os.getpid()}.py"
    open(p, "w").write(s)
    spec = importlib.util.spec_from_file_location(f"eb_g{G}", p); m = importlib.util.module_from_spec(spec); spec.loader.exec_module(m)
    enc = m.BlockEncoder(0.1, lw.KEYFRAME_ONLY, 10)
    t0 = time.time(); enc.encode(blocks[0].first_tick, blocks[0].states, blocks[0].outputs, blocks[0].inputs, keys); tc = time.time() - t0
    best = [1e9] * K; outs = []
    for r in range(reps):
        for k, b in enumerate(blocks):
            c0 = time.thread_time(); o = enc.encode(b.first_tick, b.states, b.outputs, b.inputs, keys, room=32); best[k] = min(best[k], time.thread_time() - c0)
            if r == 0: outs.append(bytes(o[0][o[1][0]:o[1][-1]]))
    same = "ref" if ref is None else ("same bytes" if outs == ref else "DIFFERENT BYTES")
    ref = ref or outs
    print(f"{G:10s} encode {sum(best)/K*1e3:.3f} ms a tick, {sum(best)/K/n*1e9:.1f} ns a ship-tick (compile {tc:.0f} s) {same} load {os.getloadavg()[0]:.1f}", flush=True)
