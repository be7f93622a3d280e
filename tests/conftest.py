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


#: The suite's longest tests, longest first (seconds of wall under `pytest -n 2`, session 22): under
#: `--dist worksteal` (the README's command) they run first, so that the two workers end together
#: (in the file order, the Redis service's tests and the sweep came last: one worker ran them
#: for a minute while the other idled). Order only: every test runs, with the same checks. A file
#: moves whole (the sweep's module fixture compiles its kernels once; its other tests share it), a
#: test with all its parameters. Nothing needs to be here; a test missing from it only runs later.
LONG_FIRST = (
    "tests/test_sweep.py",  # its fixture compiles the sweep's kernels, 78-105 s
    "tests/test_edges3d.py::test_3d_touchdowns_follow_the_reference_at_the_default_tick",  # 38-46
    "tests/test_serve_chaos.py",  # 37, 15 and 12 s: Redis killed, paused, failed over
    "tests/test_serve_cluster.py",  # 16-30 s each of two, 3-8 s the others
    "tests/test_cli_contract.py::test_ctrl_c_leaves_a_finished_log_of_what_was_simulated",  # 17-36
    "tests/test_edges.py::test_touchdowns_over_the_space_of_starts_end_as_the_reference_says",  # 17-30
    "tests/test_hostile_input.py::test_a_fuzz_campaign_of_2000_files",  # 15-22
    "tests/test_foxglove_live.py::test_foxglove_connects_to_a_running_service",  # 13-14
    "tests/test_friction_law.py::test_a_point_mass_stops_exactly_when_its_momentum_fits",  # 7-14
    "tests/test_serve_ops.py",  # 14 tests of 2-12 s, ~80 s
    "tests/test_serve.py",  # 9 tests, ~30 s
    "tests/test_edges3d.py::test_a_ship_turning_over_an_edge_is_not_pinned",  # 9-10 s at 0.1
)


def _long_first(items: list) -> None:
    """``items`` reordered in place: those whose node id starts with an entry of LONG_FIRST
    first, in its order, each group in the file order; then the rest in the file order."""
    def rank(item) -> int:
        nodeid = item.nodeid
        for i, prefix in enumerate(LONG_FIRST):
            if nodeid == prefix or nodeid.startswith(prefix + ("::" if prefix.endswith(".py") else "")):
                return i
        return len(LONG_FIRST)
    items.sort(key=rank)  # stable: each group, and the rest, keep the file order


def pytest_collection_modifyitems(config, items):
    for item in items:
        if "redis_url" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.redis)
    # only under xdist's work stealing (every worker collects; the same order in each): its first
    # worker starts on the long tests while the other takes the second half of the list, and
    # whichever runs out takes half of what the other has left. Under `--dist load` the first
    # worker's first batch would hold them all; a serial run keeps the file order
    # (tests/background.py compiles for the tests it will come to).
    if getattr(config, "workerinput", {}).get("touchdown_dist") == "worksteal":
        _long_first(items)


@pytest.hookimpl(optionalhook=True)
def pytest_configure_node(node):
    """xdist's controller, for each worker: the --dist mode (a worker's own is "no")."""
    node.workerinput["touchdown_dist"] = node.config.getoption("dist")


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
