"""Where a worker's loop spends its time: wall and CPU seconds (the loop's thread's own,
``time.thread_time``) summed per phase over every loop. Two clock reads a phase: cheap enough to
keep on (a few dozen per tick). ``bench serve`` prints the breakdown; the stats line does not."""
from __future__ import annotations

import gc
import heapq
import time
from contextlib import contextmanager

_wall = time.perf_counter
_cpu = time.thread_time


class Phases:
    def __init__(self, into: dict):
        self.into = into  # phase -> [wall s, cpu s]

    @contextmanager
    def __call__(self, name: str):
        w, c = _wall(), _cpu()
        try:
            yield
        finally:
            acc = self.into.get(name)
            if acc is None:
                acc = self.into[name] = [0.0, 0.0]
            acc[0] += _wall() - w
            acc[1] += _cpu() - c

    def add(self, name: str, wall: float, cpu: float) -> None:
        acc = self.into.setdefault(name, [0.0, 0.0])
        acc[0] += wall
        acc[1] += cpu


class SlowTicks:
    """The ``keep`` slowest loops and where each one's wall time went (its phases, those of 1 ms
    or more): what a tick's p99 and max are made of, which the sums per phase cannot say. A
    dict copy a loop (about 2 us)."""

    def __init__(self, into: dict, keep: int = 20):
        self.into = into  # Phases.into: phase -> [wall s, cpu s]
        self.keep = keep
        self._heap: list = []  # (tick s, loop, {phase: wall s})
        self._before: dict = {}

    def start(self) -> None:
        self._before = {k: v[0] for k, v in self.into.items()}

    def end(self, loop: int, tick_s: float) -> None:
        if len(self._heap) >= self.keep and tick_s <= self._heap[0][0]:
            return
        before = self._before
        parts = {k: round(v[0] - before.get(k, 0.0), 4) for k, v in self.into.items()
                 if v[0] - before.get(k, 0.0) >= 1e-3}
        item = (tick_s, loop, parts)
        if len(self._heap) < self.keep:
            heapq.heappush(self._heap, item)
        else:
            heapq.heapreplace(self._heap, item)

    def slowest(self) -> list[dict]:
        """The slowest loops first: loop number, its wall seconds, its phases' wall seconds."""
        return [{"loop": loop, "tick_s": round(t, 4), "phases": parts}
                for t, loop, parts in sorted(self._heap, key=lambda x: -x[0])]


class GcTimer:
    """Adds the garbage collector's pauses to ``phases`` as ``gc`` (the wall time of each
    collection, in whichever phase it struck; its generation 2 ones as ``gc2`` too) and
    counts them."""

    def __init__(self, phases: Phases):
        self.phases = phases
        self._t0 = 0.0
        self.longest_s = 0.0

    def __call__(self, phase: str, info: dict) -> None:
        if phase == "start":
            self._t0 = _wall()
            return
        dt = _wall() - self._t0
        self.phases.add("gc", dt, dt)
        if info.get("generation") == 2:
            self.phases.add("gc2", dt, dt)
        self.longest_s = max(self.longest_s, dt)

    def install(self) -> None:
        if self not in gc.callbacks:
            gc.callbacks.append(self)

    def remove(self) -> None:
        if self in gc.callbacks:
            gc.callbacks.remove(self)
