import numpy as np
from touchdown.bench.speed import fleet_doc
from touchdown.sim.scenario import parse
from touchdown.sim.world import World
from touchdown.logs.encode_block import BlockEncoder
from touchdown.logs.header import KEYFRAME_ONLY
n = 3000
doc = fleet_doc(n, 3600.0); doc["sim"] = {"dt": 0.1}
w = World.of(parse(doc, "x"))
enc = BlockEncoder(0.1, KEYFRAME_ONLY, 10)
keys = np.arange(n, dtype=np.int64)
for b in list(w.blocks(20))[:1]:
    pass
sizes = []
for t in range(20):
    for b in w.blocks(w.tick + 1):
        d, o = enc.encode(b.first_tick, b.states, b.outputs, b.inputs, keys)
        sizes.append((b.first_tick, (o[1]-o[0])/n))
print(sizes)
