"""Which of note 58's two rules (sim.flight.at_transition) fires in the striking ticks of envelope
touchdowns, by the feet's sliding pattern at the tick's start (issue 36, session 14, fast42d):
"H" a holding foot at NEAR_CONE of its cone, "S" a sliding foot not slowing that its own friction
could stop within TRANSITION_PIECE stiff_substep; with the number of holding feet. For the holding
rule with two holding feet, the pair's least use of its cones over the split along their joining
line (which changes neither their force nor their moment) against the feet's own; for the sliding
rule, each such foot's slip, stop time, and whether it is itself the stiffest foot. Run on the
uncompiled copy of a tree with transition_variants.patch applied (at_transition's sixth parameter):
    TD_PY=1 PYTHONPATH=/tmp/plain.pkg python transition_fires.py [STRIDE]"""
import collections, sys, tomllib, math
import numpy as np
from touchdown import scenarios
from touchdown.sim.run import run
from touchdown.sim.scenario import parse
from touchdown.sim.step import step
from touchdown.sweep.cases import Axis, Sweep
import touchdown.sim.flight as fl
import touchdown.sim.phases as ph
from touchdown.sim.vec import norm, sub, scale, dot, unit
from touchdown.sim.contact import foot_offsets_w

C = collections.Counter()
USES = []
SLIDE = []
orig = fl.at_transition
def pair_least(F, e, c):
    # lambda interval for |F_i + l e| <= c_i (sign s): returns (lo, hi) or None
    lo, hi = -math.inf, math.inf
    for (Fi, s, ci) in zip(F, (1.0, -1.0), c):
        b = s * dot(Fi, e); d = b * b - dot(Fi, Fi) + ci * ci
        if d < 0: return None
        r = math.sqrt(d); a1, a2 = s * (-b - r), s * (-b + r)
        lo, hi = max(lo, min(a1, a2)), min(hi, max(a1, a2))
    return (lo, hi) if lo <= hi else None
def least_use(F, e, load, mu):
    lo, hi = 0.0, 3.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if pair_least(F, e, [mid * mu * L for L in load]) is None: lo = mid
        else: hi = mid
    return hi
def at_wrap(cfg, fb, start, sr, h, *rest):
    r = orig(cfg, fb, start, sr, h, *rest)
    if not STRIKE[0]: return r
    ft, ce, drag, q = start.ship.footing, start.ce, start.drag, start.ship.motion.q
    mu = cfg.friction_static
    holdrule, sliderule, held = [], [], []
    for i in range(4):
        load = ce.foot_force_n[i] * ce.push_norm[i]
        if not load > 0.0: continue
        if not ft.sliding[i] and not drag[i]:
            held.append(i)
            n = ce.normal_w[i]; F = sub(ft.hold_w[i], scale(n, dot(ft.hold_w[i], n)))
            if norm(ft.hold_w[i]) >= fl.NEAR_CONE * mu * load: holdrule.append(i)
        elif not fl.slowing(sr, i) and fl._could_stop(cfg, fb, ce, ce, q, i, fl.TRANSITION_PIECE * h):
            sliderule.append(i)
    if sliderule and STRIKE[0]:
        pat0 = "".join(str(int(b)) for b in ft.sliding)
        sl = [k for k in range(4) if ce.foot_force_n[k] * ce.push_norm[k] > 0.0 and (ft.sliding[k] or drag[k])]
        ts = {k: fl._stop_time(cfg, fb, ce, q, k) for k in sl}
        stiff = min(ts, key=ts.get) if ts else -1
        for k in sliderule:
            huse = max([norm(ft.hold_w[m]) / (mu * ce.foot_force_n[m] * ce.push_norm[m]) for m in held] or [-1.0])
            SLIDE.append((pat0, k, norm(ce.slip_w[k]), ts.get(k, -1), k == stiff, len(sl), bool(drag[k]), bool(ft.sliding[k]),
                          ce.foot_force_n[k] * ce.push_norm[k], sr.rate[k], sr.own[k], huse))
    pat = "".join(str(int(b)) for b in ft.sliding)
    C[(pat, "asked")] += 1
    if r:
        kind = ("H" if holdrule else "") + ("S" if sliderule else "")
        C[(pat, "fire", kind, len(held))] += 1
        if holdrule and len(held) == 2:
            i, j = held
            off = foot_offsets_w(q, fb.craft.leg_radius_m, fb.craft.com_height_m)
            n = ce.normal_w[i]
            e = sub(off[j], off[i]); e = unit(sub(e, scale(n, dot(e, n))))
            Fs = [sub(ft.hold_w[k], scale(ce.normal_w[k], dot(ft.hold_w[k], ce.normal_w[k]))) for k in (i, j)]
            loads = [ce.foot_force_n[k] * ce.push_norm[k] for k in (i, j)]
            own = max(norm(Fs[0]) / (mu * loads[0]), norm(Fs[1]) / (mu * loads[1]))
            USES.append((pat, i, j, own, least_use(Fs, e, loads, mu), bool(sliderule)))
    return r
