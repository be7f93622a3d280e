"""The scenes of "physics you can trust at the edges" (issue 21), for ``touchdown bench physics``.

Each prints what Touchdown gives at dt 0.1 and 0.05, beside its independent reference (the 1-D
exact bounce, bench.reference.bounce_ode; the planar four-foot lander with a Coulomb law per foot,
bench.planar; a closed form) and beside what 0.5.0 gave (measured in review, quoted).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from touchdown.bench.planar import Lander, Start, foot_offsets, solve
from touchdown.bench.reference import bounce_ode
from touchdown.sim.constants import MOON_GM_M3PS2, MOON_RADIUS_M
from touchdown.sim.enums import EventKind
from touchdown.sim.run import run
from touchdown.sim.scenario import parse

GM, R = MOON_GM_M3PS2, MOON_RADIUS_M
G = GM / R ** 2
TICKS = (0.1, 0.05)


def _scene(initial, *, ship=None, contact=None, body=None, sim=None, inputs=None, duration=10.0):
    doc = {"name": "edges", "duration": duration, "sim": sim or {}, "contact": contact or {},
           "body": body or {}, "ships": [{"id": "s", **(ship or {}), "initial": initial,
                                          "inputs": inputs or []}]}
    return parse(doc, "edges")


def _events(recs, kind):
    return [e for r in recs for e in r.events if e.kind == kind]


def _tilt_deg(rec) -> float:
    q = rec.state.quat[0]
    p = rec.state.pos_m[0]
    w, x, y, z = q
    axis = np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
    return math.degrees(math.acos(min(1.0, float(axis @ p / np.linalg.norm(p)))))


def _planar(tilt_deg, v_side, v_down, t_end, mu_s=0.8, mu_k=0.5):
    ld = Lander(g_mps2=GM / (R + 3.0) ** 2, mu_s=mu_s, mu_k=mu_k, eps_mps=1e-7)
    th = math.radians(tilt_deg)
    z0 = -min(rz for _, rz, _ in foot_offsets(ld, th)) + 1e-6
    return solve(ld, Start(z_m=z0, theta_rad=th, vx_mps=v_side, vz_mps=-v_down), t_end,
                 rtol=1e-10, atol=1e-12)


def tilted_touchdown(rows, quick):
    path = _planar(10.0, 0.0, 20.0, 12.0)
    back = [e for e in path.events if e[1] == "contact"][1]
    got = []
    for dt in TICKS:
        recs = list(run(_scene({"altitude": 1e-6, "vertical_speed": -20.0, "tilt_deg": 10.0},
                               contact={"align_on_touchdown": False}, sim={"dt": dt},
                               duration=16.0)))
        c = _events(recs, EventKind.CONTACT)[1]
        ends = [EventKind(e.kind).name.lower() for r in recs for e in r.events
                if e.kind in (EventKind.LANDED, EventKind.TIPPED)]
        got.append(f"dt {dt}: back down {c.t_event_s:.3f} s at {_tilt_deg(recs[c.tick - 1]):.1f} "
                   f"deg, {ends[-1] if ends else 'in contact'}")
    rows.append(("20 m/s tilted 10 deg, no alignment (0.5.0: back at 55 deg, tipped 12.55 s)",
                 "; ".join(got),
                 f"back down {back[0]:.3f} s at {abs(math.degrees(back[2][2])):.1f} deg"))


def sideways_touchdown(rows, quick):
    path = _planar(0.0, 2.0, math.sqrt(400.0 - 2 * G * 1e-6), 2.0)
    lift = [e for e in path.events if e[1] == "liftoff"][0]
    got = []
    for dt in TICKS:
        recs = list(run(_scene({"altitude": 1e-6, "vertical_speed": -20.0,
                                "horizontal_speed": 2.0}, contact={"align_on_touchdown": False},
                               sim={"dt": dt}, duration=2.0)))
        s = recs[-1].state
        got.append(f"dt {dt}: {s.omega_body_radps[0][1]:.4f} rad/s, {s.vel_mps[0][2]:.4f} m/s")
    rows.append(("20 m/s down, 2 m/s sideways: pitch rate and horizontal speed leaving "
                 "(0.5.0: 0.315, 1.024)", "; ".join(got),
                 f"{lift[2][5]:.4f} rad/s, {lift[2][3]:.4f} m/s"))


def frictionless_tilts(rows, quick):
    for tilt in (3.0, 7.0):
        path = _planar(tilt, 0.0, math.sqrt(400.0 - 2 * G * 1e-6), 1.0, mu_s=0.0, mu_k=0.0)
        y = path.y[:, -1]
        got = []
        for dt in TICKS:
            recs = list(run(_scene({"altitude": 1e-6, "vertical_speed": -20.0, "tilt_deg": tilt},
                                   contact={"align_on_touchdown": False, "friction_static": 0.0,
                                            "friction_kinetic": 0.0}, sim={"dt": dt},
                                   duration=1.0)))
            got.append(f"dt {dt}: {_tilt_deg(recs[-1]):.3f} deg, "
                       f"{recs[-1].state.omega_body_radps[0][1]:+.4f} rad/s")
        before = "2.19 deg" if tilt == 3.0 else "pitch rate of the wrong sign"
        rows.append((f"Frictionless 20 m/s tilted {tilt:.0f} deg: tilt and pitch rate at 1 s "
                     f"(0.5.0: {before})", "; ".join(got),
                     f"{math.degrees(abs(y[2])):.3f} deg, {y[5]:+.4f} rad/s"))


def _holds(slope_deg, ship, dt) -> bool:
    """Does the ship, set down square on the slope and settled there on grippy ground, stay?"""
    alt = -G * math.cos(math.radians(slope_deg)) ** 2 / 100.0
    terrain = {"slope_deg": slope_deg, "slope_azimuth_deg": 0.0}
    start = {"state": "contact", "altitude": alt, "tilt_deg": slope_deg}
    stay = {"settle_time": 1e4}
    grip = _scene(start, ship=ship, sim={"dt": dt}, contact={"friction_static": 5.0, **stay},
                  body={"terrain": terrain}, duration=20.0)
    rest = list(run(grip))[-1].state
    import dataclasses

    from touchdown.sim.state import State
    scn = _scene(start, ship=ship, sim={"dt": dt}, contact=stay, body={"terrain": terrain},
                 duration=10.0)
    scn = dataclasses.replace(scn, initial=State(rows=rest.rows.copy(), tick=0))
    recs = list(run(scn))
    return float(np.linalg.norm(recs[-1].state.pos_m[0] - recs[0].state.pos_m[0])) < 0.01


def slope_thresholds(rows, quick):
    crit = math.degrees(math.atan(0.8))
    ships = {"squat": {"com_height": 0.5, "leg_radius": 3.0},
             "medium": {"com_height": 1.5, "leg_radius": 3.0},
             "tall": {"com_height": 2.5, "leg_radius": 3.0}}
    got = []
    for name, ship in ships.items():
        for dt in TICKS:
            lo, hi = crit - 2.0, crit + 2.0
            for _ in range(5 if quick else 8):  # bisection to 4 deg / 2^n
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if _holds(mid, ship, dt) else (lo, mid)
            got.append(f"{name} dt {dt}: {0.5 * (lo + hi) - crit:+.2f}")
    rows.append(("Steepest slope a ship holds on, minus atan(mu_s) = 38.66 deg "
                 "(0.5.0: a squat ship -2.6, -5.5 at small steps)", "; ".join(got), "0 (+-0.3)"))


def start_on_the_ground(rows, quick):
    exact = bounce_ode(GM, R, 35.0, com_height_m=3.0)
    got = []
    for dt in TICKS:
        recs = list(run(_scene({"state": "contact", "altitude": 0.0, "vertical_speed": -35.0},
                               sim={"dt": dt}, duration=20.0)))
        got.append(f"dt {dt}: {max(float(r.outputs.altitude_m[0]) for r in recs):.3f} m")
    rows.append(("35 m/s down with the feet on the ground: apex (0.5.0: 169 m at 0.1, 103 at 0.05)",
                 "; ".join(got), f"{exact.apex_m:.3f} m (less g dt^2 / 2 for the sampled top)"))


def bounce_instants(rows, quick):
    ground = lambda t, y: y[0]  # noqa: E731
    ground.terminal = True
    fall = solve_ivp(lambda t, y: [y[1], -GM / (R + 3.0 + y[0]) ** 2], (0.0, 5.0), [5.0, -20.0],
                     method="DOP853", rtol=1e-13, atol=1e-14, events=[ground])
    t0, v_impact = float(fall.t_events[0][0]), float(-fall.y_events[0][0][1])
    exact = bounce_ode(GM, R, v_impact, com_height_m=3.0)
    got = []
    for dt in TICKS + (0.02,):
        recs = list(run(_scene({"altitude": 5.0, "vertical_speed": -20.0}, sim={"dt": dt},
                               duration=15.0)))
        c = _events(recs, EventKind.CONTACT)[0]
        lo = _events(recs, EventKind.LIFTOFF)[0]
        la = _events(recs, EventKind.LANDED)
        got.append(f"dt {dt}: {c.t_event_s:.7f} / {lo.t_event_s:.7f} / "
                   f"{la[0].t_event_s if la else float('nan'):.4f} s")
    rows.append(("Bounce from 5 m at 20 m/s: contact / liftoff / landed instants "
                 "(0.5.0: 0.25 / 0.60 / 12.65 s, the tick ends)", "; ".join(got),
                 f"contact {t0:.7f}, liftoff {t0 + exact.contact_duration_s:.7f} s "
                 "(exact); landed 12.6204 s (sub-stepped at 1e-4 s)"))


def liftoff_from_landed(rows, quick):
    t_n, m0, isp = 0.6 * 60000.0, 1e4, 311.0
    sol = solve_ivp(lambda t, y: [y[1], t_n / y[2] - GM / (R + 3.0 + y[0]) ** 2,
                                  -t_n / (isp * 9.80665)], (0.0, 2.0), [0.0, 0.0, m0],
                    method="DOP853", rtol=1e-12, atol=1e-12)
    got = []
    for dt in TICKS:
        recs = list(run(_scene({"state": "landed"}, inputs=[{"t": 0.0, "throttle": 0.6}],
                               sim={"dt": dt}, duration=2.0)))
        got.append(f"dt {dt}: {float(recs[-1].outputs.altitude_m[0]):.4f} m")
    rows.append(("Throttle 0.6 from landed: height 2 s later (0.5.0: 3.761 m)", "; ".join(got),
                 f"{float(sol.y[0, -1]):.4f} m"))


SCENES = (bounce_instants, start_on_the_ground, liftoff_from_landed, frictionless_tilts,
          sideways_touchdown, tilted_touchdown, slope_thresholds)
