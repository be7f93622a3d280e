"""``touchdown bench sweep``: what the sweep's accuracy costs, charted one against the other.

The issue's envelope (``scenarios/envelope.toml``: vertical -12 to -1 m/s, sideways 0 to 6 m/s,
tilt 0 to 15 deg; Latin hypercube, seed 1; 20 s a case) is swept in this process at the default
settings and at coarser and finer ones (:data:`VARIANTS`). For each: the CPU a case costs (the
least of ``rounds`` runs of every case, one process, the kernels loaded first) and its table
against the finest's (MODEL-NOTES 57's fine run: 5 ms sub-steps, 1 ms in an impact, no coarse
sub-steps, 0.1 ms stiff pieces), which stands in for the converged answer: how many cases end in
another outcome (landed, tipped, ...), and over the cases whose outcome agrees, the median and
90th-percentile relative error of each result column.

What it answers for a designer: how much cheaper a coarser setting makes an envelope, and what it
gets wrong; for issue 36 (100,000 cases in 30 s on two cores): where on this curve that time
lies. Every setting is a run-time one (``--set`` on ``touchdown sweep``): the same kernels.
Writes ``sweep_precision.md`` and ``sweep_precision.png`` into ``--out``.
"""
from __future__ import annotations

import os
import time
import tomllib

import numpy as np

from touchdown.bench.speed import machine

#: (label, the ``--set`` overrides, what the setting is). The first is the reference.
VARIANTS = (
    ("fine", {"sim.max_substep": 0.005, "sim.impact_substep": 0.001, "sim.coarse_substep": 0.0,
              "sim.stiff_substep": 0.0001}, "the reference: 5 ms sub-steps, 1 ms in an impact"),
    ("default", {}, "the default settings"),
    ("no impact sub-steps", {"sim.impact_substep": 0.0},
     "25 ms sub-steps in an impact too (sim.impact_substep=0)"),
    ("50 ms, no impact sub-steps", {"sim.impact_substep": 0.0, "sim.max_substep": 0.05},
     "one 50 ms sub-step a tick (sim.max_substep=0.05 sim.impact_substep=0)"),
    ("seed's method", {"sim.integrator": "semi_implicit_euler"},
     "semi-implicit Euler in place of the hybrid method (sim.integrator)"),
    ("seed's method, 50 ms", {"sim.integrator": "semi_implicit_euler",
                              "sim.impact_substep": 0.0, "sim.max_substep": 0.05},
     "both"),
)
#: the result columns compared (SPEC.md section 6), where both tables have a value
COLUMNS = ("t_outcome", "max_tilt_deg", "slide_distance", "max_penetration",
           "peak_normal_force", "energy_dissipated_j")
AXES = (("ships.initial.vertical_speed", -12.0, -1.0),
        ("ships.initial.horizontal_speed", 0.0, 6.0),
        ("ships.initial.tilt_deg", 0.0, 15.0))


def sweep_of(overrides: dict, cases: int, seed: int = 1):
    """The issue's envelope sweep of ``cases`` samples with ``overrides`` set."""
    from touchdown import scenarios
    from touchdown.sim.scenario import apply_overrides
    from touchdown.sweep.cases import Axis, Sweep
    doc = apply_overrides(tomllib.loads(scenarios.text("envelope")), overrides, "bench")
    return Sweep.of(doc, "envelope", [Axis(k, lo, hi) for k, lo, hi in AXES], samples=cases,
                    seed=seed)


def run_variant(overrides: dict, cases: int, rounds: int) -> tuple[dict, float]:
    """(the table's columns, the least CPU seconds of ``rounds`` runs of every case)."""
    from touchdown.sweep.fleet import run_part
    sw = sweep_of(overrides, cases)
    best, cols = float("inf"), None
    for _ in range(rounds):
        t0 = time.process_time()
        cols = run_part(sw, np.arange(cases))
        best = min(best, time.process_time() - t0)
    return cols, best


def compare(ref: dict, got: dict) -> dict:
    """``got``'s table against ``ref``'s: outcomes that differ, and per column the median and
    90th percentile of |got - ref| / |ref| over the cases whose outcome agrees (both finite)."""
    same = ref["state"] == got["state"]
    out = {"differ": int(np.sum(~same)), "n": int(same.size)}
    for c in COLUMNS:
        a, b = np.asarray(ref[c], float), np.asarray(got[c], float)
        m = same & np.isfinite(a) & np.isfinite(b)
        rel = np.abs(b[m] - a[m]) / np.maximum(np.abs(a[m]), 1e-12)
        out[c] = (float(np.median(rel)), float(np.percentile(rel, 90))) if m.any() else (
            float("nan"), float("nan"))
    return out


