"""Session 26 (helper `events`): the service's Redis event entries, as the shard makes them
(service.shard.Shard.step: logged, and with its log paused: service.flightlog.events_of), for
600 landers arriving with long and unicode ship and player ids, 60 ticks; printed as a digest
and written to the file given (a pickle), to compare two commits' entries (no Redis needed):

    .venv/bin/python docs/issue36/tools/session26_entries.py /tmp/entries-COMMIT.pkl
"""
import hashlib
import pickle
import sys
import tempfile
from pathlib import Path

import numpy as np

from touchdown.service.flightlog import ServiceLog
from touchdown.service.shard import Shard
from touchdown.sim.scenario import parse
from touchdown.sim.world import World


def doc(n: int) -> dict:
    rng = np.random.default_rng(11)
    ships = []
    for i, (h, v) in enumerate(zip(rng.uniform(0.5, 30.0, n), rng.uniform(2.0, 49.0, n))):
        ship = {"id": f"s{i}" if i % 3 else f"лэндер-{i}-{'ü' * (i % 200)}",
                "initial": {"altitude": float(h), "vertical_speed": -float(v),
                            "east": float(10.0 * i), "tilt_deg": float(i % 7),
                            "horizontal_speed": float(i % 5)}}
        if i % 4 == 1:
            ship["player_id"] = f"игрок-{i % 13}-🚀" + "p" * (i % 150)
        ships.append(ship)
    return {"name": "arrivals", "duration": 10.0, "ships": ships}


def entries(paused: bool) -> list:
    world = World.of(parse(doc(600), "entries"))
    tmp = Path(tempfile.mkdtemp())
    where = tmp / "file-not-dir" if paused else tmp / "logs"
    if paused:
        where.write_bytes(b"")  # (a file where the directory would be: the log pauses)
    log = ServiceLog(where, lambda: world, lambda *a: None, prefix="s0", keyframe_interval=10,
                     max_bytes=1 << 30, name="entries", source="entries", retry_s=1e9)
    log.start()
    shard = Shard(0, world, log, world.params.body.name)
    got = []
    for _ in range(60):
        out = shard.step([])
        got += [e.fields for e in out.entries]
    log.close()
    return got


both = {"logged": entries(False), "paused": entries(True)}
for k, v in both.items():
    # (the digest of the entries' fields in order, by value: pickle's bytes depend on which
    # strings are the same object)
    print(k, len(v), "entries,", sum(1 for e in v if "proto" in e), "events, sha256",
          hashlib.sha256(repr([list(e.items()) for e in v]).encode()).hexdigest()[:16])
if len(sys.argv) > 1:
    Path(sys.argv[1]).write_bytes(pickle.dumps(both))
