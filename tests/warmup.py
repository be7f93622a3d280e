"""The kernels compiled once, before pytest-xdist's workers start (the README's test command,
``pytest -n 2``).

Most of a fresh clone's suite is numba compiling: the kernels' first compile (every worker that
calls a kernel before it is in the on-disk cache compiles it: two workers, twice the work), the
compile-once check's `touchdown warm` into an empty cache (tests/test_compile_once.py) and the
kernels compiled for a generic x86-64 (tests/test_determinism.py). Under xdist the controller,
before it starts the workers, runs those cold compiles at once, one a core, in subprocesses:

- ``touchdown warm`` into an empty cache of its own: the compile-once check's first half (it
  counts what compiled); its kernels are then copied into the project's cache (sim.compiled.
  cache_dir), where it lacks them, so the workers load them rather than each compiling them.
  After its count the same process compiles, into the project's cache, the twins of the kernels
  tests call from Python (tests/suite_kernels.py), cheaply there: its kernels are typed already;
- ``touchdown warm`` with NUMBA_CPU_NAME=generic into a cache of its own beside the project's
  (kept: a later run loads it), which the generic-CPU test then uses.

Each runs only when its test may be among the selected ones (its file among the arguments, neither
-m nor -k excluding it: the controller does not collect); else, if the project's
cache lacks the step, a plain ``touchdown warm`` fills it (and compiles tests/suite_kernels.py's
kernels after it). The workers find what was done in
the environment (``TOUCHDOWN_SUITE_WARM``, JSON); a test where it is missing does its own work
(a serial run: tests/background.py, or the file run alone).
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ENV = "TOUCHDOWN_SUITE_WARM"
TESTS = Path(__file__).resolve().parent
ROOT = TESTS.parent

#: The start of a script for a fresh process: the kernels that compile (rather than load from
#: the cache) are listed in ``compiled`` (numba's events); tests/test_compile_once.py's too.
COUNT_COMPILES = """
from numba.core import event
compiled = []
class Count(event.Listener):
    def on_start(self, ev):
        compiled.append(ev.data["dispatcher"].py_func.__qualname__)
    def on_end(self, ev):
        pass
event.register("numba:compile", Count())
"""

# `touchdown warm` in a fresh process, counting the kernels that compiled; then, where the
# controller asks (SUITE_KERNELS_ENV: the project's cache and the tests folder), what the tests
# compile beyond the warm (tests/suite_kernels.py), in this process where the kernels are typed
SUITE_KERNELS_ENV = "TOUCHDOWN_SUITE_KERNELS"
_WARM = COUNT_COMPILES + """
from touchdown.cli import main
main(["warm"], standalone_mode=False)
print("COMPILED", len(compiled), flush=True)
import json, os, sys
ask = os.environ.get("%s")
if ask:
    ask = json.loads(ask)
    sys.path.insert(0, ask["tests"])
    import suite_kernels
    print("SUITE_KERNELS", json.dumps(suite_kernels.compile_them(ask["cache"])))
