"""Per-state cost of a ship-tick, µs, for whichever touchdown is installed (issue 36's table).

    python -m touchdown.bench.states [--ships 1000] [--ticks 40] [--repeat 2] [--json OUT]
    python -m touchdown.bench.states --against /path/to/0.7/.venv/bin/python [--rounds 2]

The same scenes as ``touchdown bench speed``'s (bench.speed.STATE_SCENES, default model, tick
0.05 s, batches of ships that stay in one state) and 300 touchdowns of 20 s through the sweep's
loop (the envelope scene, 6° slope; vertical 1-12 m/s down, 0-6 m/s sideways, 0-15° tilt; a Latin
hypercube, seed 1). The file imports only what 0.7.0 also has, so the same file run by an older
install's interpreter (``/path/to/0.7/.venv/bin/python bench/states.py``) measures that version:
run both alternately in one session and compare ratios. CPU time of the process (time.process_time), best of ``--repeat``.
"""
from __future__ import annotations

import argparse
import json
import time

HOVER_THROTTLE = 10000.0 * 1.625 / 60000.0

SCENES = [
    ("flying, far above", {"altitude": 5000.0}, []),
    ("flying, hovering 3 m up", {"altitude": 3.0, "vertical_speed": 0.0},
     [{"t": 0.0, "throttle": HOVER_THROTTLE}]),
    ("flying, hovering 1 m up (feet in reach)", {"altitude": 1.0, "vertical_speed": 0.0},
     [{"t": 0.0, "throttle": HOVER_THROTTLE}]),
    ("bouncing upright (20-49 m/s)", {"altitude": 0.3, "vertical_speed": "bounce"}, []),
    ("contact, upright at rest", {"state": "contact", "altitude": -0.01625}, []),
    ("contact, sliding at 3 m/s", {"state": "contact", "altitude": -0.01625,
                                   "horizontal_speed": 3.0}, []),
    ("contact, tilted 20 deg, rocking", {"state": "contact", "altitude": -0.01625,
                                         "tilt_deg": 20.0}, []),
    ("landed", {"state": "landed"}, []),
    ("tipped", {"state": "tipped", "tilt_deg": 90.0}, []),
]

TOUCHDOWNS = "300 touchdowns of 20 s"


def ships_in_state(ini, inputs, n_ships):
    """``n_ships`` ships of a state scene, a metre apart; a "bounce" vertical speed spread over
    20-49 m/s down."""
    ships = []
    for i in range(n_ships):
        init = {**ini, "east": float(i)}
        if init.get("vertical_speed") == "bounce":
            init["vertical_speed"] = -(20.0 + 29.0 * i / max(n_ships - 1, 1))
        ships.append({"id": f"s{i}", "initial": init, "inputs": inputs})
    return ships


def state_cost(ini, inputs, n_ships, n_ticks, dt, repeat):
    from touchdown.sim.run import run_blocks
    from touchdown.sim.scenario import parse
    scn = parse({"name": "cost", "duration": n_ticks * dt,
                 "ships": ships_in_state(ini, inputs, n_ships), "sim": {"dt": dt}}, "bench")
    next(iter(run_blocks(scn, last_tick=1)))
    best = float("inf")
    for _ in range(repeat):
        t0 = time.process_time()
        for _block in run_blocks(scn):
            pass
        best = min(best, time.process_time() - t0)
    return best / (n_ships * n_ticks) * 1e6


def touchdowns_cost(n_cases, repeat, workers=1):
    from touchdown import scenarios
    from touchdown.sweep.cases import Axis, Sweep
    from touchdown.sweep.fleet import run_part
    import tomllib
    doc = tomllib.loads(scenarios.text("envelope"))
    axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
            Axis("ships.initial.horizontal_speed", 0.0, 6.0),
            Axis("ships.initial.tilt_deg", 0.0, 15.0)]
    sw = Sweep.of(doc, "envelope", axes, samples=n_cases, seed=1)
    run_part(sw, [0])  # kernels loaded
    n_ticks = int(round(float(doc["duration"]) / 0.05))
    best = float("inf")
    for _ in range(repeat):
        t0 = time.process_time()
        res = run_part(sw, list(range(n_cases)))
        best = min(best, time.process_time() - t0)
    outcomes = {}
    for o in res["state"]:
        outcomes[int(o)] = outcomes.get(int(o), 0) + 1
    return best / (n_cases * n_ticks) * 1e6, outcomes


