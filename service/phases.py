"""Where a worker's loop spends its time: wall and CPU seconds (the loop's thread's own,
``time.thread_time``) summed per phase over every loop. Two clock reads a phase: cheap enough to
keep on (a few dozen per tick). ``bench serve`` prints the breakdown; the stats line does not."""
from __future__ import annotations

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