""" % SUITE_KERNELS_ENV


def done() -> dict:
    """What the controller did before the workers started ({} when nothing: a serial run, or a
    run without the hook)."""
    text = os.environ.get(ENV)
    return json.loads(text) if text else {}


def _may_run(config, filename: str, test: str, markers: set[str]) -> bool:
    """Whether the test ``test`` of ``filename`` with ``markers`` may be selected: its file (or a
    folder holding it) among the arguments, or no arguments (testpaths), -m not excluding it and
    -k not excluding it (pytest's own matching: a case-insensitive part of the file's, the test's
    or a marker's name)."""
    from _pytest.mark.expression import Expression
    markexpr, keywordexpr = config.option.markexpr, config.option.keyword
    if markexpr and not Expression.compile(markexpr).evaluate(lambda m: m in markers):
        return False
    names = [filename, test, "tests", *markers]
    if keywordexpr and not Expression.compile(keywordexpr).evaluate(
            lambda k: any(k.lower() in n.lower() for n in names)):
        return False
    args = [a.split("::")[0] for a in config.args] or ["tests"]
    target = (TESTS / filename).resolve()
    for arg in args:
        path = (Path(config.invocation_params.dir) / arg).resolve()
        if path == target or path in target.parents:
            return True
    return False


def _project_cache() -> Path:
    out = subprocess.run([sys.executable, "-c",
                          "from touchdown.sim.compiled import cache_dir; print(cache_dir())"],
                         capture_output=True, text=True, cwd=ROOT, check=True)
    return Path(out.stdout.strip().splitlines()[-1])


def _warm(env: dict) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", _WARM], env=env, cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def _finish(proc: subprocess.Popen, what: str, info: dict | None = None) -> int:
    out, _ = proc.communicate(timeout=3600)
    counts = [line.split()[1] for line in out.splitlines() if line.startswith("COMPILED ")]
    if proc.returncode != 0 or not counts:
        raise RuntimeError(f"{what} failed:\n{out}")
    if info is not None:
        for line in out.splitlines():
            if line.startswith("SUITE_KERNELS "):
                info["suite_kernels"] = json.loads(line.split(maxsplit=1)[1])
    return int(counts[-1])


def _suite_kernels(project: Path) -> dict:
    """The environment asking a warm's process to compile, into the project's cache, what the
    tests would compile in the workers (tests/suite_kernels.py)."""
    return {SUITE_KERNELS_ENV: json.dumps({"cache": str(project), "tests": str(TESTS)})}


def _copy_missing(src: Path, dst: Path) -> int:
    """Copy the cache files under ``src`` into ``dst`` where ``dst`` has none of that name (an
    index numba wrote there is left as it is). Returns the files copied."""
    n = 0
    for path in src.rglob("*"):
        if path.is_file() and not path.name.startswith("."):
            target = dst / path.relative_to(src)
            if not target.exists():
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(path, target)
                n += 1
    return n


def before_workers(config) -> None:
    """The controller's step (conftest.pytest_sessionstart under xdist): the cold compiles, one a
    core; their results in os.environ for the workers, their folders removed at the end."""
    t0 = time.perf_counter()
    base = Path(tempfile.mkdtemp(prefix="touchdown-suite-warm-"))
    config._touchdown_warm_dir = base
    project = _project_cache()
    info: dict = {}
    procs = {}
    if _may_run(config, "test_compile_once.py",
                "test_after_touchdown_warm_a_record_a_replay_and_serve_compile_nothing", {"slow"}):
        info["empty_cache"] = str(base / "empty")
        procs["empty"] = _warm(dict(os.environ, NUMBA_CACHE_DIR=info["empty_cache"],
                                    **_suite_kernels(project)))
    elif not any(project.rglob("step.step_ticks-*.nbi")):
        procs["project"] = _warm(dict(os.environ, **_suite_kernels(project)))
    if _may_run(config, "test_determinism.py",
                "test_kernels_compiled_for_a_generic_cpu_give_this_hosts_bits", {"slow"}):
        # beside the project's cache, kept: a later run loads it (stale versions are pruned)
        info["generic_cache"] = str(project.parent / "generic")
        env = dict(os.environ, NUMBA_CPU_NAME="generic", NUMBA_CACHE_DIR=info["generic_cache"])
        env.pop("NUMBA_CPU_FEATURES", None)
        procs["generic"] = _warm(env)
    counts = {what: _finish(proc, f"touchdown warm ({what})", info)
              for what, proc in procs.items()}
    if "empty" in counts:
        info["warmed"] = counts["empty"]
        for kernels in Path(info["empty_cache"]).glob("touchdown-kernels-*"):
            info["copied"] = _copy_missing(kernels, project)
    info["seconds"] = round(time.perf_counter() - t0, 1)
    if procs:
        config._touchdown_warm_seconds = info["seconds"]
    os.environ[ENV] = json.dumps(info)
    reporter = config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None:
        reporter.write_line(f"tests/warmup.py, before the workers: {info}")


def summary(reporter) -> None:
    """At the end, the warm's time: pytest's own "passed in" starts after it (the terminal
    reporter takes its start time after this hook), so the whole run took both."""
    seconds = getattr(reporter.config, "_touchdown_warm_seconds", None)
    if seconds is not None:
        reporter.write_line(f"tests/warmup.py: {seconds:.0f} s compiling before the workers "
                            "started, not in the time pytest gives below")


def cleanup(config) -> None:
    base = getattr(config, "_touchdown_warm_dir", None)
    if base is not None:
        shutil.rmtree(base, ignore_errors=True)
