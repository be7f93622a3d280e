"""Session 26 (helper `events`): what a transition event costs, before and after
logs.encode_events. Run from a worktree's venv on either commit:

    .venv/bin/python docs/issue36/tools/session26_events.py

1. isolated: the bench's 10,000 landers arriving at 2-49 m/s (bench.mujoco_side's fleet), 1 s
   (20 one-tick blocks, 12,950 events), stepped once; then each block's events made again and
   again: event_message(...).SerializeToString() one by one (protobuf's objects, the path before),
   and, where the module exists, logs.encode_events.event_messages with and without the writer's
   keys. Best of 5, CPU us an event.
2. in context: `touchdown record` of that fleet (service.driver.record), best of 4: the whole
   process's CPU (every thread) per ship-tick, and the recording thread's time inside
   LogWriter.write_block_serialized (the caller's side of the log: joins, commands, events, the
   queue) per event.
"""
import os
import tempfile
import time

import numpy as np

from touchdown.logs import header as H
from touchdown.logs import writer as W
from touchdown.service.driver import record
from touchdown.sim.scenario import parse
from touchdown.sim.state import State
from touchdown.sim.world import World

N_SHIPS = 10_000
rng = np.random.default_rng(7)
ships_doc = [{"id": f"s{i}", "initial": {"altitude": float(h), "vertical_speed": -float(v),
                                         "east": float(10.0 * i)}}
             for i, (h, v) in enumerate(zip(rng.uniform(0.5, 30.0, N_SHIPS),
                                            rng.uniform(2.0, 49.0, N_SHIPS)))]
scn = parse({"name": "arrivals", "duration": 1.0, "ships": ships_doc}, "bench")

w = World.of(scn)
table = H.ShipTable(w.ship_ids, list(w.params.ships.player_id))
body, dt = w.params.body.name, w.params.sim.dt_s
blocks = [b for b in w.blocks(20) if b.events]
E = sum(len(b.events) for b in blocks)


def best(f, n=5):
    out = []
    for _ in range(n):
        t0 = time.process_time()
        f()
        out.append(time.process_time() - t0)
    return min(out) / E * 1e6


def protobuf():
    for b in blocks:
        for ev in b.events:
            H.event_message(table, body, dt, State(rows=b.states[ev.tick - b.first_tick],
                                                   tick=ev.tick), ev).SerializeToString()


print(f"isolated: {E} events in {len(blocks)} blocks of {N_SHIPS} ships")
print(f"  event_message + SerializeToString: {best(protobuf):6.2f} us an event")
try:
    from touchdown.logs.encode_events import event_messages
except ImportError:
    event_messages = None
if event_messages is not None:
    keys = table.keys(blocks[0].ship_ids)

    def written(with_keys):
        def go():
            for b in blocks:
                event_messages(table, body, dt, b.states, b.first_tick, b.events,
                               keys=keys if with_keys else None)
        go()  # (compiled code loaded)
        return go
    print(f"  encode_events, the writer's keys:   {best(written(True)):6.2f} us an event")
    print(f"  encode_events, ids from the events: {best(written(False)):6.2f} us an event")

acc = [0.0, 0]
orig = W.LogWriter.write_block_serialized


def timed(self, block):
    t0 = time.thread_time()
    got = orig(self, block)
    acc[0] += time.thread_time() - t0
    acc[1] += len(got[0])
    return got


W.LogWriter.write_block_serialized = timed
d = tempfile.mkdtemp()
record(scn, os.path.join(d, "b.mcap"), "bench")  # (compiled code loaded)
runs = []
for _ in range(4):
    acc[:] = [0.0, 0]
    t0 = time.process_time()
    record(scn, os.path.join(d, "b.mcap"), "bench")
    runs.append((time.process_time() - t0, acc[0], acc[1]))
cpu, caller, events = min(runs)
print(f"in context (touchdown record, best of 4): {cpu / (N_SHIPS * 20) * 1e6:.3f} us CPU a "
      f"ship-tick (every thread); write_block_serialized's thread time {caller * 1e3:.1f} ms = "
      f"{caller / events * 1e6:.2f} us an event ({events} events)")
