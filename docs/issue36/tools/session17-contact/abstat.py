import sys, statistics as st
# abba log: per round A B B A; ratio B/A of pair sums per round
rows = {}
for ln in open(sys.argv[1]):
    p = ln.split()
    rows.setdefault(int(p[0]), []).append((p[1], [float(x) for x in p[2:5]]))
names = ["sliding", "rocking", "touchdowns"]
A = rows[1][0][0]; B = rows[1][1][0]
for k, nm in enumerate(names):
    rs = []; amin = bmin = 1e9
    for r, runs in rows.items():
        a = [v[k] for n, v in runs if n == A]; b = [v[k] for n, v in runs if n == B]
        if len(a) == 2 and len(b) == 2:
            rs.append(sum(b) / sum(a)); amin = min(amin, *a); bmin = min(bmin, *b)
    print(f"{nm:11s} {A} min {amin:.2f}  {B} min {bmin:.2f}  {B}/{A} per round: mean {st.mean(rs):.3f} median {st.median(rs):.3f} (n={len(rs)}, range {min(rs):.3f}-{max(rs):.3f})")
