"""Speed benchmark: recording and stepping rates, with units and the machine.

    touchdown bench speed            # the full figures (a few minutes)
    touchdown bench speed --quick    # small runs, to check the benchmark itself works

Figures:
* one ship, a long recording with the full MCAP log (ticks/s). The scene is the built-in ``bounce``
  run for ``n_ticks``: a bounce, then mostly landed, as a long recording mostly is.
* 10,000 ships: stepping alone and stepping + logging (ship-ticks/s). The fleet is a mix:
  40% flying high, 40% landed, 10% tipped, 10% arriving at 2-49 m/s (touchdowns, bounces).
* peak resident memory of the process (ru_maxrss).

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


STATE_SCENES = {
    "flying, far above (one step a tick, no contact work)": {"altitude": 5000.0},
    "flying, near the ground (sub-stepped)": {"altitude": 3.0, "vertical_speed": 0.0},
    "contact (sliding, sub-stepped)": {"state": "contact", "altitude": -0.016,
                                       "horizontal_speed": 3.0},
    "landed (pinned)": {"state": "landed"},
    "tipped (pinned, pivot dynamics)": {"state": "tipped", "tilt_deg": 90.0},
}


def state_costs(n_ships: int = 1000, n_ticks: int = 40) -> list[tuple[str, float]]:
    """Microseconds per ship-tick for a batch whose ships all stay in one state."""
    out = []
    for label, ini in STATE_SCENES.items():
        ships = [{"id": f"s{i}", "initial": {**ini, "east": float(i)}} for i in range(n_ships)]
        # flying near the ground: hover with thrust equal to weight so that it stays there
        inputs = [{"t": 0.0, "throttle": 10000.0 * 1.625 / 60000.0}] if "near" in label else []
        for sh in ships:
            sh["inputs"] = inputs
        scn = parse({"name": "cost", "duration": n_ticks * 0.05, "ships": ships}, "bench")
        st, inp = scn.initial, scn.inputs_at(0)
        t0 = time.perf_counter()
        for _ in range(n_ticks):
            st, _, _ = step(scn.params, st, inp)
        out.append((label, (time.perf_counter() - t0) / (n_ships * n_ticks) * 1e6))
    return out


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
    print("cost per ship-tick by state (batches of 1,000 ships in one state, default method):")
    for label, us in state_costs(1000, 10 if quick else 40):
        print(f"  {label:<55} {us:8.2f} us")
    peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak resident memory: {peak_mib:,.0f} MiB")


if __name__ == "__main__":
    main()
