"""``touchdown bench physics``: the scenes of "physics that holds everywhere", measured, and those
of issue 35 ("3-D contact at the edges", bench.edges3d) beside the 3-D reference.

Each scene is one a user might try off the well-walked paths (a slide on a rotating body, a free
tumble, a fall onto the side, a spin in contact, a hill, a start on a slope, an impossible start, a
liftoff where the body's spin lightens the ship, a ship on a single point; and the edges of
bench.edges: tilted and sideways touchdowns, slopes, starts on the ground, event instants) and prints the figure
a user would check, beside what physics says it should be. The energy here is computed by this
file from the recorded state (its own bookkeeping, not sim.energy), with the kinetic energy of a
tipped ship taken as I_p theta'^2 / 2 about its pivot, so that the same script measures a version
whose tipped ships report no motion. It uses only scenario keys and state fields that 0.2.0 had,
so the same file run on that version gives the "before" column.
"""
from __future__ import annotations

import math
import time

import numpy as np

from touchdown.sim.contact import foot_offsets_w
from touchdown.sim.enums import EventKind, SurfaceState
from touchdown.sim.measure import terrain_height
from touchdown.sim.run import run
from touchdown.sim.scenario import ScenarioError, parse

MOON_ROTATION_S = 2360592.0  # sidereal month
EARTH_ROTATION_S = 86164.0905  # sidereal day
EARTH = {"name": "Earth", "radius": 6378137.0, "gm": 3.986004418e14}
SPINNER = {"name": "Spinner", "radius": 200000.0, "surface_gravity": 1.0,
           "rotation_period": 3600.0}


def scene(initial: dict, ship: dict | None = None, contact: dict | None = None,
          body: dict | None = None, sim: dict | None = None, inputs: list | None = None,
          duration: float = 10.0):
    doc = {"name": "bench", "duration": duration, "sim": sim or {}, "contact": contact or {},
           "body": body or {}, "ships": [{"id": "s", **(ship or {}), "initial": initial,
                                          "inputs": inputs or []}]}
    return parse(doc, "bench")


def inertia(scn, st) -> np.ndarray:
    return scn.params.ships.inertia0_kgm2[0] * (st.mass_kg[0] / scn.params.ships.mass0_kg[0])


def kinetic(scn, st) -> tuple[float, float]:
    """(translational, rotational) kinetic energy relative to the surface, J; a tipped ship's as
    its turn about the pivot under the pivot model (0.7's; since 0.8 a tipped ship moves by the
    full model and its velocities are its motion)."""
    om = scn.params.body.omega_radps
    p, q = st.pos_m[0], st.quat[0]
    i_b = inertia(scn, st)
    model = getattr(scn.params.contact, "tipped_model", None)  # before 0.8: the pivot model
    pivot_model = model is None or getattr(model, "label", model) == "pivot"
    if int(st.surface_state[0]) == int(SurfaceState.TIPPED) and pivot_model:
        up = p / np.linalg.norm(p)
        axis = np.cross(up, _rot(q, np.array([0.0, 0.0, 1.0])))
        axis /= np.linalg.norm(axis)
        d = p - _pivot_now(scn, st)
        axis_b = _rot_inv(q, axis)
        i_p = float(axis_b @ (i_b * axis_b)) + st.mass_kg[0] * float(np.cross(axis, d) @ np.cross(axis, d))
        return 0.5 * i_p * float(st.pivot_rate_radps[0]) ** 2, 0.0
    v = st.vel_mps[0] - om * np.array([-p[1], p[0], 0.0])
    w = st.omega_body_radps[0] - _rot_inv(q, np.array([0.0, 0.0, om]))
    return 0.5 * st.mass_kg[0] * float(v @ v), 0.5 * float(w @ (i_b * w))


