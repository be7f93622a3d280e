import sys, time
import numpy as np
n, K = int(sys.argv[1]), int(sys.argv[2])
from touchdown.bench.speed import fleet_doc
from touchdown.sim.scenario import parse
from touchdown.sim.world import World
from touchdown.logs.encode_block import BlockEncoder
from touchdown.logs.header import KEYFRAME_ONLY
import zstandard, zlib_ng.zlib_ng as zn
doc = fleet_doc(n, 3600.0); doc["sim"] = {"dt": 0.1}
w = World.of(parse(doc, "x"))
blocks = []
for t in range(K):
    blocks.extend(w.blocks(w.tick + 1))
enc = BlockEncoder(0.1, KEYFRAME_ONLY, 10)
keys = np.arange(n, dtype=np.int64)
b = blocks[0]; enc.encode(b.first_tick, b.states, b.outputs, b.inputs, keys)
for rep in range(3):
    c0 = time.thread_time(); outs = []
    for b in blocks:
        outs.append(enc.encode(b.first_tick, b.states, b.outputs, b.inputs, keys))
    c1 = time.thread_time()
    print(f"encode {(c1-c0)/K*1e3:.3f} ms a tick, {(c1-c0)/K/n*1e9:.1f} ns a ship; bytes/ship {sum(int(o[1][-1]) for o in outs)/K/n:.1f}")
for lvl in (-8, -20, -50, 1):
    z = zstandard.ZstdCompressor(level=lvl)
    c0 = time.thread_time(); tot = 0; raw = 0
    for d, off in outs:
        x = bytes(d[:off[-1]]); raw += len(x)
        tot += len(z.compress(x))
    c1 = time.thread_time()
    print(f"zstd {lvl}: {(c1-c0)/K*1e3:.3f} ms a tick (incl bytes copy) ratio {raw/tot:.2f}")
c0 = time.thread_time()
for d, off in outs: zn.crc32(d[:off[-1]])
print("crc", (time.thread_time()-c0)/K*1e3)
try:
    import lz4.frame
    c0 = time.thread_time(); tot = 0
    for d, off in outs: tot += len(lz4.frame.compress(bytes(d[:off[-1]])))
    print(f"lz4 {(time.thread_time()-c0)/K*1e3:.3f} ms ratio {raw/tot:.2f}")
except ImportError as e: print(e)
import resource
for rep in range(2):
    f0 = resource.getrusage(resource.RUSAGE_THREAD).ru_minflt
    c0 = time.thread_time()
    for b in blocks:
        o = enc.encode(b.first_tick, b.states, b.outputs, b.inputs, keys); del o
    c1 = time.thread_time()
    f1 = resource.getrusage(resource.RUSAGE_THREAD).ru_minflt
    print(f"encode (buffer freed) {(c1-c0)/K*1e3:.3f} ms a tick; faults a tick {(f1-f0)/K:.0f}")
