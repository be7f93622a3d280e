"""Work a serial run of the suite (CI's) starts at its beginning on the core it leaves idle.

The whole suite runs in one process (README, "Tests"), so one of the machine's two cores idles
while three tests spend most of their time compiling kernels in subprocesses of their own: the
compile-once check (every kernel into an empty cache), the generic-CPU build and the sweep's
kernels. Each registers its subprocess work here as a job, a function of no arguments; when such
a test is among the collected ones of a serial run, conftest.py starts its job at the beginning
on a background thread (one job after the other), and the test takes the job's result when it
comes to it. The job is the same work the test would do inline, done earlier: run alone (`pytest
tests/test_compile_once.py`), under xdist (`-n 2`: its workers already use both cores) or where
the test is not selected, nothing starts and the test calls the function itself.
"""
from __future__ import annotations

import threading
from typing import Any, Callable

_jobs: dict[str, Callable[[], Any]] = {}
_started: dict[str, "_Run"] = {}


class _Run:
    def __init__(self) -> None:
        self.done = threading.Event()
        self.value: Any = None
        self.error: BaseException | None = None


def job(test_nodeid_suffix: str) -> Callable[[Callable[[], Any]], Callable[[], Any]]:
    """Register the decorated function as the background work of the test whose node id ends in
    ``test_nodeid_suffix`` ("test_file.py::test_name")."""
    def register(fn: Callable[[], Any]) -> Callable[[], Any]:
        _jobs[test_nodeid_suffix] = fn
        return fn
    return register


def start(nodeids: list[str]) -> list[str]:
    """Start, one after the other on one daemon thread, the jobs of the tests among ``nodeids``.
    Returns the keys started."""
    chosen = [key for key in _jobs if any(n.endswith(key) for n in nodeids)]
    if not chosen:
        return []
    for key in chosen:
        _started[key] = _Run()

    def run_all() -> None:
        for key in chosen:
            run = _started[key]
            try:
                run.value = _jobs[key]()
            except BaseException as exc:  # handed to the test, which raises it
                run.error = exc
            finally:
                run.done.set()

    threading.Thread(target=run_all, name="suite-background", daemon=True).start()
    return chosen


def result(fn: Callable[[], Any]) -> Any:
    """The registered function's result: the background run's, waited for, if it was started;
    else ``fn()`` called now."""
    key = next((k for k, f in _jobs.items() if f is fn), None)
    run = _started.get(key) if key is not None else None
    if run is None:
        return fn()
    run.done.wait()
    if run.error is not None:
        raise run.error
    return run.value


def wait(fn: Callable[[], Any]) -> None:
    """For a job that only fills the kernel cache ahead of a test: wait for it if it was
    started (its failure is the test's own to find: the test does the work again and fails
    where it does); else nothing."""
    key = next((k for k, f in _jobs.items() if f is fn), None)
    run = _started.get(key) if key is not None else None
    if run is not None:
        run.done.wait()
