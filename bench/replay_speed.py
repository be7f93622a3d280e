"""Replay benchmark: ``touchdown bench replay [--quick]``.

* ``replay --verify`` speed as a fraction of ``record`` speed on the same log (same scene, same
  ticks; the verify re-simulates and compares every number).
* the time to verify the last 1,000 ticks of a 1,000,000-tick log recorded with keyframes every
  1,000 ticks (a seek through the MCAP chunk index to the nearest keyframe, then 1,000 ticks).
* what keyframes cost: file size and recording speed with keyframes every tick vs every 1,000.
"""
from __future__ import annotations

import os
import tempfile
import time

from touchdown import scenarios
from touchdown.bench.speed import machine
from touchdown.replay.verify import verify
from touchdown.service import driver
from touchdown.sim.scenario import parse_text


def record(path: str, n_ticks: int, keyframe_every: int = 1) -> float:
    scn = parse_text(scenarios.text("bounce"), "bounce", {"duration": n_ticks * 0.05})
    t0 = time.perf_counter()
    driver.record(scn, path, "bounce", keyframe_every)
    return time.perf_counter() - t0


def main(quick: bool = False) -> None:
    n = 5_000 if quick else 20_000
    big = 20_000 if quick else 1_000_000
    print(f"machine: {machine()}")
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "log.mcap")
        record(path, 10)  # the kernels compiled or loaded before anything is timed
        verify(path)
        t_rec = record(path, n)
        t0 = time.perf_counter()
        res = verify(path)
        t_ver = time.perf_counter() - t0
        assert res.identical, res.report()
        print(f"record {n:,} ticks: {n / t_rec:,.0f} ticks/s; replay --verify: {n / t_ver:,.0f} "
              f"ticks/s; verify / record speed = {t_rec / t_ver:.2f}")
        sparse = os.path.join(tmp, "sparse.mcap")
        t_sparse = record(sparse, n, keyframe_every=1000)
        print(f"keyframes every tick: {os.path.getsize(path) / 1e6:.2f} MB, {n / t_rec:,.0f} "
              f"ticks/s; every 1,000 ticks: {os.path.getsize(sparse) / 1e6:.2f} MB, "
              f"{n / t_sparse:,.0f} ticks/s")
        long_path = os.path.join(tmp, "long.mcap")
        t_long = record(long_path, big, keyframe_every=1000)
        print(f"recorded a {big:,}-tick log in {t_long:.0f} s "
              f"({os.path.getsize(long_path) / 1e6:.1f} MB)")
        t0 = time.perf_counter()
        res = verify(long_path, first=big - 1000, last=big)
        t_tail = time.perf_counter() - t0
        assert res.identical, res.report()
        print(f"verify the last 1,000 ticks of the {big:,}-tick log: {t_tail:.2f} s "
              f"(from the keyframe at tick {res.first_tick:,})")


if __name__ == "__main__":
    main()
