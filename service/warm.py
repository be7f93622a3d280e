"""A worker's compiled code made ready before it takes a shard (issue 34).

The step, the flight log's encoder and the autopilot's terrain function are numba kernels: the
first call of each in a process compiles it (15-30 s on a fresh install) or loads it from the
cache on disk (``sim.compiled.cache_dir``: ``$NUMBA_CACHE_DIR/touchdown-kernels-<hash>``, else
beside the sources, else ``~/.cache/touchdown``). A worker that took its leases first stalled the
shards it took for that long (its first tick came 31.7 s after it took them on a fresh install).
:func:`warm` runs one small shard of the service's own scene through the same path a tick takes
(requests, the autopilot, the step, the flight log written and read back, telemetry) in a
temporary folder, before the worker takes any lease; ``touchdown serve --warm-only`` does only
that and exits, for an image's build step (docs/SERVICE.md, "A worker's compiled code").
"""
from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

from touchdown.service.commands import Request
from touchdown.service.flightlog import ServiceLog
from touchdown.service.shard import Shard
from touchdown.service.telemetry import TelemetryEncoder
from touchdown.sim.compiled import cache_dir
from touchdown.sim.world import World

TICKS = 40  # enough for a ship dropped 0.5 m to touch, bounce and settle: every phase's code


def warm(scene, dt_s: float, body: str) -> float:
    """Run a two-ship shard of ``scene`` (on ``body``) for TICKS ticks with its flight log (in a
    temporary folder, removed): every kernel a worker's tick calls is compiled or loaded.
    Returns the seconds it took."""
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="touchdown-warm-") as tmp:
        world = World.empty(scene)
        shard = Shard(0, world, None, body, streams=("warm", "warm"))
        shard.log = ServiceLog(Path(tmp), lambda: shard.world, lambda line: None,
                               prefix="warm", keyframe_interval=10, max_bytes=1 << 20,
                               name="warm", source="warm")
        shard.log.start()
        table = json.dumps({"initial": {"altitude": 0.5, "vertical_speed": -1.0}})
        requests = [Request("0-1", "spawn", "warm-a", {"ship": {"id": "warm-a",
                                                                "player_id": "warm",
                                                                **json.loads(table)}},
                            "warm"),
                    Request("0-2", "spawn", "warm-b", {"ship": {"id": "warm-b",
                                                                "player_id": "warm",
                                                                "initial": {"altitude": 30.0}}},
                            "warm")]
        tele = TelemetryEncoder()
        for i in range(TICKS):
            if i == 1:
                requests = [Request("0-3", "autoland", "warm-b", {}, "warm")]
            out = shard.step(requests)
            requests = []
            for b in out.blocks:
                if b.ship_ids:
                    tele.encode(b.states[-1], b.outputs[-1], b.ship_ids, b.last_tick, dt_s, 0,
                                0, 1)
        shard.log.close(complete=True, reason="stopped")
    return time.perf_counter() - t0


def where() -> str:
    """Where the compiled kernels are kept (sim.compiled.cache_dir)."""
    return str(cache_dir())
