import json, glob, sys
def load(L):
    d = {}
    for f in glob.glob(f"/tmp/substep/approx-{L}-*.json"):
        d.update(json.load(open(f)))
    return d
labels = sys.argv[1:]
ds = [load(L) for L in labels]
keys = sorted(set().union(*ds), key=lambda k: -max(d.get(k, (0,))[0] for d in ds))
print("worst |err|/tol per test (approx asserts):", " ".join(f"{L:>9s}" for L in labels))
for k in keys[:int(40)]:
    print(f"{k[-95:]:95s}", " ".join(f"{d[k][0]:9.3f}" if k in d else "        -" for d in ds))
