"""The 300 envelope touchdowns' outcome columns (bench/states.py's workload) under sim settings,
saved for comparison between settings and versions:

    python envelope_columns.py OUT.npz [KEY=VALUE ...]     # e.g. clear_tick=false
    python envelope_columns.py --fine OUT.npz              # the fine run: max_substep 5 ms,
                                                           # impact_substep 1 ms, stiff 0.1 ms
    python envelope_columns.py --compare A.npz B.npz [REF.npz]

--compare prints, for each column, the largest and p90 difference between A and B (and each
one's against REF, the fine run, where given), and how many outcomes differ."""
import sys
import tomllib

import numpy as np

FINE = {"max_substep": 0.005, "impact_substep": 0.001, "coarse_substep": 0.0,
        "stiff_substep": 0.0001}
COLS = ("t_outcome", "max_tilt_deg", "slide_distance", "max_penetration", "peak_normal_force",
        "energy_dissipated_j")


def value(text):
    low = text.lower()
    if low in ("true", "false"):
        return low == "true"
    try:
        return float(text)
    except ValueError:
        return text


def run(out, overrides):
    from touchdown import scenarios
    from touchdown.sweep.cases import Axis, Sweep
    from touchdown.sweep.fleet import run_part
    doc = tomllib.loads(scenarios.text("envelope"))
    doc.setdefault("sim", {}).update(overrides)
    axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
            Axis("ships.initial.horizontal_speed", 0.0, 6.0),
            Axis("ships.initial.tilt_deg", 0.0, 15.0)]
    sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)
    cols = run_part(sw, list(range(300)))
    np.savez(out, **{k: np.asarray(v) for k, v in cols.items()})


def compare(a_path, b_path, ref_path=None):
    a, b = np.load(a_path, allow_pickle=True), np.load(b_path, allow_pickle=True)
    ref = np.load(ref_path, allow_pickle=True) if ref_path else None
    print(f"outcomes differing: {int(np.sum(a['state'] != b['state']))} of {len(a['state'])}")
    for c in COLS:
        x, y = a[c].astype(float), b[c].astype(float)
        ok = np.isfinite(x) & np.isfinite(y)
        d = np.abs(x[ok] - y[ok])
        line = f"{c:22s} A-B max {d.max():.3g} p90 {np.percentile(d, 90):.3g}"
        if ref is not None:
            r = ref[c].astype(float)
            for name, z in (("A", x), ("B", y)):
                okr = np.isfinite(z) & np.isfinite(r)
                e = np.abs(z[okr] - r[okr])
                line += f" | {name}-fine max {e.max():.3g} p90 {np.percentile(e, 90):.3g}"
        print(line)


if __name__ == "__main__":
    args = sys.argv[1:]
    if args[0] == "--compare":
        compare(*args[1:])
    elif args[0] == "--fine":
        run(args[1], dict(FINE, **{k: value(v) for k, v in (x.split("=", 1) for x in args[2:])}))
    else:
        run(args[0], {k: value(v) for k, v in (x.split("=", 1) for x in args[1:])})
