"""Where the CPU of ``bench/mujoco_side.py``'s fleet with its full log goes, piece by piece.

The fleet of bench/mujoco_side.py (10,000 landers arriving at 2-49 m/s from 0.5-30 m, 20 ticks
of 0.05 s) recorded as ``touchdown record`` does (service.driver.record), each piece's CPU time
taken on the thread that runs it (``time.thread_time``: the step and the events on the caller's
thread; the encoding, compression, CRCs and writes on the writer's), and the whole run's CPU
(``time.process_time``, every thread: what mujoco_side times). The pieces are timed by wrapping
the functions that do them: the wrappers add a few microseconds a call (a few hundred calls a
run). ``python -m touchdown.bench.fleet_log_parts [ships] [ticks] [runs]``.
"""
from __future__ import annotations

import collections
import os
import statistics
import sys
import tempfile
import time

import numpy as np

#: piece -> CPU seconds this run (reset by each run)
_CPU: dict[str, float] = collections.defaultdict(float)
_CALLS: dict[str, int] = collections.defaultdict(int)
_BYTES: dict[str, int] = collections.defaultdict(int)


def _timed(name: str, fn, count_bytes: bool = False):
    def wrapper(*args, **kwargs):
        t0 = time.thread_time()
        try:
            return fn(*args, **kwargs)
        finally:
            _CPU[name] += time.thread_time() - t0
            _CALLS[name] += 1
            if count_bytes and args:
                _BYTES[name] += memoryview(args[0]).nbytes
    wrapper.__wrapped__ = fn
    return wrapper


class _TimedStream:
    """A file whose writes are timed (the writer's stream)."""

    def __init__(self, f):
        self._f = f

    def write(self, data):
        t0 = time.thread_time()
        try:
            return self._f.write(data)
        finally:
            _CPU["write (file)"] += time.thread_time() - t0
            _CALLS["write (file)"] += 1
            _BYTES["write (file)"] += memoryview(data).nbytes

    def __getattr__(self, name):
        return getattr(self._f, name)


def fleet_scenario(n_ships: int, n_ticks: int):
    """bench/mujoco_side.py's touchdown_fleet scenario."""
    from touchdown.sim.scenario import parse
    rng = np.random.default_rng(7)
    ships = [{"id": f"s{i}", "initial": {"altitude": float(h), "vertical_speed": -float(v),
                                         "east": float(10.0 * i)}}
             for i, (h, v) in enumerate(zip(rng.uniform(0.5, 30.0, n_ships),
                                            rng.uniform(2.0, 49.0, n_ships)))]
    return parse({"name": "arrivals", "duration": n_ticks * 0.05, "ships": ships}, "bench")


class _Wrapped:
    """Stands in for a module inside ``mcap.writer`` (zstandard, zlib: logs.encode's stand-ins),
    its ``name`` function timed."""

    def __init__(self, module, name: str, label: str):
        self._module = module
        setattr(self, name, _timed(label, getattr(module, name), count_bytes=True))

    def __getattr__(self, name):
        return getattr(self._module, name)


_DONE: list[bool] = []


def _instrument() -> None:
    """Wrap the pieces (once)."""
    import mcap.writer

    from touchdown.logs import encode_block, encode_events, header, writer
    from touchdown.sim import world

    if _DONE:
        return
    _DONE.append(True)
    world.World.of = classmethod(_timed("World.of (caller)", world.World.of.__func__))
    header.scenario_message = _timed("header: scenario_message (caller)",
                                     header.scenario_message)
    world.World.blocks = _timed_generator("step (caller)", world.World.blocks)
    world.World.first_block = _timed("first_block (caller)", world.World.first_block)
    writer.event_messages = _timed("events (caller)", encode_events.event_messages)
    writer.LogWriter.write_block_serialized = _timed(
        "write_block total (caller)", writer.LogWriter.write_block_serialized)
    writer.LogWriter.close = _timed("close (caller)", writer.LogWriter.close)
    encode_block.BlockEncoder.encode = _timed("encode ticks (writer)",
                                              encode_block.BlockEncoder.encode)
    # (the writer's thread runs the method its constructor looks up: the wrapped one)
    writer.LogWriter._drain = _timed("writer thread total", writer.LogWriter._drain)
    writer.LogWriter._write_encoded = _timed("write_encoded (writer)",
                                             writer.LogWriter._write_encoded)
    # every chunk's compression and CRC goes through these (logs.encode's stand-ins)
    mcap.writer.zstandard = _Wrapped(mcap.writer.zstandard, "compress", "zstd compress")
    mcap.writer.zlib = _Wrapped(mcap.writer.zlib, "crc32", "crc32")
    real_open = open

    def opened(path, mode="r", *args, **kwargs):
        f = real_open(path, mode, *args, **kwargs)
        return _TimedStream(f) if "w" in mode and str(path).endswith(".partial") else f
    writer.open = opened


