"""Speed benchmark: recording and stepping rates, with units and the machine.

    touchdown bench speed            # the full figures (a few minutes)
    touchdown bench speed --quick    # small runs, to check the benchmark itself works

Figures (issue 9's aims in brackets):
* one ship, a 100,000-tick recording with the full MCAP log [50,000 ticks/s], and stepping alone
  [200,000 ticks/s]. The scene is the built-in ``bounce`` run for 100,000 ticks: a bounce, then
  mostly landed, as a long recording mostly is.
* 10,000 ships, stepping alone [5,000,000 ship-ticks/s] and stepping + the full log
  [1,000,000], on one core (the process pinned to one CPU, the log's thread sharing it) and on
  all this machine's cores. The fleet is a mix: 40% flying high, 40% landed, 10% tipped, 10%
  arriving at 2-49 m/s (touchdowns, bounces).
* the first ``touchdown record bounce`` with an empty kernel cache (compilation included) [30 s],
  and a later one [1 s]: whole commands, in subprocesses.
* cost per ship-tick by state and model, microseconds.
* peak resident memory of the process (ru_maxrss).
* MuJoCo beside Touchdown on the same landers, as ratios (bench/mujoco_side.py; the ``bench``
  extra installs mujoco).

Timing uses time.perf_counter around the work only (scenario parsing excluded); no figure here is
an assertion: benchmarks are measured, never asserted in the test suite.
"""
from __future__ import annotations

import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager

import numpy as np

from touchdown import scenarios
from touchdown.service.driver import record
from touchdown.sim.run import run_blocks
from touchdown.sim.scenario import parse, parse_text


def machine() -> str:
    cpu = "unknown CPU"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return (f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, "
            f"numpy {np.__version__}, {platform.system()} {platform.machine()}")


def fleet_doc(n: int, duration: float) -> dict:
    rng = np.random.default_rng(7)
    ships = []
    for i in range(n):
        kind = i % 10
        e, nn = float(rng.uniform(-2e4, 2e4)), float(rng.uniform(-2e4, 2e4))
        if kind < 4:
            ini = {"altitude": float(rng.uniform(500, 5e4)), "vertical_speed": -5.0,
                   "horizontal_speed": 50.0}
        elif kind < 8:
            ini = {"state": "landed"}
        elif kind == 8:
            ini = {"state": "tipped", "tilt_deg": 90.0}
        else:
            ini = {"altitude": float(rng.uniform(0.5, 30)),
                   "vertical_speed": -float(rng.uniform(2, 49))}
        ini.update(east=e, north=nn)
        ships.append({"id": f"ship-{i:05d}", "initial": ini})
    return {"name": "bench-fleet", "duration": duration, "ships": ships}


@contextmanager
def one_core():
    """Pin this process (and the log's thread) to one CPU for the duration."""
    before = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {min(before)})
    try:
        yield
    finally:
        os.sched_setaffinity(0, before)


def _warm(scn) -> None:
    next(iter(run_blocks(scn, last_tick=1)))  # the kernels loaded before timing


def one_ship_recording(n_ticks: int, path: str) -> float:
    scn = parse_text(scenarios.text("bounce"), "bounce", {"duration": n_ticks * 0.05})
    _warm(scn)
    t0 = time.perf_counter()
    record(scn, path, "bounce")
    return (scn.params.sim.n_ticks + 1) / (time.perf_counter() - t0)


def one_ship_stepping(n_ticks: int) -> float:
    scn = parse_text(scenarios.text("bounce"), "bounce", {"duration": n_ticks * 0.05})
    _warm(scn)
    t0 = time.perf_counter()
    for _block in run_blocks(scn):
        pass
    return (scn.params.sim.n_ticks + 1) / (time.perf_counter() - t0)


def fleet_stepping(n_ships: int, n_ticks: int) -> float:
    scn = parse(fleet_doc(n_ships, n_ticks * 0.05), "bench")
    _warm(scn)
    t0 = time.perf_counter()
    for _block in run_blocks(scn):
        pass
    return n_ships * n_ticks / (time.perf_counter() - t0)


def fleet_recording(n_ships: int, n_ticks: int, path: str) -> float:
    scn = parse(fleet_doc(n_ships, n_ticks * 0.05), "bench")
    _warm(scn)
    t0 = time.perf_counter()
    record(scn, path, "bench")
    return n_ships * (n_ticks + 1) / (time.perf_counter() - t0)


def first_and_later_record(tmp: str) -> tuple[float, float]:
    """Wall seconds of ``touchdown record bounce`` with an empty kernel cache (it compiles) and
    then with the cache it left, each a whole command in a fresh process."""
    env = dict(os.environ, NUMBA_CACHE_DIR=os.path.join(tmp, "kernel-cache"))
    cmd = [sys.executable, "-m", "touchdown.cli", "record", "bounce", "-o",
           os.path.join(tmp, "b.mcap")]
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    out = []
    for _ in range(2):
        t0 = time.perf_counter()
        subprocess.run(cmd, env=env, cwd=root, check=True, capture_output=True)
        out.append(time.perf_counter() - t0)
    return out[0], out[1]


HOVER_THROTTLE = 10000.0 * 1.625 / 60000.0  # the default ship's weight on the Moon / max thrust

