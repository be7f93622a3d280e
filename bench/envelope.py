"""``touchdown bench envelope``: the stand / tip boundary over sideways speed (and slope), from
three engines: Touchdown (a sweep), the planar four-foot reference (bench/planar.py: scipy's
Radau on the regularised Coulomb law per foot, mu_s 0.8 / mu_k 0.5) and MuJoCo (the bench
extra's lander, bench/mujoco_side.py: four sphere feet on soft contacts, one friction coefficient
per contact, run at 0.5 and at 0.8, the seed's kinetic and static values).

The scene: the default lander (10 t, centre of mass 3 m above the feet, feet 2.26 m out) touches
down upright (its long axis along local vertical) with its feet at the ground, descending at
V_DOWN, moving sideways toward a foot at speed u, on ground that falls away in the direction of
motion at slope alpha (downhill). For each slope and engine the boundary is the smallest u at
which it tips over (its tilt from the ground's normal passes TIP_DEG: beyond the critical angle
atan(a / h) = 37 deg toward a foot the fall cannot be stopped), found by bisection on [0, U_MAX]
for the reference and MuJoCo, and read off a sweep for Touchdown. An engine that never tips on
[0, U_MAX] says so (">U_MAX"), one that tips at 0 says "0".

Needs the bench extra (``pip install -e '.[bench]'``: scipy, mujoco).
"""
from __future__ import annotations

import math
import time

import numpy as np

V_DOWN = 2.0  # m/s
U_MAX = 8.0  # m/s
TIP_DEG = 45.0
SLOPES_DEG = (0.0, 4.0, 8.0)
T_END_S = 8.0
BISECTIONS = 8  # U_MAX / 2^8 = 0.03 m/s


def _moon_g(com_height_m: float) -> float:
    from touchdown.sim.constants import MOON_RADIUS_M
    return 4.9048695e12 / (MOON_RADIUS_M + com_height_m) ** 2


# -- Touchdown ------------------------------------------------------------------------------------
def touchdown_boundary(slopes=SLOPES_DEG, n_speeds: int = 161) -> dict[float, float | None]:
    """The smallest swept sideways speed that tips, per slope (None: none on the grid), from one
    `touchdown sweep` over sideways speed x slope."""
    from touchdown.sweep.cases import Axis, Sweep
    from touchdown.sweep.run import run
    doc = {"name": "bench-envelope", "duration": T_END_S,
           "body": {"name": "Luna", "terrain": {"slope_deg": 0.0, "slope_azimuth_deg": 90.0}},
           "ships": [{"id": "lander", "initial": {"altitude": 1e-6, "vertical_speed": -V_DOWN,
                                                  "horizontal_speed": 0.0, "heading_deg": 90.0}}]}
    axes = [Axis("body.terrain.slope_deg", 0.0, 1.0, 1), Axis("ships.initial.horizontal_speed",
                                                             0.0, U_MAX, n_speeds)]
    sw = Sweep(doc, "bench", tuple(axes), values=np.array(
        [(s, u) for s in slopes for u in np.linspace(0.0, U_MAX, n_speeds)]))
    res = run(sw, workers=2)
    cols = res.columns
    out = {}
    for s in slopes:
        sel = sw.values[:, 0] == s
        tipped = cols["state"][sel] == 3
        speeds = sw.values[sel, 1]
        out[s] = float(speeds[np.argmax(tipped)]) if tipped.any() else None
        out[(s, "pattern")] = "".join("T" if t else "." for t in tipped[::8])
    return out


# -- the planar reference ---------------------------------------------------------------------------
def _planar_start(slope_deg: float, u: float):
    """Upright in the world, feet at the ground, (u sideways, V_DOWN down) in the world: in the
    slope's frame (X downhill along the ground, Z its normal)."""
    from touchdown.bench.planar import Start, foot_offsets
    a = math.radians(slope_deg)
    vx = u * math.cos(a) + V_DOWN * math.sin(a)
    vz = u * math.sin(a) - V_DOWN * math.cos(a)
    th = -a  # the long axis along local vertical: tilted uphill from the ground's normal
    ld = _planar_lander(slope_deg)
    z0 = -min(rz for _, rz, _ in foot_offsets(ld, th)) + 1e-6
    return Start(z_m=z0, theta_rad=th, vx_mps=vx, vz_mps=vz)


def _planar_lander(slope_deg: float, push_only: bool = False):
    """The reference's lander; ``push_only``: the ground only pushes (critically damped, as
    MuJoCo's contacts are set here) instead of the absorbers that hold a pressed foot down."""
    from touchdown.bench.planar import Lander
    extra = dict(zeta=1.0, bounce_speed_mps=0.0) if push_only else {}
    return Lander(g_mps2=_moon_g(3.0), mu_s=0.8, mu_k=0.5, eps_mps=1e-6,
                  slope_rad=math.radians(slope_deg), **extra)


def planar_tips(slope_deg: float, u: float, push_only: bool = False) -> bool:
    from touchdown.bench.planar import solve
    path = solve(_planar_lander(slope_deg, push_only), _planar_start(slope_deg, u), T_END_S,
                 tipped_rad=math.radians(TIP_DEG), rtol=1e-8, atol=1e-10)
    return path.tipped_t_s is not None


