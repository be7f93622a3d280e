"""Session 36: what a flight-log rotation costs the service's loop thread (the caller of
RotatingLog.write_block), and the bytes of a rotated run (to prove a change leaves them alone).

    python session36_rotation.py time SHIPS [ROTATIONS] [CHURN]
    python session36_rotation.py bytes [SHIPS]

``time``: bench serve's fleet (bench.speed.fleet_doc, dt 0.1 s: the service's tick) of SHIPS
ships, stepped a tick at a time and written to a RotatingLog as a live shard writes it (open
ended, keyframes every 10 ticks, zstd -8, the live queue, the headers' tables given as
service.serve's _header_tables makes them), its bound small enough that it rotates ROTATIONS
times; CHURN ships join and as many leave every tick (0: a fixed fleet). Each rotation: the
caller's wall ms (rotating_s's delta), split by what _rotate and _open call (perf_counter
around each, wrapped in logs.rotating's namespace); and the caller's wall ms of the next block
that has events (a new file's first: its event encoder's ids, logs.encode_events), against the
median of the blocks that are neither.

``bytes``: a small fleet with joins, leaves, commands and events, every block a file of its own
(``max_bytes=1``: where a file ends does not hang on the writer's thread), each file's sha256
and one over all; the same before and after a change means the same bytes.
"""
from __future__ import annotations

import hashlib
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import touchdown.logs.rotating as rot
from touchdown.bench.speed import fleet_doc
from touchdown.logs.encode import ShipTables
from touchdown.logs.header import header_table
from touchdown.logs.writer import LIVE_QUEUE_BLOCKS, QUEUE_BYTES, LogWriter
from touchdown.sim.scenario import parse
from touchdown.sim.world import World

#: piece -> caller's wall seconds in the rotation being timed
_SPLIT: dict[str, float] = {}
_IN_ROTATION = [False]


def _timed(name: str, fn):
    def wrapper(*args, **kwargs):
        if not _IN_ROTATION[0]:
            return fn(*args, **kwargs)
        t0 = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            _SPLIT[name] = _SPLIT.get(name, 0.0) + time.perf_counter() - t0
    return wrapper


#: a cProfile.Profile of every rotation and every new file's first block with events, if asked
_PROFILE: list = []


def _instrument() -> None:
    for name in ("world_header_later", "world_record_later"):  # (before, after the change)
        if hasattr(rot, name):
            setattr(rot, name, _timed("header", getattr(rot, name)))
    rot.ShipTable = _timed("ShipTable(ids, players)", rot.ShipTable)
    rot.Block = _timed("keyframe Block copy", rot.Block)
    LogWriter.__init__ = _timed("LogWriter.__init__", LogWriter.__init__)
    LogWriter.write_block = _timed("new writer.write_block(keyframe)", LogWriter.write_block)
    LogWriter.close = _timed("old writer.close(wait=False)", LogWriter.close)
    whole = rot.RotatingLog._rotate

    def rotate(self, world, block):
        _IN_ROTATION[0] = True
        if _PROFILE:
            _PROFILE[0].enable()
        try:
            return whole(self, world, block)
        finally:
            if _PROFILE:
                _PROFILE[0].disable()
            _IN_ROTATION[0] = False
    rot.RotatingLog._rotate = rotate


def machine() -> str:
    out = subprocess.run(["lscpu"], capture_output=True, text=True).stdout
    model = next((ln.split(":", 1)[1].strip() for ln in out.splitlines()
                  if ln.startswith("Model name")), "?")
    cpus = next((ln.split(":", 1)[1].strip() for ln in out.splitlines()
                 if ln.startswith("CPU(s)")), "?")
    load = open("/proc/loadavg").read().split()[:3]
    return f"{model}, {cpus} CPUs, load {' '.join(load)}, Python {sys.version.split()[0]}"


def fleet_world(n: int) -> World:
    doc = fleet_doc(n, 3600.0)
    doc["sim"] = {"dt": 0.1}
    return World.of(parse(doc, "session36"))


def service_tables(world: World) -> ShipTables:
    """The headers' tables as service.serve's _header_tables makes them (the scene's ships)."""
    tables = ShipTables()
    for sid in world.ship_ids:
        tables[sid] = header_table(world.known[sid])
    return tables