#: (state, the model that state gets, initial conditions, commands): batches of ships that stay in
#: that state (and model) for the whole measurement.
STATE_SCENES = [
    ("flying, far above", "coarse: one step a tick, no contact work", {"altitude": 5000.0}, []),
    # 3 m up the feet cannot reach the ground within a tick (sim.tight_reach: one step a tick);
    # 1 m up they can, and the ship is sub-stepped with the contact looked for
    ("flying, hovering 3 m up", "coarse: out of the feet's reach",
     {"altitude": 3.0, "vertical_speed": 0.0}, [{"t": 0.0, "throttle": HOVER_THROTTLE}]),
    ("flying, hovering 1 m up (feet in reach)", "full model, sub-stepped",
     {"altitude": 1.0, "vertical_speed": 0.0}, [{"t": 0.0, "throttle": HOVER_THROTTLE}]),
    ("bouncing upright (20-49 m/s)", "vertical: one exact step a tick",
     {"altitude": 0.3, "vertical_speed": "bounce"}, []),
    ("contact, upright at rest", "vertical: one exact step a tick",
     {"state": "contact", "altitude": -0.01625}, []),
    ("contact, sliding at 3 m/s", "full model, sub-stepped",
     {"state": "contact", "altitude": -0.01625, "horizontal_speed": 3.0}, []),
    ("contact, tilted 20 deg, rocking", "full model, sub-stepped",
     {"state": "contact", "altitude": -0.01625, "tilt_deg": 20.0}, []),
    ("landed", "pinned to the body", {"state": "landed"}, []),
    ("tipped", "pinned; pivot about the low foot", {"state": "tipped", "tilt_deg": 90.0}, []),
]

#: The configurations compared, each a [sim] table.
COST_CONFIGS = [
    ("default", {}),
    ("default, vertical sub-stepped", {"vertical_one_step": False}),
    ("seed's method", {"integrator": "semi_implicit_euler", "max_substep": 0.0,
                       "on_unstable": "allow"}),
    ("rk4 + sub-steps", {"integrator": "rk4"}),
]


def state_costs(n_ships: int = 1000, n_ticks: int = 40, dt: float = 0.05
                ) -> list[tuple[str, str, list[float]]]:
    """Microseconds per ship-tick for batches whose ships all stay in one state, one column per
    configuration of :data:`COST_CONFIGS`."""
    from touchdown.bench.states import ships_in_state
    rows = []
    for label, model, ini, inputs in STATE_SCENES:
        ships = ships_in_state(ini, inputs, n_ships)
        costs = []
        for _, sim in COST_CONFIGS:
            scn = parse({"name": "cost", "duration": n_ticks * dt, "ships": ships,
                         "sim": {"dt": dt, **sim}}, "bench")
            _warm(scn)
            t0 = time.perf_counter()
            for _block in run_blocks(scn):
                pass
            costs.append((time.perf_counter() - t0) / (n_ships * n_ticks) * 1e6)
        rows.append((label, model, costs))
    return rows


def main(quick: bool = False, against: list[str] | None = None) -> None:
    if against:
        from touchdown.bench import states
        print(f"machine: {machine()}")
        print("cost per ship-tick by state, us (tick 0.05 s, default model; CPU time, least of "
              "alternating fresh processes; bench/states.py):")
        states.print_comparison(states.compare(against, rounds=1 if quick else 2,
                                               ships=200 if quick else 1000,
                                               cases=50 if quick else 300))
    one_ticks = 5_000 if quick else 100_000
    fleet_ticks = 10 if quick else 100
    cores = len(os.sched_getaffinity(0))
    print(f"machine: {machine()}")
    with tempfile.TemporaryDirectory() as tmp:
        first, later = first_and_later_record(tmp)
        print(f"touchdown record bounce: first run after install (kernels compiled) {first:.1f} s "
              f"[aim 30 s]; later runs {later:.2f} s [aim 1 s]")
        path = os.path.join(tmp, "one.mcap")
        rate = one_ship_recording(one_ticks, path)
        print(f"one ship, {one_ticks:,}-tick recording with the full log: {rate:,.0f} ticks/s "
              f"[aim 50,000] (log {os.path.getsize(path) / 1e6:.1f} MB)")
        print(f"one ship, stepping alone: {one_ship_stepping(one_ticks):,.0f} ticks/s "
              f"[aim 200,000]")
        for label, pin in (("one core", True), (f"{cores} cores", False)):
            with (one_core() if pin else _nothing()):
                step_rate = fleet_stepping(10_000, fleet_ticks)
                rec_rate = fleet_recording(10_000, fleet_ticks, os.path.join(tmp, "fleet.mcap"))
            print(f"10,000 ships, {label}: stepping {step_rate:,.0f} ship-ticks/s [aim 5,000,000]"
                  f"; stepping + full log {rec_rate:,.0f} ship-ticks/s [aim 1,000,000] "
                  f"({fleet_ticks} ticks; log {os.path.getsize(os.path.join(tmp, 'fleet.mcap')) / 1e6:.0f} MB)")
    for dt in (0.05, 0.1):
        print(f"cost per ship-tick by state and model, us (tick {dt:g} s; batches of 1,000 ships "
              "that stay in one state):")
        print(f"  {'state':<36}{'model (default)':<42}"
              + "".join(f"{name:>32}" for name, _ in COST_CONFIGS))
        for label, model, costs in state_costs(1000, 10 if quick else 40, dt):
            print(f"  {label:<36}{model:<42}" + "".join(f"{c:>32.2f}" for c in costs))
    peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak resident memory: {peak_mib:,.0f} MiB")
    from touchdown.bench import mujoco_side
    mujoco_side.main(quick=quick)  # the anchor: MuJoCo on the same machine, in the same run


@contextmanager
def _nothing():
    yield


if __name__ == "__main__":
    main()