# -- MuJoCo ------------------------------------------------------------------------------------------
def mujoco_tips(slope_deg: float, u: float, friction: float, dt_s: float = 0.002) -> bool:
    """The lander on the tilted plane (gravity turned by the slope: X downhill, Z the normal).
    Its contacts are damped as Touchdown's leg absorbers take an impact under bounce_speed
    (absorb_damping_ratio, critical): with the bounce's zeta = 0.3 MuJoCo's lander bounces off
    at 2 m/s and comes down on one sphere foot, on which it rolls over (no rolling friction)."""
    import mujoco

    from touchdown.bench.mujoco_side import FOOT_RADIUS_M, lander_xml
    from touchdown.sim.scenario import parse
    scn = parse({"name": "x", "duration": 1.0, "ships": [{"id": "a"}]}, "bench")
    sh, cp = scn.params.ships, scn.params.contact
    g = _moon_g(3.0)
    a = math.radians(slope_deg)
    xml = lander_xml(float(sh.mass0_kg[0]), sh.inertia0_kgm2[0], float(sh.leg_radius_m[0]),
                     float(sh.com_height_m[0]), float(sh.stiffness_per_kg[0]),
                     cp.absorb_damping_ratio, dt_s=dt_s, friction=friction, gravity=g,
                     integrator="implicitfast")
    xml = xml.replace(f'gravity="0 0 {-g}"', f'gravity="{g * math.sin(a)} 0 {-g * math.cos(a)}"')
    # both geoms of a contact: MuJoCo takes the larger friction; the plane gets the same
    xml = xml.replace('<geom type="plane" size="0 0 1"',
                      f'<geom type="plane" size="0 0 1" friction="{friction} 0.005 0.0001"')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    h, leg = float(sh.com_height_m[0]), float(sh.leg_radius_m[0])
    th = -a  # turn about y by th: the long axis (0, 0, 1) -> (sin th, 0, cos th)
    data.qpos[3:7] = (math.cos(th / 2), 0.0, math.sin(th / 2), 0.0)
    # the lowest foot's sphere touching the plane
    lows = [-(x * math.sin(th)) - (h - FOOT_RADIUS_M) * math.cos(th) for x in (leg, -leg, 0.0)]
    data.qpos[2] = -min(lows) + FOOT_RADIUS_M + 1e-6
    data.qvel[0] = u * math.cos(a) + V_DOWN * math.sin(a)
    data.qvel[2] = u * math.sin(a) - V_DOWN * math.cos(a)
    cos_tip = math.cos(math.radians(TIP_DEG))
    for _ in range(int(T_END_S / dt_s)):
        mujoco.mj_step(model, data)
        w, x, y, z = data.qpos[3:7]
        if 1.0 - 2.0 * (x * x + y * y) < cos_tip:  # the long axis' z component
            return True
    return False


def boundary(tips, lo: float = 0.0, hi: float = U_MAX, n: int = BISECTIONS) -> float | None:
    """The smallest u in [lo, hi] at which ``tips(u)``, by bisection (None: not at hi; 0: at lo)."""
    if tips(lo):
        return 0.0
    if not tips(hi):
        return None
    for _ in range(n):
        mid = 0.5 * (lo + hi)
        if tips(mid):
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def _fmt(x) -> str:
    return f">{U_MAX:g}" if x is None else f"{x:.2f}"


def main(quick: bool = False) -> dict:
    slopes = SLOPES_DEG[:2] if quick else SLOPES_DEG
    n = 4 if quick else BISECTIONS
    t0 = time.perf_counter()
    td = touchdown_boundary(slopes, 41 if quick else 161)
    t_td = time.perf_counter() - t0
    rows = []
    times = {"touchdown": t_td, "planar": 0.0, "mujoco": 0.0}
    for s in slopes:
        t0 = time.perf_counter()
        pl = boundary(lambda u: planar_tips(s, u), n=n)
        push = boundary(lambda u: planar_tips(s, u, True), n=n)
        times["planar"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        mj5 = boundary(lambda u: mujoco_tips(s, u, 0.5), n=n)
        mj8 = boundary(lambda u: mujoco_tips(s, u, 0.8), n=n)
        times["mujoco"] += time.perf_counter() - t0
        rows.append((s, td[s], pl, push, mj5, mj8, td[(s, "pattern")]))
    print(f"Stand / tip boundary: the smallest sideways speed (m/s) at which the default lander, "
          f"touching down upright at {V_DOWN:g} m/s, moving toward a foot and downhill, tips over "
          f"(Moon; tilt past {TIP_DEG:g} deg from the ground's normal; {T_END_S:g} s)")
    print()
    print("| slope (deg) | Touchdown (mu_s 0.8, mu_k 0.5) | planar reference (0.8 / 0.5) | "
          "planar, ground that only pushes | MuJoCo mu 0.5 | MuJoCo mu 0.8 |")
    print("| --- | --- | --- | --- | --- | --- |")
    for s, a, b, p, c, d, _ in rows:
        print(f"| {s:g} | {_fmt(a)} | {_fmt(b)} | {_fmt(p)} | {_fmt(c)} | {_fmt(d)} |")
    print()
    print("Touchdown's outcome along the sweep (every 8th speed from 0 to "
          f"{U_MAX:g} m/s; T tipped): " + "; ".join(f"{s:g} deg {p}" for s, *_, p in rows))
    print(f"wall time: Touchdown {times['touchdown']:.1f} s (one sweep of "
          f"{len(slopes) * (41 if quick else 161)} cases), planar {times['planar']:.1f} s, "
          f"MuJoCo {times['mujoco']:.1f} s")
    return {"rows": rows, "times": times}
