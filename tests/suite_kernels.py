"""What the suite's tests compile beyond ``touchdown warm``, compiled once before xdist's workers
start (tests/warmup.py), in the process that has just run the warm.

A worker that calls a kernel from Python (a test calling a phase or the friction solve,
``touchdown export`` filling its JSON lines) compiles that kernel's twin (sim.compiled._Inner):
in a fresh worker that types every kernel it calls again (they are not cached on disk), 5 to 20 s
of CPU each (the friction solve's 18 s). In the warm's process the kernels are typed already, so
each twin costs only its own code (the friction solve's 1.6 s); it goes into the project's cache
(:func:`compile_them`'s ``cache``), where the workers load it. The sweep's own kernels too (its
reductions: the sweep steps with the warm's sim.step.step_ticks; before session 27 its own loop
around the step was the whole step optimized again, 129 s of CPU even here).

Each call below is one a test makes (the same helper, the same argument types): a call whose
types drift from the test's only leaves that test to compile its own, as before; a call that
fails is named in the result and skipped (the test then fails where it does).
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

TESTS = Path(__file__).resolve().parent


def _friction() -> None:
    # test_friction_law's direct calls of the friction solve (both of _solve_feet's signatures)
    import math

    import numpy as np

    import test_friction_law as F
    F.point_mass(1000.0, (0.3, 0.4), (150.0, 150.0, 100.0, 100.0))
    a, slip, radius, lam0, active = F.two_feet_on_their_rims()
    F._gauss_seidel(a, slip, radius, lam0.copy(), active, False)
    F._from_carried(a, slip, radius, lam0.copy(), active, math.inf)
    F._solve_feet(a, slip, radius, lam0.copy(), active, True)
    F._slipping(a, slip, lam0, active, 1e-9)
    F.spread_over_step((1.0, 2.0, -3.0), (1.0, 0.0, 0.0, 0.0), (1.0, 2.0, 0.5), (0.2, 1.5, 0.5),
                       (0.0, 0.1, 0.0), (0.0, 0.1, 0.0), 0.05)
    F.disk(np.eye(2), np.array([1.0, 0.0]), 0.5)


def _settle() -> None:
    # test_transitions' settle (sim.phases.settle)
    import test_transitions as T
    params, st = T._contact_state("attached")
    T._settles(params, st, 1)


def _export() -> None:
    # `touchdown export` of a log (logs.json_lines' twins): test_cli_contract, test_export_numpy
    from click.testing import CliRunner

    from touchdown.cli import main
    with tempfile.TemporaryDirectory(prefix="touchdown-suite-kernels-") as tmp:
        log = str(Path(tmp) / "b.mcap")
        runner = CliRunner()
        for args in (["record", "bounce", "--set", "duration=1", "-o", log], ["export", log]):
            r = runner.invoke(main, args)
            if r.exit_code != 0:
                raise RuntimeError(f"{args[0]}: {r.output}")


def _sweep() -> None:
    # tests/test_sweep.py's sweep_kernels fixture: the sweep's reductions (sweep.fleet.ready)
    from touchdown.sweep.fleet import ready
    ready()


STEPS = {"friction": _friction, "settle": _settle, "export": _export, "sweep": _sweep}


def compile_them(cache: str, steps: tuple[str, ...] = tuple(STEPS)) -> dict:
    """Compile the kernels of ``steps`` (names in STEPS, default all) into ``cache`` (the
    project's kernel folder, sim.compiled.cache_dir()). Returns {step: seconds} and, under
    "failed", the steps that raised."""
    import numba
    numba.config.CACHE_DIR = cache  # a twin's cache is placed when it is made (first call)
    if str(TESTS) not in sys.path:
        sys.path.insert(0, str(TESTS))
    done: dict = {}
    for name in steps:
        step = STEPS[name]
        t0 = time.perf_counter()
        try:
            step()
        except Exception as exc:  # the test compiles its own and fails where it does
            done.setdefault("failed", []).append(f"{name}: {type(exc).__name__}: {exc}"[:200])
            continue
        done[name] = round(time.perf_counter() - t0, 1)
    return done