def measure(cases: int, rounds: int) -> list[dict]:
    """Every variant's CPU a case and its comparison with the first (the reference)."""
    run_variant({}, 2, 1)  # the kernels loaded (or compiled) before any timing
    rows, ref = [], None
    for label, overrides, what in VARIANTS:
        cols, cpu_s = run_variant(overrides, cases, 1 if ref is None else rounds)
        if ref is None:
            ref = cols
        rows.append({"label": label, "what": what, "ms_per_case": 1e3 * cpu_s / cases,
                     **compare(ref, cols)})
    return rows


def table(rows: list[dict]) -> str:
    """The rows as a Markdown table, with the time 100,000 cases would take on two cores."""
    base = next(r for r in rows if r["label"] == "default")["ms_per_case"]
    head = ("| setting | CPU ms a case | default / it | 100,000 on 2 cores, s | outcomes off "
            "| t_outcome med / p90 | slide med / p90 | max tilt med / p90 |")
    lines = [head, "|" + " --- |" * 8]
    for r in rows:
        ref = r["label"] == "fine"
        lines.append(
            f"| {r['label']} | {r['ms_per_case']:.2f} | {base / r['ms_per_case']:.2f}x | "
            f"{r['ms_per_case'] * 100_000 / 2e3:.0f} | "
            + ("(reference) | | | |" if ref else
               f"{r['differ']} ({100.0 * r['differ'] / r['n']:.1f}%) | "
               + " | ".join(f"{r[c][0]:.1e} / {r[c][1]:.1e}"
                            for c in ("t_outcome", "slide_distance", "max_tilt_deg")) + " |"))
    return "\n".join(lines)


def chart(rows: list[dict], path: str) -> None:
    """CPU a case against the share of outcomes that differ from the reference's."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for r in rows[1:]:
        share = 100.0 * r["differ"] / r["n"]
        ax.scatter(r["ms_per_case"], max(share, 0.01), s=60,
                   marker="*" if r["label"] == "default" else "o")
        ax.annotate(r["label"], (r["ms_per_case"], max(share, 0.01)), fontsize=8,
                    xytext=(5, 4), textcoords="offset points")
    aim_ms = 2 * 30.0 / 100_000 * 1e3  # issue 36: 100,000 cases in 30 s on two cores
    ax.axvline(aim_ms, linestyle="--", color="grey")
    ax.annotate("100,000 in 30 s\non 2 cores", (aim_ms, 1.0), fontsize=8, xytext=(4, 0),
                textcoords="offset points", color="grey")
    ax.set_xlim(left=0.0)
    ax.set_yscale("log")
    ax.set_xlabel("CPU a case, ms (one process)")
    ax.set_ylabel("outcomes unlike the fine reference's, % (log)")
    ax.set_title("touchdown sweep: cost against accuracy (the issue's envelope)")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(quick: bool = False, cases: int | None = None, rounds: int = 2,
         out_dir: str | None = "docs") -> list[dict]:
    n = cases or (60 if quick else 2000)
    rows = measure(n, 1 if quick else rounds)
    text = table(rows)
    print(f"touchdown sweep, cost against accuracy: {n:,} envelope cases a setting, one process "
          f"(least of {1 if quick else rounds} runs); {machine()}")
    print(text)
    print("(outcomes off: cases ending in another state than the fine reference's; the errors "
          "are relative, over the cases whose outcome agrees; 100,000 on 2 cores: the CPU a case "
          "x 100,000 / 2, without the processes' start)")
    if out_dir:
        os.makedirs(out_dir, exist_ok=True)
        with open(os.path.join(out_dir, "sweep_precision.md"), "w") as f:
            f.write(f"{n:,} envelope cases a setting, one process; {machine()}\n\n{text}\n\n"
                    + "\n".join(f"- {r['label']}: {r['what']}" for r in rows) + "\n")
        try:
            chart(rows, os.path.join(out_dir, "sweep_precision.png"))
        except ImportError:
            print("the chart: skipped (matplotlib: pip install -e '.[bench]')")
    return rows
