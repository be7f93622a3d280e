"""Work-precision benchmark: ``touchdown bench accuracy [--quick] [--out DIR]``.

For each method and tick, canonical scenes are run and compared with independent references
(``bench/reference.py``: the exact piecewise bounce, a pivot ODE, Coulomb's law, the static sag):

    apex_20, apex_45        first apex of a 20 / 45 m/s lunar impact (relative error)
    separation_45           separation speed of the 45 m/s impact
    penetration_45          deepest penetration of the 45 m/s impact
    contact_20              duration of the first contact of the 20 m/s impact
    slide                   stopping distance of a 5 m/s slide (v^2 / 2 mu_k g)
    topple                  time to tip from 5 deg past the critical angle (pivot ODE)

against the CPU time per simulated second. Writes ``work_precision.png`` (one panel per measure,
one curve per method), ``work_precision.csv`` and ``work_precision.md`` into ``--out``.
Methods are run plain (one step per tick, the stability guard off) so that each curve is the
method itself; "rk4 + sub-steps" is the default configuration (25 ms contact sub-steps).
"""
from __future__ import annotations

import csv
import math
import os
import time

import numpy as np

from bench.reference import bounce_ode, critical_angle_rad, topple_time
from bench.speed import machine
from sim.enums import EventKind
from sim.run import run
from sim.scenario import parse

MOON_GM, MOON_R = 4.9048695e12, 1737400.0
G = MOON_GM / MOON_R ** 2
PLAIN = ["explicit_euler", "semi_implicit_euler", "velocity_verlet", "rk4"]
DEFAULT = "rk4 + sub-steps"


def _doc(initial, sim, duration, ship=None, contact=None):
    return {"name": "accuracy", "duration": duration, "sim": sim, "contact": contact or {},
            "ships": [{"id": "s", **(ship or {}), "initial": initial}]}


def _run(doc):
    scn = parse(doc, "accuracy")
    t0 = time.process_time()
    recs = list(run(scn))
    return scn, recs, (time.process_time() - t0) / scn.params.sim.duration_s


def _events(recs):
    return [(r.tick, EventKind(e.kind), e.v_radial_mps) for r in recs for e in r.events]


def bounce_errors(sim, v0):
    alt0 = 0.3
    scn, recs, cost = _run(_doc({"altitude": alt0, "vertical_speed": -v0}, sim, 2 * v0 / G + 1.0))
    ref = bounce_ode(MOON_GM, MOON_R, math.sqrt(v0 * v0 + 2 * G * alt0))
    ev = _events(recs)
    if len(ev) < 2 or ev[0][1] != EventKind.CONTACT or ev[1][1] != EventKind.LIFTOFF:
        return cost, {}
    (t_c, _, _), (t_l, _, v_sep) = ev[0], ev[1]
    t_next = ev[2][0] if len(ev) > 2 else len(recs)
    alt = np.array([r.outputs.altitude_m[0] for r in recs])
    peak = max(r.outputs.peak_penetration_m[0] for r in recs[t_c:t_l + 1])
    dt = scn.params.sim.dt_s
    # contact duration from the tick times, refined by the crossing speeds at both ends
    t_in = t_c * dt - (-alt[t_c]) / max(abs(ev[0][2]), 1e-9)
    t_out = t_l * dt - alt[t_l] / max(v_sep, 1e-9)
    return cost, {"apex": abs(alt[t_l:t_next].max() / ref.apex_m - 1),
                  "separation": abs(v_sep / ref.separation_speed_mps - 1),
                  "penetration": abs(peak / ref.max_penetration_m - 1),
                  "contact": abs((t_out - t_in) / ref.contact_duration_s - 1)}


def slide_error(sim):
    v0, mu_k = 5.0, 0.5
    scn, recs, cost = _run(_doc({"state": "contact", "altitude": -G / 100.0, "horizontal_speed": v0},
                                sim, v0 / (mu_k * G) + 2.0, contact={"settle_linear_vel": 1e-3}))
    p0 = recs[0].state.pos_m[0]
    d = max(float(np.linalg.norm(r.state.pos_m[0] - p0)) for r in recs)
    return cost, abs(d / (v0 * v0 / (2 * mu_k * G)) - 1)


