"""abba.py ROUNDS PY_A PY_B [ROWS]: bench/states.py --only ROWS (default 4,6,9: at rest, rocking,
the 300 touchdowns) run by two interpreters alternately, A B B A a round; CPU us a ship-tick per
run, each row's B/A ratio per round (> 1: A cheaper). Run from the tree whose bench/states.py to
use (the file imports only what older installs have)."""
import json
import os
import statistics
import subprocess
import sys
import tempfile

rounds, py_a, py_b = int(sys.argv[1]), sys.argv[2], sys.argv[3]
only = sys.argv[4] if len(sys.argv) > 4 else "4,6,9"
me = os.path.abspath("bench/states.py")
res = {"A": [], "B": []}
with tempfile.TemporaryDirectory() as tmp:
    for r in range(rounds):
        per = {"A": [], "B": []}
        for lab in ("A", "B", "B", "A"):
            out = os.path.join(tmp, "o.json")
            subprocess.run([py_a if lab == "A" else py_b, me, "--only", only, "--ships", "500",
                            "--ticks", "40", "--cases", "300", "--repeat", "2", "--json", out],
                           check=True, capture_output=True, cwd=tmp)
            per[lab].append(json.load(open(out))["rows"])
        for lab in per:
            res[lab].append({k: sum(x[k] for x in per[lab]) / 2 for k in per[lab][0]})
        load = os.getloadavg()[0]
        print(f"round {r}: load {load:.1f} " + "  ".join(
            f"{k[:18]}: A {res['A'][-1][k]:.3f} B {res['B'][-1][k]:.3f} B/A {res['B'][-1][k] / res['A'][-1][k]:.3f}"
            for k in res["A"][-1]), flush=True)
for k in res["A"][0]:
    ratios = [b[k] / a[k] for a, b in zip(res["A"], res["B"])]
    print(f"{k:40s} A least {min(a[k] for a in res['A']):.3f} B least {min(b[k] for b in res['B']):.3f}"
          f"  B/A mean {statistics.mean(ratios):.3f} median {statistics.median(ratios):.3f}"
          f" range {min(ratios):.3f}-{max(ratios):.3f}")