def time_rotations(n: int, rotations: int, churn: int) -> None:
    _instrument()
    t0 = time.perf_counter()
    world = fleet_world(n)
    print(f"{machine()}\n{n} ships (built in {time.perf_counter() - t0:.1f} s), churn {churn} "
          f"joins + {churn} leaves a tick", flush=True)
    with tempfile.TemporaryDirectory(dir=".") as d:
        # about 8 ticks a file (~110 bytes a ship-tick at zstd -8, keyframes 1 in 10)
        log = rot.RotatingLog(d, world, prefix="s36", keyframe_interval=10,
                              max_bytes=n * 110 * 8, name="session36", source="serve",
                              open_ended=True, zstd_level=-8,
                              queue=(LIVE_QUEUE_BLOCKS, QUEUE_BYTES),
                              tables=service_tables(world), drop_cache=True)
        log.write_block(world.first_block())
        rows, plain, after, cpus = [], [], [], []
        joined = 0
        pending_after = False
        while len(rows) < rotations:
            if churn and world.tick > 0:
                ids = world.ship_ids
                for j in range(churn):
                    world.retire(ids[(world.tick * churn + j) * 7 % len(ids)])
                    world.spawn({"id": f"new-{joined:06d}", "initial": {
                        "altitude": 10.0 + j, "vertical_speed": -20.0,
                        "east": 30.0 * joined}})
                    joined += 1
            for block in world.blocks(world.tick + 1):
                files, r0 = len(log.files), log.rotating_s
                _SPLIT.clear()
                c0, u0 = time.perf_counter(), time.thread_time()
                log.write_block(block)
                wall, cpu = time.perf_counter() - c0, time.thread_time() - u0
                if len(log.files) != files:
                    took = log.rotating_s - r0
                    cpus.append(cpu)
                    _SPLIT["rest (keyframe arrays, _path, ...)"] = took - sum(_SPLIT.values())
                    rows.append((len(log.files), block.last_tick, took, dict(_SPLIT)))
                    pending_after = True
                elif pending_after and block.events:
                    after.append(wall)
                    pending_after = False
                elif not pending_after:
                    plain.append(wall)
        log.close()
        print(f"{len(log.files)} files, {log.event_count} events; caller's wall ms a block "
              f"(no rotation, not a new file's first with events): median "
              f"{statistics.median(plain) * 1e3:.2f} (n={len(plain)})")
    print("rotation  tick   rotating ms   " + "  ".join(
        f"{k}" for k in sorted(rows[0][3])))
    for files, tick, s, split in rows:
        print(f"  file {files:2d} at {tick:4d}: {s * 1e3:7.2f}   " + "  ".join(
            f"{k} {v * 1e3:.2f}" for k, v in sorted(split.items())))
    ms = [s * 1e3 for _, _, s, _ in rows]
    print(f"rotation ms: median {statistics.median(ms):.2f}, min {min(ms):.2f}, "
          f"max {max(ms):.2f}; the caller's CPU in the rotating block's write_block "
          f"(thread_time: no GIL waits): median {statistics.median(cpus) * 1e3:.2f} ms")
    if after:
        am = [a * 1e3 for a in after]
        print(f"a new file's first block with events: median {statistics.median(am):.2f} ms, "
              f"max {max(am):.2f} (n={len(am)}; median block "
              f"{statistics.median(plain) * 1e3:.2f})")


def digest_run(n: int = 300) -> list[tuple[str, str]]:
    """(file name, sha256) of each file of a rotated run with joins, leaves, commands, events."""
    world = fleet_world(n)
    with tempfile.TemporaryDirectory(dir=".") as d:
        log = rot.RotatingLog(d, world, prefix="b", keyframe_interval=4, max_bytes=1,
                              name="session36", source="serve", open_ended=True,
                              zstd_level=-8, tables=service_tables(world), keyframe_phase=1)
        log.write_block(world.first_block())
        joined = 0
        for t in range(1, 40):
            if t % 3 == 0:  # a file with ships joined, one with ships gone
                world.spawn({"id": f"j{joined}", "player_id": f"p{joined % 2}",
                             "initial": {"altitude": 5.0, "vertical_speed": -9.0}})
                joined += 1
            if t % 5 == 0:
                world.retire(world.ship_ids[t])
            if t % 4 == 0:
                world.command(world.ship_ids[-1], 0.5)
            for block in world.blocks(t):
                log.write_block(block)
        log.close()
        print(f"{log.event_count} events, {joined} joined", file=sys.stderr)
        return [(p.name, hashlib.sha256(p.read_bytes()).hexdigest()) for p in log.files]


def main() -> None:
    if sys.argv[1] == "bytes":
        got = digest_run(int(sys.argv[2]) if len(sys.argv) > 2 else 300)
        for name, h in got:
            print(name, h)
        whole = hashlib.sha256("".join(h for _, h in got).encode()).hexdigest()
        print(f"{len(got)} files, all: {whole}")
        return
    if sys.argv[1] == "profile":
        import cProfile
        import pstats
        _PROFILE.append(cProfile.Profile())
        time_rotations(int(sys.argv[2]), int(sys.argv[3]) if len(sys.argv) > 3 else 6, 0)
        pstats.Stats(_PROFILE[0]).sort_stats("tottime").print_stats(25)
        return
    time_rotations(int(sys.argv[2]), int(sys.argv[3]) if len(sys.argv) > 3 else 6,
                   int(sys.argv[4]) if len(sys.argv) > 4 else 0)


if __name__ == "__main__":
    main()
