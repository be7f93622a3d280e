"""tick_costs.py's per-tick CPU times joined with strike_counts.py's per-tick counts (the same
STRIDE): each (state, sliding feet, striking) row's ticks a case, us a tick, share of the
touchdown, method steps, pieces and solves a tick, and us a method step (issue 36, session 13):

    python strike_join.py PER.pkl COSTS.pkl"""
import collections
import pickle
import sys

per = pickle.load(open(sys.argv[1], "rb"))
cost = pickle.load(open(sys.argv[2], "rb"))
n_cases = len({c for c, _ in cost})
rows = collections.defaultdict(lambda: [0, 0.0, 0, 0, 0])
total = 0.0
for k, us in cost.items():
    total += us
    key, counts = per.get(k, (("other",), {}))
    r = rows[key]
    r[0] += 1
    r[1] += us
    r[2] += counts.get("substep", 0)
    r[3] += counts.get("pieces", 0)
    r[4] += counts.get("solves", 0)
striking = sum(v[1] for k, v in rows.items() if len(k) == 3 and k[2] == "S")
print(f"{total / n_cases:.0f} us a touchdown; ticks that strike {100 * striking / total:.1f}%")
print("key                  ticks/case  us/tick  share  steps/tick pieces solves  us/step")
for k, (n, us, st, pc, so) in sorted(rows.items(), key=lambda kv: -kv[1][1]):
    print(f"{str(k):20s} {n / n_cases:10.1f} {us / n:8.1f} {100 * us / total:5.1f}% "
          f"{st / n:10.1f} {pc / n:6.1f} {so / n:6.1f} {us / max(st, 1):8.2f}")