def energy(scn, rec) -> float:
    """Kinetic relative to the surface, gravity m GM (1/R - 1/r), the frame's centrifugal
    potential, and the springs' stored energy (J)."""
    st, par = rec.state, scn.params
    om, gm, big_r = par.body.omega_radps, par.body.gm_m3ps2, par.body.radius_m
    p, q, m = st.pos_m[0], st.quat[0], st.mass_kg[0]
    trans, rot = kinetic(scn, st)
    r = float(np.linalg.norm(p))
    pot = m * gm * (r - big_r) / (big_r * r)
    spin_b = _rot_inv(q, np.array([0.0, 0.0, om]))
    cent = (-0.5 * m * om * om * (p[0] ** 2 + p[1] ** 2 - big_r ** 2)
            - 0.5 * float(spin_b @ (inertia(scn, st) * spin_b)))
    c, s = math.cos(om * rec.tick * par.sim.dt_s), math.sin(om * rec.tick * par.sim.dt_s)
    spring = 0.0
    k_leg = 0.25 * float(par.ships.stiffness_per_kg[0]) * m
    for off in foot_offsets_w(tuple(map(float, q)), float(par.ships.leg_radius_m[0]),
                              float(par.ships.com_height_m[0])):
        foot = p + np.array(off)
        east, north = -s * foot[0] + c * foot[1], foot[2]
        x = big_r + float(terrain_height(par.body.terrain, np.array([east]), np.array([north]))[0]) \
            - float(np.linalg.norm(foot))
        spring += 0.5 * k_leg * x * x if x > 0.0 else 0.0
    return trans + rot + pot + cent + spring


def _rot(q, v):
    u = q[1:]
    t = 2.0 * np.cross(u, v)
    return v + q[0] * t + np.cross(u, t)


def _rot_inv(q, v):
    return _rot(np.array([q[0], -q[1], -q[2], -q[3]]), v)


def _pivot_now(scn, st):
    om = scn.params.body.omega_radps
    if om == 0.0:
        return st.pin_pivot_bf_m[0]
    # the pinned pose and pivot are body-fixed; the pose now is inertial: rotate by the same angle
    p_bf, p = st.pin_pos_bf_m[0], st.pos_m[0]
    ang = math.atan2(p[1], p[0]) - math.atan2(p_bf[1], p_bf[0])
    c, s = math.cos(ang), math.sin(ang)
    x, y, z = st.pin_pivot_bf_m[0]
    return np.array([c * x - s * y, s * x + c * y, z])


def topics(recs) -> list[tuple[float, str]]:
    return [(r.tick, EventKind(e.kind).topic) for r in recs for e in r.events]


def first(recs, dt, name) -> str:
    for tick, topic in topics(recs):
        if topic == name:
            return f"{tick * dt:.2f} s"
    return "never"


def tilt(rec) -> float:
    p, q = rec.state.pos_m[0], rec.state.quat[0]
    c = float(_rot(q, np.array([0.0, 0.0, 1.0])) @ (p / np.linalg.norm(p)))
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


# -- the scenes ------------------------------------------------------------------------------
def rotating_slides(rows, quick):
    for label, body, heading, span in (
            ("Moon still, 6 m/s sideways touchdown", {}, 0.0, 60.0),
            ("Moon turning (27.3 d), the same heading north", {"rotation_period": MOON_ROTATION_S},
             0.0, 60.0),
            ("Moon turning (27.3 d), the same heading east", {"rotation_period": MOON_ROTATION_S},
             90.0, 60.0),
            ("Earth turning, the same heading north", {**EARTH, "rotation_period": EARTH_ROTATION_S},
             0.0, 30.0)):
        scn = scene({"altitude": 0.2, "vertical_speed": -2.0, "horizontal_speed": 6.0,
                     "heading_deg": heading}, body=body, duration=span)
        recs = list(run(scn))
        upright = [r for r in recs if int(r.state.surface_state[0]) != int(SurfaceState.TIPPED)]
        spin = max(math.sqrt(sum(x * x for x in _rel_rates(scn, r))) for r in upright)
        speed = float(recs[-1].outputs.v_tangential_mps[0])
        rows.append((label, f"2 m/s down: events {[(round(t * 0.05, 2), n) for t, n in topics(recs)]}; "
                            f"largest spin before any tip {spin:.3g} rad/s; speed at {span:g} s "
                            f"{speed:.3g} m/s", "the same on a still and a turning body"))
    for label, body in (("Moon turning, slide on the feet north at 4 m/s",
                         {"rotation_period": MOON_ROTATION_S}),
                        ("Earth turning, slide on the feet north at 4 m/s",
                         {**EARTH, "rotation_period": EARTH_ROTATION_S})):
        g = 1.6248 if "name" not in body else 9.80
        scn = scene({"state": "contact", "altitude": -g / 100.0, "horizontal_speed": 4.0},
                    body=body, duration=20.0)
        recs = list(run(scn))
        spin = max(math.sqrt(sum(x * x for x in _rel_rates(scn, r))) for r in recs)
        rows.append((label, f"landed {first(recs, 0.05, 'ship.landed')}; largest spin {spin:.3g} rad/s",
                     f"stops after v / (mu_k g) = {4.0 / (0.5 * g):.2f} s, no spin-up"))


