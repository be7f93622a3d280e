"""Speed benchmark: recording and stepping rates, with units and the machine.

    touchdown bench speed            # the full figures (a few minutes)
    touchdown bench speed --quick    # small runs, to check the benchmark itself works

Figures:
* one ship, a long recording with the full MCAP log (ticks/s). The scene is the built-in ``bounce``
  run for ``n_ticks``: a bounce, then mostly landed, as a long recording mostly is.
* 10,000 ships: stepping alone and stepping + logging (ship-ticks/s). The fleet is a mix:
  40% flying high, 40% landed, 10% tipped, 10% arriving at 2-49 m/s (touchdowns, bounces).
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
import tempfile
import time

import numpy as np

import scenarios
from logs.mcap_log import LogWriter
from sim.run import run
from sim.scenario import parse, parse_text
from sim.step import step


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


def one_ship_recording(n_ticks: int, path: str) -> float:
    scn = parse_text(scenarios.text("bounce"), "bounce", {"duration": n_ticks * 0.05})
    t0 = time.perf_counter()
    with LogWriter(path, scn, "bounce") as w:
        for rec in run(scn):
            w.write(rec)
    return (scn.params.sim.n_ticks + 1) / (time.perf_counter() - t0)


def fleet_stepping(n_ships: int, n_ticks: int) -> float:
    scn = parse(fleet_doc(n_ships, n_ticks * 0.05), "bench")
    st, inputs = scn.initial, scn.inputs_at(0)
    t0 = time.perf_counter()
    for _ in range(n_ticks):
        st, _, _ = step(scn.params, st, inputs)
    return n_ships * n_ticks / (time.perf_counter() - t0)


def fleet_recording(n_ships: int, n_ticks: int, path: str) -> float:
    scn = parse(fleet_doc(n_ships, n_ticks * 0.05), "bench")
    t0 = time.perf_counter()
    with LogWriter(path, scn, "bench") as w:
        for rec in run(scn):
            w.write(rec)
    return n_ships * (n_ticks + 1) / (time.perf_counter() - t0)


HOVER_THROTTLE = 10000.0 * 1.625 / 60000.0  # the default ship's weight on the Moon / max thrust

#: (state, the model that state gets, initial conditions, commands): batches of ships that stay in
#: that state (and model) for the whole measurement.
STATE_SCENES = [
    ("flying, far above", "coarse: one step a tick, no contact work", {"altitude": 5000.0}, []),
    ("flying, near the ground (hovering)", "full model, sub-stepped",
     {"altitude": 3.0, "vertical_speed": 0.0}, [{"t": 0.0, "throttle": HOVER_THROTTLE}]),
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
    rows = []
    for label, model, ini, inputs in STATE_SCENES:
        ships = []
        for i in range(n_ships):
            init = {**ini, "east": float(i)}
            if init.get("vertical_speed") == "bounce":
                init["vertical_speed"] = -(20.0 + 29.0 * i / max(n_ships - 1, 1))
            ships.append({"id": f"s{i}", "initial": init, "inputs": inputs})
        costs = []
        for _, sim in COST_CONFIGS:
            scn = parse({"name": "cost", "duration": n_ticks * dt, "ships": ships,
                         "sim": {"dt": dt, **sim}}, "bench")
            st, inp = scn.initial, scn.inputs_at(0)
            t0 = time.perf_counter()
            for _ in range(n_ticks):
                st, _, _ = step(scn.params, st, inp)
            costs.append((time.perf_counter() - t0) / (n_ships * n_ticks) * 1e6)
        rows.append((label, model, costs))
    return rows


def main(quick: bool = False) -> None:
    one_ticks = 5_000 if quick else 100_000
    fleet_ticks = 10 if quick else 100
    print(f"machine: {machine()}")
    with tempfile.TemporaryDirectory() as tmp:
        rate = one_ship_recording(one_ticks, os.path.join(tmp, "one.mcap"))
        size = os.path.getsize(os.path.join(tmp, "one.mcap"))
        print(f"one ship, {one_ticks:,}-tick recording with the full log: {rate:,.0f} ticks/s "
              f"(log {size / 1e6:.1f} MB)")
        rate = fleet_stepping(10_000, fleet_ticks)
        print(f"10,000 ships, stepping only ({fleet_ticks} ticks): {rate:,.0f} ship-ticks/s")
        rate = fleet_recording(10_000, fleet_ticks, os.path.join(tmp, "fleet.mcap"))
        size = os.path.getsize(os.path.join(tmp, "fleet.mcap"))
        print(f"10,000 ships, stepping + full log ({fleet_ticks} ticks): {rate:,.0f} ship-ticks/s "
              f"(log {size / 1e6:.1f} MB)")
    for dt in (0.05, 0.1):
        print(f"cost per ship-tick by state and model, us (tick {dt:g} s; batches of 1,000 ships "
              "that stay in one state):")
        print(f"  {'state':<36}{'model (default)':<42}"
              + "".join(f"{name:>32}" for name, _ in COST_CONFIGS))
        for label, model, costs in state_costs(1000, 10 if quick else 40, dt):
            print(f"  {label:<36}{model:<42}" + "".join(f"{c:>32.2f}" for c in costs))
    peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak resident memory: {peak_mib:,.0f} MiB")
    from bench import mujoco_side
    mujoco_side.main(quick=quick)  # the anchor: MuJoCo on the same machine, in the same run


if __name__ == "__main__":
    main()