def topple_error(sim):
    h, a, m = 3.0, 2.26, 10000.0
    th0 = critical_angle_rad(h, a) + math.radians(5.0)
    scn, recs, cost = _run(_doc({"state": "contact", "altitude": -G / 100.0,
                                 "tilt_deg": math.degrees(th0)}, sim, 8.0))
    tipped = [t for t, k, _ in _events(recs) if k == EventKind.TIPPED]
    if not tipped:
        return cost, float("nan")
    i_t = m * (3 * a * a + (2 * h) ** 2) / 12.0
    ref = topple_time(G, m, i_t, h, a, th0, math.radians(80.0))
    return cost, abs(tipped[0] * scn.params.sim.dt_s / ref - 1)


def sweep(quick: bool):
    dts = [0.005, 0.02, 0.05, 0.1] if quick else [0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2]
    configs = [(m, dt, {"integrator": m, "dt": dt, "max_substep": 0.0, "on_unstable": "allow"})
               for m in PLAIN for dt in dts]
    configs += [(DEFAULT, dt, {"integrator": "rk4", "dt": dt, "max_substep": 0.025})
                for dt in dts if dt >= 0.02]
    rows = []
    for label, dt, sim in configs:
        with np.errstate(all="ignore"):
            c20, b20 = bounce_errors(sim, 20.0)
            c45, b45 = bounce_errors(sim, 45.0)
            cs, es = slide_error(sim)
            ct, et = topple_error(sim)
        nan = float("nan")
        for measure, err, cost in (
                ("apex_20", b20.get("apex", nan), c20), ("apex_45", b45.get("apex", nan), c45),
                ("separation_45", b45.get("separation", nan), c45),
                ("penetration_45", b45.get("penetration", nan), c45),
                ("contact_20", b20.get("contact", nan), c20), ("slide", es, cs),
                ("topple", et, ct)):
            rows.append({"measure": measure, "method": label, "dt_s": dt,
                         "relative_error": err, "cpu_s_per_sim_s": cost})
        print(f"  {label:<20} dt {dt:<6g} apex_20 {b20.get('apex', nan):.2e} "
              f"apex_45 {b45.get('apex', nan):.2e} slide {es:.2e} topple {et:.2e}", flush=True)
    return rows


def write(rows, out_dir: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(out_dir, exist_ok=True)
    with open(os.path.join(out_dir, "work_precision.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    measures = list(dict.fromkeys(r["measure"] for r in rows))
    methods = list(dict.fromkeys(r["method"] for r in rows))
    with open(os.path.join(out_dir, "work_precision.md"), "w") as f:
        f.write(f"Relative error against the references; cost in CPU seconds per simulated second. "
                f"Machine: {machine()}.\n\n")
        f.write("| method | dt (s) | cost (CPU s / sim s) | " + " | ".join(measures) + " |\n")
        f.write("|---|---|---|" + "---|" * len(measures) + "\n")
        for m in methods:
            for dt in sorted({r["dt_s"] for r in rows if r["method"] == m}):
                sel = {r["measure"]: r for r in rows if r["method"] == m and r["dt_s"] == dt}
                cost = sel[measures[0]]["cpu_s_per_sim_s"]
                cells = [("unstable" if not math.isfinite(sel[x]["relative_error"])
                          else f"{sel[x]['relative_error']:.1e}") for x in measures]
                f.write(f"| {m} | {dt:g} | {cost:.3f} | " + " | ".join(cells) + " |\n")
    cols = 4
    fig, axes = plt.subplots(math.ceil(len(measures) / cols), cols, figsize=(16, 7.5), dpi=100)
    for ax, measure in zip(axes.flat, measures):
        for m in methods:
            pts = sorted((r["cpu_s_per_sim_s"], r["relative_error"]) for r in rows
                         if r["measure"] == measure and r["method"] == m
                         and math.isfinite(r["relative_error"]) and r["relative_error"] > 0)
            if pts:
                x, y = zip(*pts)
                ax.loglog(x, y, "o-", label=m, lw=2 if m == DEFAULT else 1.2)
        ax.axhline(0.01, color="grey", ls=":", lw=1)
        ax.set_title(measure)
        ax.set_xlabel("CPU s per simulated s")
        ax.set_ylabel("relative error")
    for ax in list(axes.flat)[len(measures):]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=8)
    fig.suptitle("Touchdown work-precision: error against cost, the tick swept per method "
                 "(dotted: 1%)")
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "work_precision.png"))


def main(quick: bool = False, out_dir: str = "docs") -> None:
    print(f"machine: {machine()}")
    rows = sweep(quick)
    write(rows, out_dir)
    print(f"wrote {out_dir}/work_precision.png, .csv and .md")


if __name__ == "__main__":
    main()