def _rel_rates(scn, rec):
    om = scn.params.body.omega_radps
    return rec.state.omega_body_radps[0] - _rot_inv(rec.state.quat[0], np.array([0.0, 0.0, om]))


def held_creep(rows, quick):
    span = 60.0 if quick else 3600.0
    g_eff = 1.0 - (2 * math.pi / 3600.0) ** 2 * 200000.0
    scn = scene({"state": "contact", "altitude": -g_eff / 100.0, "north": 20000.0},
                body=SPINNER, contact={"settle_time": 1e4}, duration=span)
    recs = list(run(scn))

    def body_fixed(rec):
        p = rec.state.pos_m[0]
        a = -scn.params.body.omega_radps * rec.tick * 0.05
        return np.array([math.cos(a) * p[0] - math.sin(a) * p[1],
                         math.sin(a) * p[0] + math.cos(a) * p[1], p[2]])

    drift = float(np.linalg.norm(body_fixed(recs[-1]) - body_fixed(recs[10])))
    rows.append(("Held in contact on spinning-moon (20 km north of the equator)",
                 f"moves {drift * 1e3 * 3600.0 / (span - 0.5):.3g} mm per hour (over {span:g} s)",
                 "0: static friction holds (mu_s g_eff > the centrifugal pull along the ground)"))


def free_rotation(rows, quick):
    for label, ship, rates in (("Symmetric ship, body rates (0.9, 0, 3)", {}, [0.9, 0.0, 3.0]),
                               ("Symmetric ship, body rates (0.3, 0, 1)", {}, [0.3, 0.0, 1.0]),
                               ("Dzhanibekov (30,000 / 45,000 / 20,000), rates (1, 0.01, 0)",
                                {"inertia": [30000.0, 45000.0, 20000.0]}, [1.0, 0.01, 0.0])):
        scn = scene({"altitude": 1e6, "angular_velocity": rates}, ship=ship, duration=60.0)
        recs = list(run(scn))
        i_b = inertia(scn, recs[0].state)
        e = [0.5 * float(r.state.omega_body_radps[0] @ (i_b * r.state.omega_body_radps[0]))
             for r in recs]
        ell = [float(np.linalg.norm(_rot(r.state.quat[0], i_b * r.state.omega_body_radps[0])))
               for r in recs]
        rows.append((label, f"over 60 s: rotational energy x{e[-1] / e[0]:.6g} (largest change "
                            f"{max(abs(x / e[0] - 1.0) for x in e):.2g}), |L| largest change "
                            f"{max(abs(x / ell[0] - 1.0) for x in ell):.2g}",
                     "x1 and x1 (torque-free)"))