def compare(others: list[str], rounds: int = 2, ships: int = 1000, ticks: int = 40,
            cases: int = 300, repeat: int = 2) -> dict[str, dict[str, float]]:
    """The table for this install and for each interpreter of ``others`` (another checkout's
    ``.venv/bin/python``, e.g. 0.7.0's), each a fresh process running this file, alternating
    ``rounds`` times; the least of each row over the rounds. Returns {label: {row: us}}."""
    import os
    import subprocess
    import sys
    import tempfile
    me = os.path.abspath(__file__)
    pythons = [("this", sys.executable)] + [(o, o) for o in others]
    best: dict[str, dict[str, float]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(rounds):
            for label, py in pythons:
                out = os.path.join(tmp, f"{r}-{len(best)}.json")
                subprocess.run([py, me, "--ships", str(ships), "--ticks", str(ticks), "--cases",
                                str(cases), "--repeat", str(repeat), "--json", out],
                               check=True, capture_output=True, cwd=tmp)
                with open(out) as f:
                    got = json.load(f)
                row = best.setdefault(label, {})
                row["version"] = got["version"]
                for k, v in got["rows"].items():
                    row[k] = min(row.get(k, float("inf")), v)
    return best


def print_comparison(best: dict[str, dict[str, float]]) -> None:
    """The table: a column per install (this first), then each other's cost over this one's
    (how many times cheaper this is)."""
    labels = list(best)
    names = [("this " if k == "this" else "") + str(best[k]["version"]) for k in labels]
    print(f"  {'state':<40}" + "".join(f"{n:>14}" for n in names)
          + "".join(f"{n + ' / this':>20}" for n in names[1:]))
    for row in [label for label, _, _ in SCENES] + [TOUCHDOWNS]:
        vals = [best[k].get(row, float("nan")) for k in labels]
        print(f"  {row:<40}" + "".join(f"{v:>14.2f}" for v in vals)
              + "".join(f"{vals[j] / vals[0]:>19.2f}x" for j in range(1, len(vals))))


def _version() -> str:
    from importlib.metadata import version
    try:
        return version("touchdown")
    except Exception:
        return "?"


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--ships", type=int, default=1000)
    ap.add_argument("--ticks", type=int, default=40)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--cases", type=int, default=300)
    ap.add_argument("--only", default="", help="comma-separated row numbers (0-8)")
    ap.add_argument("--json", default="")
    ap.add_argument("--against", action="append", default=[],
                    help="another install's python (repeatable): the table beside it")
    ap.add_argument("--rounds", type=int, default=2)
    a = ap.parse_args(argv)
    if a.against:
        print_comparison(compare(a.against, a.rounds, a.ships, a.ticks, a.cases, a.repeat))
        return
    rows = {}
    only = {int(x) for x in a.only.split(",") if x}
    for k, (label, ini, inputs) in enumerate(SCENES):
        if only and k not in only:
            continue
        rows[label] = state_cost(ini, inputs, a.ships, a.ticks, 0.05, a.repeat)
        print(f"{label:<40}{rows[label]:8.2f} us", flush=True)
    if not only or len(SCENES) in only:
        c, outcomes = touchdowns_cost(a.cases, a.repeat)
        rows[TOUCHDOWNS] = c
        print(f"{TOUCHDOWNS:<40}{c:8.2f} us  {outcomes}", flush=True)
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"version": _version(), "rows": rows}, f)


if __name__ == "__main__":
    main()
