"""What the test files share: the recorded scenes several files read (recorded once a session,
read-only), the Redis fixture, and the suite's parts.

The parts (markers registered in pyproject.toml):
- ``redis``: needs a Redis server (the shared one on 127.0.0.1:6379 or private redis-servers);
- ``slow``: long runs (chaos, clusters, logs at scale, property runs over many cases, sweeps).
``pytest -n 2 -m "not redis and not slow"`` is the fast physics-and-logs part (README, "Tests");
``pytest -n 2`` (CI, .ci/run) runs all of it on both cores, the kernels compiled before the workers
start (tests/warmup.py); plain ``pytest`` runs all of it in one process (tests/background.py). A test that asks for ``redis_url`` is marked ``redis``
here, whatever its file says.

A missing Redis fails in CI (CI=true, set by .ci/run; a ``redis`` test that skips there fails,
:func:`pytest_runtest_makereport`), skips elsewhere (tests/redis_server.py).
"""
from __future__ import annotations

import os
import stat
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from redis_server import redis_url  # noqa: F401 - the session's Redis, a fixture for every file


def _hypothesis_without_local_constants() -> None:
    """Hypothesis (6.1xx) mixes numbers it finds in the modules loaded so far into its draws
    (hypothesis.internal.conjecture.providers._get_local_constants), so a derandomized test drew
    other examples after other tests had imported other modules in the same worker: a start the
    3-D reference test never drew alone failed it in the whole suite's run. Without them, a
    test's examples depend only on its own source, in any run. (An internal of hypothesis: where
    it is gone, nothing is patched and the draws are hypothesis's own.)"""
    try:
        from hypothesis.internal.conjecture import providers
    except ImportError:
        return
    if hasattr(providers, "_get_local_constants") and hasattr(providers, "Constants"):
        providers._get_local_constants = lambda: providers.Constants()


_hypothesis_without_local_constants()


def _record(path: Path, scene: str, *sets: str) -> Path:
    from touchdown.cli import main
    args = ["record", scene, "-o", str(path)] + [x for s in sets for x in ("--set", s)]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0, r.output
    # read-only: a test that would change the shared log must copy it first (fails loudly if not)
    path.chmod(stat.S_IRUSR | stat.S_IRGRP | stat.S_IROTH)
    return path


@pytest.fixture(scope="session")
def bounce_log(tmp_path_factory) -> Path:
    """The built-in ``bounce`` as ``touchdown record bounce`` writes it (30 s, 601 ticks),
    recorded once a session; read-only."""
    return _record(tmp_path_factory.mktemp("scenes") / "bounce.mcap", "bounce")


@pytest.fixture(scope="session")
def fleet_log_20s(tmp_path_factory) -> Path:
    """The built-in ``fleet`` cut to 20 s, recorded once a session; read-only."""
    return _record(tmp_path_factory.mktemp("scenes") / "fleet-20s.mcap", "fleet", "duration=20")


@pytest.hookimpl(hookwrapper=True)
def pytest_collection(session):
    """Collection keeps the bytecode of what it imports, PYTHONDONTWRITEBYTECODE=1 or not (this
    machine's harness sets it): pytest reads its rewritten test modules' pyc
    (tests/__pycache__/*-pytest-*.pyc) whatever the setting, but writes them only where it is
    off, so every worker of every run rewrote the asserts of every test module again (4.6 s of
    its 8 s collection, measured) and compiled the project's modules the tests import (as did
    each subprocess a test starts). The pyc go where Python puts them (``__pycache__``, which
    .gitignore ignores); the setting is the environment's again once collection ends."""
    was = sys.dont_write_bytecode
    sys.dont_write_bytecode = False
    try:
        yield
    finally:
        sys.dont_write_bytecode = was


def pytest_collection_modifyitems(config, items):
    for item in items:
        if "redis_url" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.redis)
    if hasattr(config, "workerinput"):
        _sweep_first(items)


def _sweep_first(items) -> None:
    """Under xdist, tests/test_sweep.py's tests first, in their order (every worker collects the
    same order; the controller deals it out). Its sweeps needed the sweep's own compile of the
    step (~130 s of CPU, under a lock in the kernel cache): where the file came late, both
    workers met it near the end (worksteal hands the thief the tail of the other's queue), one
    compiling while the other waited on the lock, 103 s of a worker's time idle in one CI run.
    The sweep now steps with record's compiled step (sweep.fleet), which the warm-up compiles;
    the file stays first, its longer tests (the Ctrl-C subprocess, the Dask cluster) at the
    head of one worker's queue rather than its tail."""
    def is_sweep(it) -> bool:
        return it.nodeid.split("::", 1)[0].endswith("test_sweep.py")
    items.sort(key=lambda it: not is_sweep(it))  # (a stable sort: each part keeps its order)


def pytest_sessionstart(session):
    """Under xdist (the README's `pytest -n 2`) the controller compiles the kernels once, before
    the workers start (tests/warmup.py)."""
    config = session.config
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return
    import warmup
    warmup.before_workers(config)


def pytest_terminal_summary(terminalreporter):
    import warmup
    warmup.summary(terminalreporter)


def pytest_unconfigure(config):
    import warmup
    warmup.cleanup(config)


def pytest_collection_finish(session):
    """A serial run (no xdist: CI's) starts the compile-bound work of the selected tests on the
    core it leaves idle (tests/background.py)."""
    config = session.config
    if hasattr(config, "workerinput") or getattr(config.option, "numprocesses", None):
        return
    import background
    background.start([item.nodeid for item in session.items])


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """In CI a test that needs Redis and skipped (whatever skipped it) is a failure: CI must run
    the service's tests, never pass without them."""
    outcome = yield
    report = outcome.get_result()
    if report.skipped and os.environ.get("CI") == "true" and item.get_closest_marker("redis"):
        report.outcome = "failed"
        report.longrepr = f"skipped in CI, where Redis is required: {report.longrepr}"