def fall_onto_side(rows, quick):
    for tilt0, speed in ((45.0, 5.0), (30.0, 30.0)):
        scn = scene({"altitude": 1e-4, "vertical_speed": -speed, "tilt_deg": tilt0},
                    contact={"align_on_touchdown": False, "friction_static": 0.0,
                             "friction_kinetic": 0.0}, duration=10.0)
        recs = list(run(scn))
        for k, r in enumerate(recs):
            if any(e.to_state == SurfaceState.TIPPED for e in r.events):
                before = sum(kinetic(scn, recs[k - 1].state))
                after = sum(kinetic(scn, r.state))
                rows.append((f"Frictionless touchdown at {tilt0:g} deg, {speed:g} m/s, onto its side",
                             f"kinetic energy {before / 1e3:.4g} kJ before contact -> tipped, "
                             f"{after / 1e3:.4g} kJ after", "after <= before"))
                break
        else:
            rows.append((f"Frictionless touchdown at {tilt0:g} deg, {speed:g} m/s",
                         f"never tipped: {[t for _, t in topics(recs)]}", "tips"))


def yaw_spin(rows, quick):
    scn = scene({"state": "contact", "altitude": -0.016248, "angular_velocity": [0.0, 0.0, 0.05]},
                duration=60.0)
    recs = list(run(scn))
    g, m, a = 1.6248, 10000.0, 2.26
    i_z = 0.5 * m * a * a
    stops = next((r.tick * 0.05 for r in recs if abs(_rel_rates(scn, r)[2]) < 1e-6), None)
    rows.append(("Spin of 0.05 rad/s about the long axis, in contact",
                 f"spin stopped {'never' if stops is None else f'{stops:.2f} s'}; landed "
                 f"{first(recs, 0.05, 'ship.landed')}",
                 f"four feet stop it in {0.05 * i_z / (0.5 * m * g * a):.2f} s"))


def frictionless_hill(rows, quick):
    bump = {"terrain": {"bumps": [{"east": 20.0, "north": 0.0, "radius": 15.0, "height": 2.0}]}}
    scn = scene({"state": "contact", "altitude": -0.016248, "horizontal_speed": 5.0,
                 "heading_deg": 90.0}, body=bump,
                contact={"friction_static": 0.0, "friction_kinetic": 0.0}, duration=12.0)
    recs = list(run(scn))
    top = min(recs, key=lambda r: abs(r.state.pos_m[0][1] - 20.0))
    v_top = float(np.linalg.norm(top.state.vel_mps[0]))
    g = 1.6248
    e0, e1 = energy(scn, recs[0]), energy(scn, top)
    rows.append(("Frictionless slide at 5 m/s over a 2 m hill",
                 f"speed at the top {v_top:.3g} m/s; energy there {e1 - e0:+.4g} J",
                 f"{math.sqrt(25.0 - 2.0 * g * 2.0):.3g} m/s; <= 0 J"))


def slope_start(rows, quick):
    bump = {"terrain": {"bumps": [{"east": 0.0, "north": 0.0, "radius": 15.0, "height": 2.0}]}}
    scn = scene({"altitude": 0.5, "east": 7.0}, body=bump, duration=2.0)
    recs = list(run(scn))
    alt0 = float(recs[0].outputs.altitude_m[0])
    fastest = max(float(np.linalg.norm(r.state.vel_mps[0])) for r in recs[:5])
    rows.append(("Placed 0.5 m up on a hill's side (7 m from a 2 m bump's top)",
                 f"lowest foot at t = 0: {alt0:+.3g} m; fastest in the first 0.2 s "
                 f"{fastest:.3g} m/s", "+0.5 m; ~0.3 m/s (falling)"))


def impossible_starts(rows, quick):
    for label, initial in (("altitude = -20 (flying)", {"altitude": -20.0}),
                           ("altitude = -20 (contact)", {"state": "contact", "altitude": -20.0}),
                           ("landed at altitude +5", {"state": "landed", "altitude": 5.0})):
        try:
            scn = scene(initial, duration=2.0)
        except ScenarioError as exc:
            rows.append((label, f"refused: {exc.key}: {exc.problem[:70]}...", "refused (exit 2)"))
            continue
        recs = list(run(scn))
        fastest = max(float(np.linalg.norm(r.state.vel_mps[0])) for r in recs)
        alt = float(recs[-1].outputs.altitude_m[0])
        rows.append((label, f"accepted: fastest {fastest:.3g} m/s, altitude after 2 s "
                            f"{alt:.3g} m, events {[t for _, t in topics(recs)]}",
                     "refused (exit 2)"))


