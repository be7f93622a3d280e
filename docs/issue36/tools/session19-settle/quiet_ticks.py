"""The envelope touchdowns' quiet contact ticks (in contact, no foot sliding at the tick's start),
restarted from their recorded states (issue 36, session 19, helper settle).

    python quiet_ticks.py LIST.json [PATH[,PATH]] [COPIES]        # CPU: us a ship-tick by path
    (import) ticks(LIST, paths, copies) -> [(params, State, Inputs)], work(items)

LIST.json: [[case, tick, path], ...] as quiet_counts.py writes it (path: strike / coarse / fine,
which of step_ship's ways the tick took at the start's bits). Each tick is stepped (sim.step.step)
from its recorded state for COPIES copies of the ship in one batch."""
import copy
import os
import json
import sys
import time
import tomllib

import numpy as np

from touchdown import scenarios
from touchdown.sim.run import run
from touchdown.sim.scenario import parse
from touchdown.sim.state import Inputs, State
from touchdown.sim.step import step
from touchdown.sweep.cases import Axis, Sweep


def ticks(listed, paths=None, copies=4):
    doc = tomllib.loads(scenarios.text("envelope"))
    axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
            Axis("ships.initial.horizontal_speed", 0.0, 6.0),
            Axis("ships.initial.tilt_deg", 0.0, 15.0)]
    sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)
    want = {}
    for c, t, p in listed:
        if paths is None or p in paths:
            want.setdefault(c, []).append((t, p))
    items = []
    # $QUIET_RECORD_SIM (KEY=VALUE,...): sim settings of the recording run only (the ticks
    # restarted from another tree's bits, e.g. coarse_held=2 for the start's)
    rec_sim = dict(kv.split("=", 1) for kv in os.environ.get("QUIET_RECORD_SIM", "").split(",") if kv)
    for c, ts in sorted(want.items()):
        one = sw.case_doc(c)
        rec_doc = copy.deepcopy(one)
        rec_doc.setdefault("sim", {}).update({k: float(v) for k, v in rec_sim.items()})
        many = copy.deepcopy(one)
        many["ships"] = [dict(copy.deepcopy(one["ships"][0]), id=f"s{i}") for i in range(copies)]
        batch = parse(many, "batch")
        recs = list(run(parse(rec_doc, "one")))
        by = {r.tick: i for i, r in enumerate(recs)}
        for t, p in ts:
            r0, r1 = recs[by[t]], recs[by[t] + 1]
            assert int(r0.state.rows[0]["surface_state"]) == 1
            items.append((batch.params, State(rows=np.repeat(r0.state.rows, copies), tick=r0.state.tick),
                          Inputs(rows=np.repeat(r1.inputs.rows, copies)), p))
    return items


def work(items):
    for params, st, inp, _p in items:
        step(params, st, inp)


if __name__ == "__main__":
    listed = json.load(open(sys.argv[1]))
    paths = sys.argv[2].split(",") if len(sys.argv) > 2 and sys.argv[2] != "all" else None
    copies = int(sys.argv[3]) if len(sys.argv) > 3 else 100
    items = ticks(listed, paths, copies)
    work(items[:5])
    for p in sorted(set(i[3] for i in items)):
        sub = [i for i in items if i[3] == p]
        best = []
        for it in sub:
            b = float("inf")
            for _ in range(3):
                t0 = time.process_time()
                work([it])
                b = min(b, time.process_time() - t0)
            best.append(b)
        print(f"{p:7s} ticks {len(sub):5d}  us a ship-tick {sum(best) / len(sub) / copies * 1e6:7.2f}"
              f"  share-weight {sum(best) / copies * 1e6:9.0f} us")