def _timed_generator(name: str, fn):
    def wrapper(*args, **kwargs):
        gen = fn(*args, **kwargs)
        while True:
            t0 = time.thread_time()
            try:
                item = next(gen)
            except StopIteration:
                _CPU[name] += time.thread_time() - t0
                return
            _CPU[name] += time.thread_time() - t0
            _CALLS[name] += 1
            yield item
    return wrapper


def one_run(scn, path: str, keyframe_interval: int = 1) -> dict[str, float]:
    from touchdown.service.driver import record
    _CPU.clear()
    _CALLS.clear()
    _BYTES.clear()
    t0w, t0p, t0t = time.perf_counter(), time.process_time(), time.thread_time()
    record(scn, path, "bench", keyframe_interval=keyframe_interval)
    out = dict(_CPU)
    out["whole run, every thread (process_time)"] = time.process_time() - t0p
    out["whole run, caller's thread"] = time.thread_time() - t0t
    out["whole run, wall"] = time.perf_counter() - t0w
    out["_bytes_zstd_in"] = _BYTES["zstd compress"]
    out["_bytes_file"] = os.path.getsize(path)
    return out


def stepping_alone(scn) -> float:
    """CPU seconds of the run stepped alone (bench/mujoco_side.py's "stepping alone")."""
    from touchdown.sim.run import run_blocks
    t0 = time.process_time()
    for _ in run_blocks(scn):
        pass
    return time.process_time() - t0


def main(n_ships: int = 10_000, n_ticks: int = 20, runs: int = 5, keyframe_interval: int = 1,
         zstd_level: int | None = None) -> None:
    """Print the table. ``zstd_level``: the chunks' (logs.encode.DEFAULT_ZSTD_LEVEL if None)."""
    from touchdown.logs import encode
    from touchdown.sim.run import run_blocks
    if zstd_level is not None:
        encode.DEFAULT_ZSTD_LEVEL = zstd_level
    scn = fleet_scenario(n_ships, n_ticks)
    next(iter(run_blocks(scn, last_tick=1)))
    stepped = [stepping_alone(scn) for _ in range(runs)]
    _instrument()
    ship_ticks = n_ships * n_ticks
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "bench.mcap")
        one_run(scn, path, keyframe_interval)  # warm
        got = [one_run(scn, path, keyframe_interval) for _ in range(runs)]
    for g, st in zip(got, stepped):
        g["stepping alone (run_blocks, no log), every thread"] = st
    print(f"{n_ships:,} ships, {n_ticks} ticks (+ tick 0), {runs} runs, keyframe every "
          f"{keyframe_interval}, zstd level {encode.DEFAULT_ZSTD_LEVEL}; load "
          f"{os.getloadavg()[0]:.2f}; CPU µs a ship-tick (median, min), ms a run (median)")
    keys = sorted({k for g in got for k in g if not k.startswith("_")},
                  key=lambda k: -statistics.median(g.get(k, 0.0) for g in got))
    for k in keys:
        xs = [g.get(k, 0.0) for g in got]
        print(f"  {k:44s} {statistics.median(xs) / ship_ticks * 1e6:7.3f} "
              f"{min(xs) / ship_ticks * 1e6:7.3f}   {statistics.median(xs) * 1e3:8.1f} ms")
    print(f"  zstd input {got[-1]['_bytes_zstd_in'] / ship_ticks:.0f} B a ship-tick, file "
          f"{got[-1]['_bytes_file'] / ship_ticks:.1f} B a ship-tick "
          f"({got[-1]['_bytes_file'] / 1e6:.1f} MB)")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))