def effective_gravity_liftoff(rows, quick):
    m = 10000.0
    g_eff = 1.0 - (2 * math.pi / 3600.0) ** 2 * 200000.0
    for state, alt in (("landed", 0.0), ("contact", -g_eff / 100.0)):
        scn = scene({"state": state, "altitude": alt}, ship={"max_thrust": 9000.0},
                    body=SPINNER, inputs=[{"t": 0.0, "throttle": 1.0}], duration=3.0)
        recs = list(run(scn))
        rows.append((f"{state.capitalize()} on spinning-moon, 9 kN up (m g_eff = {m * g_eff / 1e3:.2f} kN)",
                     f"liftoff {first(recs, 0.05, 'ship.liftoff')}", "at once"))


def point_foot(rows, quick):
    scn = scene({"state": "contact", "altitude": -0.016248, "tilt_deg": 1.0},
                ship={"leg_radius": 0.0}, duration=30.0)
    recs = list(run(scn))
    rows.append(("leg_radius = 0, tilted 1 deg (the seed's inverted pendulum)",
                 f"landed {first(recs, 0.05, 'ship.landed')}, tipped {first(recs, 0.05, 'ship.tipped')}",
                 "never lands; falls over"))


def edge_angle(rows, quick):
    h, a = 3.0, 2.26
    foot, edge = math.degrees(math.atan2(a, h)), math.degrees(math.atan2(a, math.sqrt(2) * h))
    out = []
    for name, heading, crit in (("a foot", 0.0, foot), ("the edge between two", 45.0, edge)):
        for side in (-0.5, 0.5):
            scn = scene({"state": "contact", "altitude": -0.016248, "tilt_deg": crit + side,
                         "yaw_deg": heading}, duration=25.0)
            recs = list(run(scn))
            out.append(f"{crit + side:.1f} deg toward {name}: "
                       + ("falls" if any(t == "ship.tipped" for _, t in topics(recs)) else "stands"))
    rows.append(("Critical tilt: toward a foot atan(a/h) = %.1f deg, toward an edge "
                 "atan(a/(sqrt2 h)) = %.1f deg" % (foot, edge), "; ".join(out),
                 "stands below, falls above, each"))


SCENES = (rotating_slides, held_creep, free_rotation, fall_onto_side, yaw_spin, frictionless_hill,
          slope_start, impossible_starts, effective_gravity_liftoff, point_foot, edge_angle)


def _edges():
    """The scenes of the edges (bench.edges), where this version has them."""
    try:
        from touchdown.bench import edges
    except ImportError:  # a version before them
        return ()
    return edges.SCENES


def _edges3d():
    """The scenes of issue 35 beside the 3-D reference (bench.edges3d), where this version has
    them."""
    try:
        from touchdown.bench import edges3d
    except ImportError:  # a version before them
        return ()

    def edges_in_3d(rows, quick):
        dts = (0.05,) if quick else (0.1, 0.05, 0.005)
        for scene, what, ref, *sims in edges3d.table(dts):
            got = "; ".join(f"dt {dt:g}: {v}" for dt, v in zip(dts, sims))
            rows.append((f"{scene}: {what}", got, f"3-D reference: {ref}"))
    return (edges_in_3d,)


def main(quick: bool = False) -> None:
    from touchdown.sim import __version__

    from touchdown.bench.speed import machine
    print(f"touchdown {__version__}; {machine()}")
    for fn in SCENES + _edges() + _edges3d():
        rows: list[tuple[str, str, str]] = []
        t0 = time.perf_counter()
        try:
            fn(rows, quick)
        except Exception as exc:  # a scene the version cannot express
            rows.append((fn.__name__, f"could not run: {type(exc).__name__}: {exc}", ""))
        for label, got, expect in rows:
            print(f"- {label}\n    measured: {got}\n    physics:  {expect}")
        print(f"    ({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    import sys
    main(quick="--quick" in sys.argv)