fl.at_transition = at_wrap
STRIKE = [False]
orig_strike = ph.striking
def strike_wrap(*a, **k):
    r = orig_strike(*a, **k)
    STRIKE[0] = STRIKE[0] or bool(r)
    return r
ph.striking = strike_wrap
stride = int(sys.argv[1]) if len(sys.argv) > 1 else 30
doc = tomllib.loads(scenarios.text("envelope"))
axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0), Axis("ships.initial.horizontal_speed", 0.0, 6.0), Axis("ships.initial.tilt_deg", 0.0, 15.0)]
sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)
for c in range(0, 300, stride):
    batch = parse(sw.case_doc(c), "one")
    recs = list(run(batch))
    for r0, r1 in zip(recs[:-1], recs[1:]):
        row = r0.state.rows[0]
        if int(row["surface_state"]) not in (0, 1): continue
        STRIKE[0] = False
        step(batch.params, r0.state, r1.inputs)
n = len(range(0, 300, stride))
for k, v in sorted(C.items(), key=lambda kv: -kv[1]):
    print(k, round(v / n, 2))
U = np.array([(u[3], u[4]) for u in USES]) if USES else np.zeros((0, 2))
print("pair hold-rule fires:", len(USES) / n, "a case")
if len(U):
    print("own use quantiles", np.percentile(U[:, 0], [10, 50, 90]))
    print("pair least use quantiles", np.percentile(U[:, 1], [10, 50, 90]))
    print("pair least >= 0.9:", np.mean(U[:, 1] >= 0.9), " also slide rule:", np.mean([u[5] for u in USES]))
    print("pair least >= 0.9 and no slide rule:", np.mean([(u[4] >= 0.9) or u[5] for u in USES]))
S = SLIDE
print("slide-rule feet:", len(S) / n, "a case")
for pat in ("1010", "0101", "1000", "0010"):
    T = [x for x in S if x[0] == pat]
    if not T: continue
    sp = np.array([x[2] for x in T])
    print(pat, len(T) / n, "speed quantiles mm/s", np.percentile(1e3 * sp, [10, 50, 90, 99]),
          "is the stiff one", np.mean([x[4] for x in T]), "n sliding", np.mean([x[5] for x in T]),
          "below stick", np.mean(sp <= 1e-4), "t_stop q us", np.percentile([1e6 * x[3] for x in T], [10, 50, 90]))
    hu = np.array([x[11] for x in T]); print("   holding feet's largest use of their cones: none", np.mean(hu < 0), "quantiles", np.percentile(hu[hu >= 0], [10, 50, 90, 99]) if np.any(hu >= 0) else "", "share >= 0.5", np.mean(hu >= 0.5))
import pickle; pickle.dump((dict(C), USES, SLIDE), open("/tmp/transition_fires.pkl", "wb"))
