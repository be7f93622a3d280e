"""What a first run compiles (issue 36: the first `touchdown record` after an install under 15 s).

- A record compiles each entry point once: one type specialization of each (an int where a
  float was expected, or a non-contiguous array, would compile the whole step a second time).
- After `touchdown warm` (the README's install line runs it), a record, a replay and the
  service's shard compile nothing: every kernel they call is in the on-disk cache.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import background
import warmup

ROOT = Path(__file__).resolve().parents[1]

# In a fresh process (the suite's own may have called the kernels with other types): the
# command line's record, then each compiled entry point's specializations, and the number of
# kernels that compiled rather than loaded from the cache.
_RUN = warmup.COUNT_COMPILES + """
from touchdown.cli import main
for args in ARGS:
    try:
        main(args, standalone_mode=False)
    except SystemExit as exc:
        assert not exc.code, (args, exc.code)
from numba.core.registry import CPUDispatcher
from touchdown.sim import measure, placement, step, world
for mod in (step, placement, world, measure):
    for name, obj in vars(mod).items():
        if type(obj) is CPUDispatcher and obj.signatures:  # an entry point, not an inner kernel
            print("SPECIALIZATIONS", f"{mod.__name__}.{name}", len(obj.signatures))
print("COMPILED", len(compiled), ",".join(sorted(set(compiled))))
"""


def _run(args: list[list[str]], env: dict, cwd: Path) -> tuple[dict[str, int], int, str]:
    r = subprocess.run([sys.executable, "-c", _RUN.replace("ARGS", repr(args))], env=env,
                       cwd=cwd, capture_output=True, text=True, timeout=1800)
    assert r.returncode == 0, r.stdout + r.stderr
    specs, compiled, names = {}, None, ""
    for line in r.stdout.splitlines():
        if line.startswith("SPECIALIZATIONS "):
            _, name, n = line.split()
            specs[name] = int(n)
        elif line.startswith("COMPILED "):
            parts = line.split(maxsplit=2)
            compiled, names = int(parts[1]), parts[2] if len(parts) > 2 else ""
    assert compiled is not None, r.stdout + r.stderr
    return specs, compiled, names


def test_a_record_compiles_each_entry_point_once(tmp_path):
    specs, _, _ = _run([["record", "bounce", "-o", str(tmp_path / "b.mcap")],
                        ["record", "hills", "-o", str(tmp_path / "h.mcap")]],
                       dict(os.environ), tmp_path)
    for name in ("touchdown.sim.step.step_ticks", "touchdown.sim.step.observe_ships",
                 "touchdown.sim.placement._place_ships"):
        assert specs.get(name) == 1, specs
    assert all(n == 1 for n in specs.values()), specs  # any other entry point a record calls


@background.job("test_compile_once.py::test_after_touchdown_warm_a_record_a_replay_and_serve_compile_nothing")
def _warm_then_run_everything() -> tuple[int, int, str]:
    """With an empty cache: `touchdown warm`, then a record of each kind of built-in scene, a
    replay --verify and the service's warm-up. Returns (kernels warm compiled, kernels the rest
    compiled, their names). In a folder of its own, removed after."""
    import tempfile
    with tempfile.TemporaryDirectory(prefix="touchdown-compile-once-") as tmp:
        tmp_path = Path(tmp)
        env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
        _, warmed, _ = _run([["warm"]], env, tmp_path)
        _, compiled, names = _run(_the_rest(tmp_path), env, tmp_path)
        return warmed, compiled, names


def _the_rest(tmp_path: Path) -> list[list[str]]:
    """After the warm: a record of each kind of built-in scene, a replay --verify and the
    service's warm-up (their logs in ``tmp_path``)."""
    logs = {name: str(tmp_path / f"{name}.mcap")
            for name in ("bounce", "hills", "spinning-moon", "fleet", "slide")}
    runs = [["record", name, "-o", path] for name, path in logs.items()]
    return runs + [["replay", logs["bounce"], "--verify"], ["serve", "--warm-only"]]


@pytest.mark.slow
def test_after_touchdown_warm_a_record_a_replay_and_serve_compile_nothing(tmp_path):
    """With an empty cache (a fresh install): `touchdown warm` compiles, then recording built-in
    scenes of every kind of scene (flat, hills, a turning body, a fleet), replaying one with
    --verify and the service's own warm-up compile nothing. (In a serial run of the suite the
    work starts at the suite's beginning on the idle core, tests/background.py; under xdist the
    controller runs the warm before the workers start, tests/warmup.py.)"""
    warm = warmup.done()
    if "empty_cache" in warm:  # under xdist the controller ran the warm (tests/warmup.py)
        warmed = warm["warmed"]
        _, compiled, names = _run(_the_rest(tmp_path), dict(
            os.environ, NUMBA_CACHE_DIR=warm["empty_cache"]), tmp_path)
    else:
        warmed, compiled, names = background.result(_warm_then_run_everything)
    assert warmed > 0  # the cache was empty
    assert compiled == 0, names
