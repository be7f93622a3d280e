"""The scenes of issue 35 ("3-D contact at the edges"), each run by the simulation and by the
independent 3-D reference (bench.reference3d) from one description, and measured the same way.

A :class:`Scene` is a start in the scenario's own terms (SPEC.md: ``ships.initial``, the ship's
size, the slope, an RCS burn) and builds both the scenario (:meth:`Scene.scenario`) and the
reference's start (:meth:`Scene.reference`). Both runs become a :class:`Track`: the state on a
time grid in the reference's coordinates (the centre of mass from the landing site, velocity,
attitude, body rates) and the events with their instants. The measures (:func:`tilt_deg`,
:func:`landing_instant`, ...) read only tracks, so the simulation and the reference are measured by
the same lines. The simulation is imported only in :func:`run_sim`.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from touchdown.bench.reference3d import (Ground3, Lander3, Law, MOON_GM, MOON_R, Start3, Path3,
                                         feet_state, params_array, solve3)

#: what landing asks (the seed's thresholds, Touchdown's defaults)
SETTLE_TILT_DEG, SETTLE_ANG, SETTLE_LIN, SETTLE_TIME = 5.0, 0.01, 0.5, 0.5
#: and every pressing foot slipping slower than this (Touchdown's reading, MODEL-NOTES 45)
SETTLE_SLIP = 0.01


@dataclass(frozen=True)
class Scene:
    """One start, in scenario terms. ``side_speed_mps`` adds a horizontal speed at
    ``side_heading_deg`` (a speed out of the tilt plane, which the scenario's one heading cannot
    give: the simulation's start is changed after parsing). ``rcs``: the RCS command (fractions of
    ``max_rcs_torque``) from t = 0 until ``rcs_until_s``."""

    name: str
    duration_s: float
    state: str = "flying"
    altitude_m: float = 0.0
    tilt_deg: float = 0.0
    heading_deg: float = 0.0
    yaw_deg: float = 0.0
    vertical_speed_mps: float = 0.0
    horizontal_speed_mps: float = 0.0
    side_speed_mps: float = 0.0
    side_heading_deg: float = 90.0
    angular_velocity: tuple = (0.0, 0.0, 0.0)
    mass_kg: float = 1e4
    com_height_m: float = 3.0
    leg_radius_m: float = 2.26
    slope_deg: float = 0.0
    slope_azimuth_deg: float = 0.0
    max_rcs_torque_nm: float = 20000.0
    rcs: tuple = (0.0, 0.0, 0.0)
    rcs_until_s: float = 0.0
    throttle: float = 0.0
    max_thrust_n: float = 60000.0
    contact: tuple = ()  # further contact.* keys for the simulation, as (key, value) pairs
    #: a start in contact at the equilibrium sag of four feet standing square on the slope
    at_equilibrium: bool = False

    @property
    def g_surface(self) -> float:
        return MOON_GM / MOON_R ** 2

    def start_altitude(self) -> float:
        if not self.at_equilibrium:
            return self.altitude_m
        # four feet along the slope's normal carry the weight's normal part: k x sec(a) = m g cos a
        g = MOON_GM / (MOON_R + self.com_height_m) ** 2
        c = math.cos(math.radians(self.slope_deg))
        return -g * c * c / 100.0

    def lander(self) -> Lander3:
        torque = tuple(self.max_rcs_torque_nm * x for x in self.rcs)
        return Lander3(mass_kg=self.mass_kg, com_height_m=self.com_height_m,
                       leg_radius_m=self.leg_radius_m, thrust_n=self.throttle * self.max_thrust_n,
                       rcs_torque_body_nm=torque, rcs_until_s=self.rcs_until_s)

    def ground(self) -> Ground3:
        return Ground3(slope_deg=self.slope_deg, slope_azimuth_deg=self.slope_azimuth_deg)

    def reference(self) -> Start3:
        return Start3(altitude_m=self.start_altitude(), tilt_deg=self.tilt_deg,
                      heading_deg=self.heading_deg, yaw_deg=self.yaw_deg,
                      vertical_speed_mps=self.vertical_speed_mps,
                      horizontal_speed_mps=self.horizontal_speed_mps,
                      angular_velocity_body=self.angular_velocity, state=self.state)

    def doc(self, dt: float, sim: dict | None = None, contact: dict | None = None) -> dict:
        inputs = []
        if self.rcs_until_s > 0.0 and any(self.rcs):
            inputs = [{"t": 0.0, "rcs": list(self.rcs)}, {"t": self.rcs_until_s, "rcs": [0, 0, 0]}]
        if self.throttle > 0.0:
            inputs.append({"t": 0.0, "throttle": self.throttle})
            inputs.sort(key=lambda x: x["t"])
        initial = {"state": self.state, "altitude": self.start_altitude(),
                   "tilt_deg": self.tilt_deg, "heading_deg": self.heading_deg,
                   "yaw_deg": self.yaw_deg, "vertical_speed": self.vertical_speed_mps,
                   "horizontal_speed": self.horizontal_speed_mps,
                   "angular_velocity": list(self.angular_velocity)}
        con = {"align_on_touchdown": False, **dict(self.contact), **(contact or {})}
        return {"name": self.name, "duration": self.duration_s, "sim": {"dt": dt, **(sim or {})},
                "contact": con,
                "body": {"terrain": {"slope_deg": self.slope_deg,
                                     "slope_azimuth_deg": self.slope_azimuth_deg}},
                "ships": [{"id": "s", "mass": self.mass_kg, "fuel_mass": 0.2 * self.mass_kg,
                           "com_height": self.com_height_m, "leg_radius": self.leg_radius_m,
                           "max_rcs_torque": self.max_rcs_torque_nm,
                           "max_thrust": self.max_thrust_n,
                           "initial": initial, "inputs": inputs}]}

    def side_velocity(self) -> np.ndarray:
        """The added horizontal velocity at the site, inertial (the site is (R, 0, 0): east +y,
        north +z)."""
        hd = math.radians(self.side_heading_deg)
        return self.side_speed_mps * np.array([0.0, math.sin(hd), math.cos(hd)])


@dataclass
class Track:
    """A run on a time grid: ``t`` (s), the centre of mass from the site ``d`` (m), velocity
    ``v``, attitude ``q`` (w, x, y, z), body rates ``w``; ``state`` (the simulation's surface
    state, "" for the reference); the events as (instant, kind)."""

    t: np.ndarray
    d: np.ndarray
    v: np.ndarray
    q: np.ndarray
    w: np.ndarray
    events: list
    state: np.ndarray | None = None
    scene: Scene | None = None
    landed_t_s: float | None = None  # the simulation's ship.landed instant (None: never)
    path: Path3 | None = None

    def first(self, kind: str) -> float | None:
        for t, k in self.events:
            if k == kind:
                return t
        return None


def run_sim(sc: Scene, dt: float, sim: dict | None = None, contact: dict | None = None) -> Track:
    """The scene run by the simulation at tick ``dt``: its ticks as a Track."""
    from touchdown.sim.enums import EventKind, SurfaceState
    from touchdown.sim.run import run
    from touchdown.sim.scenario import parse
    from touchdown.sim.state import State
    scn = parse(sc.doc(dt, sim, contact), sc.name)
    if sc.side_speed_mps != 0.0:
        rows = scn.initial.rows.copy()
        rows["vel_mps"][0] += sc.side_velocity()
        scn = dataclasses.replace(scn, initial=State(rows=rows, tick=scn.initial.tick))
    recs = list(run(scn))
    st = np.array([r.state.rows[0] for r in recs])
    t = np.array([r.tick * dt for r in recs])
    events, landed = [], None
    names = {EventKind.CONTACT: "contact", EventKind.LIFTOFF: "liftoff",
             EventKind.TIPPED: "tipped", EventKind.RIGHTED: "righted",
             EventKind.LANDED: "landed", EventKind.CRASHED: "crashed"}
    for r in recs:
        for e in r.events:
            kind = names.get(EventKind(e.kind), str(e.kind))
            events.append((e.t_event_s, kind))
            if kind == "landed" and landed is None:
                landed = e.t_event_s
    d = st["pos_m"] - np.array([MOON_R, 0.0, 0.0])
    state = np.array([SurfaceState(int(s)).label for s in st["surface_state"]])
    return Track(t, d, st["vel_mps"], st["quat"], st["omega_body_radps"], events, state, sc,
                 landed)


@lru_cache(maxsize=256)
def run_reference(sc: Scene, law: Law = Law(), method: str = "LSODA", step_s: float = 1e-3,
                  stop_at_tipped: bool = True) -> Track:
    """The scene by the 3-D reference, sampled every ``step_s`` (cached within a session)."""
    y0 = None
    ld, gr, st = sc.lander(), sc.ground(), sc.reference()
    if sc.side_speed_mps != 0.0:
        from touchdown.bench.reference3d import initial_state
        y0 = initial_state(ld, gr, st)
        y0[3:6] += sc.side_velocity()
    path = solve3(ld, gr, st, sc.duration_s, law=law, method=method, y0=y0,
                  stop_at_tipped=stop_at_tipped)
    n = int(round(path.t_end_s / step_s))
    t = np.linspace(0.0, n * step_s, n + 1)
    t = t[t <= path.t_end_s + 1e-12]
    ys = path.sample(t)
    return Track(t, ys[:, 0:3], ys[:, 3:6], ys[:, 6:10], ys[:, 10:13],
                 [(e.t_s, e.kind) for e in path.events], None, sc, None, path)


# -- measures (the same for both) ------------------------------------------------------------------
def _rot(q, v):
    """Rows of q applied to v (body -> inertial)."""
    q = np.atleast_2d(q)
    u = q[:, 1:]
    tt = 2.0 * np.cross(u, v)
    return v + q[:, :1] * tt + np.cross(u, tt)


def up(tr: Track) -> np.ndarray:
    p = tr.d + np.array([MOON_R, 0.0, 0.0])
    return p / np.linalg.norm(p, axis=1)[:, None]


def tilt_deg(tr: Track) -> np.ndarray:
    """The long axis' angle from local vertical, per sample."""
    ez = _rot(tr.q, np.array([0.0, 0.0, 1.0]))
    c = np.clip(np.sum(ez * up(tr), axis=1), -1.0, 1.0)
    return np.degrees(np.arccos(c))


def at(tr: Track, values: np.ndarray, t: float) -> float:
    return float(np.interp(t, tr.t, values))


def horizontal_m(tr: Track) -> np.ndarray:
    """(east, north) of the centre of mass from its start, m."""
    return tr.d[:, 1:3] - tr.d[0, 1:3]


def yaw_rate_up(tr: Track) -> np.ndarray:
    """The angular velocity's component along local up, rad/s."""
    w_w = _rot(tr.q, tr.w) if tr.w.ndim == 1 else np.array(
        [_rot(q, w)[0] for q, w in zip(tr.q, tr.w)])
    return np.sum(w_w * up(tr), axis=1)


def yaw_deg(tr: Track) -> np.ndarray:
    """The heading of body x projected on the local horizontal (from north toward east), unwrapped,
    relative to its start, degrees."""
    ex = np.array([_rot(q, np.array([1.0, 0.0, 0.0]))[0] for q in tr.q])
    ang = np.unwrap(np.arctan2(ex[:, 1], ex[:, 2]))
    return np.degrees(ang - ang[0])


def _margins(tr: Track) -> np.ndarray:
    """The settle thresholds' smallest margin per sample (> 0: all hold), each linear in its
    quantity: speeds, angular speed, tilt from the ground's normal, the centre of mass over the
    footprint, the feet still (Touchdown's reading of the seed, MODEL-NOTES 45; the simulation and
    the reference are judged by the same rule here)."""
    sc = tr.scene
    gr = sc.ground()
    u = up(tr)
    v_rad = np.sum(tr.v * u, axis=1)
    v_tan = np.linalg.norm(tr.v - v_rad[:, None] * u, axis=1)
    w = np.linalg.norm(tr.w, axis=1)
    s_e, s_n = gr.gradient
    n = u - np.array([0.0, s_e, s_n])
    n /= np.linalg.norm(n, axis=1)[:, None]
    ez = _rot(tr.q, np.array([0.0, 0.0, 1.0]))
    cos_t = np.sum(ez * n, axis=1)
    c5 = math.cos(math.radians(SETTLE_TILT_DEG))
    m = np.minimum((SETTLE_LIN - np.abs(v_rad)) / SETTLE_LIN, (SETTLE_LIN - v_tan) / SETTLE_LIN)
    m = np.minimum(m, (SETTLE_ANG - w) / SETTLE_ANG)
    m = np.minimum(m, (cos_t - c5) / (1.0 - c5))
    # over the footprint: up in the body frame
    ub = np.array([_rot(np.array([q[0], -q[1], -q[2], -q[3]]), uu)[0] for q, uu in zip(tr.q, u)])
    over = sc.com_height_m * (np.abs(ub[:, 0]) + np.abs(ub[:, 1])) < sc.leg_radius_m * ub[:, 2]
    m = np.where(over, m, np.minimum(m, -1.0))
    # the feet still: every pressing foot slipping slower than SETTLE_SLIP
    par = params_array(sc.lander(), gr, Law(), False, False)
    y = np.hstack([tr.d, tr.v, tr.q, tr.w])
    slip = np.array([float(np.max(np.where(fs[0] > 0.0, fs[4], 0.0)))
                     for fs in (feet_state(yy, par) for yy in y)])
    return np.minimum(m, (SETTLE_SLIP - slip) / SETTLE_SLIP)


def settle_instant(tr: Track) -> float | None:
    """The first instant at which the settle thresholds have held for SETTLE_TIME in continuous
    time (the instant they began to hold interpolated between samples), or None."""
    m = _margins(tr)
    t = tr.t
    began = None
    for k in range(len(t)):
        if m[k] > 0.0:
            if began is None:
                began = t[k] if k == 0 else t[k - 1] + (t[k] - t[k - 1]) * (
                    m[k - 1] / (m[k - 1] - m[k]))
            if t[k] - began >= SETTLE_TIME:
                return began + SETTLE_TIME
        else:
            began = None
    return None


def outcome(tr: Track) -> str:
    """What happened by the end: "tipped", "crashed", "flying", "landed" (the simulation's state;
    for the reference, at rest by the settle rule and still standing), "contact" (neither)."""
    if tr.first("crashed") is not None:
        return "crashed"
    if tr.first("tipped") is not None and (tr.first("righted") is None
                                           or tr.first("righted") < tr.first("tipped")):
        return "tipped"
    if tr.state is not None:
        return str(tr.state[-1])
    if tr.events and tr.events[-1][1] == "liftoff":
        return "flying"
    return "landed" if settle_instant(tr) is not None else "contact"


# -- the scenes of issue 35 ----------------------------------------------------------------------
#: 1. the default lander standing square on a 27 degree slope, the edge between two feet downhill
#: (1.04 degrees under the static edge limit), started at its equilibrium sag
EDGE_ON_SLOPE = Scene("edge-on-slope", 15.0, state="contact", at_equilibrium=True, tilt_deg=27.0,
                      yaw_deg=45.0, slope_deg=27.0)
#: 2. a squat ship on a slope just steeper than atan(mu_s) (38.66 degrees)
SLIDE_39 = Scene("slide-39.3", 6.0, state="contact", at_equilibrium=True, tilt_deg=39.3,
                 slope_deg=39.3, com_height_m=0.5, leg_radius_m=3.0)
#: 3. a 2 m/s touchdown tilted 24 (and 27) degrees toward an edge
EDGE_24 = Scene("edge-24", 12.0, altitude_m=0.0, tilt_deg=24.0, yaw_deg=45.0,
                vertical_speed_mps=-2.0)
EDGE_27 = dataclasses.replace(EDGE_24, name="edge-27", tilt_deg=27.0, duration_s=14.0)
#: 4. a landed ship on a 35 degree slope given 30% of its weight in thrust (mu_s (m g cos a - T)
#: < m g sin a: it slides), and a landed ship on level ground given 40 kN m of RCS torque about
#: the edge between two feet (the weight's moment about that edge is 26 kN m: it tips over)
def _thrust_fraction(frac: float) -> float:
    return frac * 1e4 * MOON_GM / (MOON_R + 3.0) ** 2 / 60000.0


LANDED_THRUST = Scene("landed-thrust-35", 6.0, state="landed", at_equilibrium=True,
                      tilt_deg=35.0, slope_deg=35.0, throttle=_thrust_fraction(0.3))
LANDED_TORQUE = Scene("landed-torque", 8.0, state="landed", at_equilibrium=True, yaw_deg=45.0,
                      max_rcs_torque_nm=40000.0, rcs=(math.sqrt(0.5), math.sqrt(0.5), 0.0),
                      rcs_until_s=8.0)
#: 5. a ship tipped at 85 degrees toward a foot, righted by 80 kN m at (cos 30, sin 30, 0) of
#: body (x, y) until 1.5 s (and until 2.5 s); and with the torque in the foot's plane
TIPPED_RCS = Scene("tipped-rcs", 3.0, state="tipped", tilt_deg=85.0, yaw_deg=-90.0,
                   max_rcs_torque_nm=80000.0,
                   rcs=(math.cos(math.radians(30)), math.sin(math.radians(30)), 0.0),
                   rcs_until_s=1.5)
TIPPED_RCS_LONG = dataclasses.replace(TIPPED_RCS, name="tipped-rcs-2.5", rcs_until_s=2.5,
                                      duration_s=4.0)
TIPPED_RCS_PLANE = dataclasses.replace(TIPPED_RCS, name="tipped-rcs-plane",
                                       rcs=(math.cos(math.radians(30)), 0.0, 0.0))
#: 6. tilted 10 degrees, 0.5 rad/s about the long axis, 3 m/s horizontal, 5 m/s down
SPIN_SLIDE = Scene("spin-slide", 10.0, altitude_m=0.0, tilt_deg=10.0, vertical_speed_mps=-5.0,
                   horizontal_speed_mps=3.0, angular_velocity=(0.0, 0.0, 0.5))
#: 7. a slow skid toward an edge (2 m/s horizontal, 2 m/s down, yaw 45); a 1 rad/s spin at a
#: 2 m/s touchdown
SKID_EDGE = Scene("skid-edge", 8.0, altitude_m=0.0, yaw_deg=45.0, vertical_speed_mps=-2.0,
                  horizontal_speed_mps=2.0)
SPIN_TOUCHDOWN = Scene("spin-touchdown", 8.0, altitude_m=0.0, vertical_speed_mps=-2.0,
                       angular_velocity=(0.0, 0.0, 1.0))
#: 8. 20 m/s touchdowns tilted toward an edge around the critical tilt; the combined touchdown
#: with its sideways speed out of the tilt plane
EDGE_20_24 = Scene("edge-20-24", 15.0, altitude_m=0.0, tilt_deg=24.0, yaw_deg=45.0,
                   vertical_speed_mps=-20.0)
EDGE_20_285 = dataclasses.replace(EDGE_20_24, name="edge-20-28.5", tilt_deg=28.5)
COMBINED = Scene("combined-out-of-plane", 15.0, altitude_m=0.0, tilt_deg=10.0,
                 vertical_speed_mps=-20.0, side_speed_mps=2.0, side_heading_deg=90.0)


# -- what each scene is judged by -----------------------------------------------------------------
def _fmt(x, spec="{:.4g}"):
    return "-" if x is None else spec.format(x)


def tip_instant(tr: Track) -> float | None:
    return tr.first("tipped")


def landing(tr: Track) -> float | None:
    """The simulation's ship.landed instant; the reference's settle instant if it stays up."""
    if tr.path is None:
        return tr.landed_t_s
    return settle_instant(tr) if outcome(tr) == "landed" else None


def distance_m(tr: Track) -> float:
    return float(np.linalg.norm(horizontal_m(tr)[-1]))


def peak_tilt(tr: Track) -> float:
    return float(tilt_deg(tr).max())


def tilt_rate_dps(tr: Track) -> np.ndarray:
    """The tilt's rate from the angular velocity, per sample, deg/s: -((w x e_z) . up) / sin."""
    ez = _rot(tr.q, np.array([0.0, 0.0, 1.0]))
    w_w = np.array([_rot(q, w)[0] for q, w in zip(tr.q, tr.w)])
    u = up(tr)
    c = np.clip(np.sum(ez * u, axis=1), -1.0, 1.0)
    return np.degrees(-np.sum(np.cross(w_w, ez) * u, axis=1) / np.sqrt(1.0 - c * c))


def righting(tr: Track) -> tuple[float | None, float | None]:
    """(the instant the tilt comes back under 80 degrees, its rate there, deg/s)."""
    t80 = tr.first("righted")
    if t80 is None:
        return None, None
    return t80, float(np.interp(t80, tr.t, tilt_rate_dps(tr)))


def lowest_after_righting(tr: Track) -> float | None:
    t80 = tr.first("righted")
    if t80 is None:
        return None
    til = tilt_deg(tr)
    return float(til[tr.t >= t80].min())


def _event_after(tr: Track, kind: str, after: float) -> float | None:
    for t, k in tr.events:
        if k == kind and t > after:
            return t
    return None


#: scene -> [(what, measure(track) -> float | str | None)]
MEASURES = {
    EDGE_ON_SLOPE: [("outcome", outcome), ("tipped at (s)", tip_instant),
                    ("landed at (s)", landing)],
    SLIDE_39: [("slid in 6 s (m)", distance_m)],
    EDGE_24: [("landed at (s)", landing)],
    EDGE_27: [("landed at (s)", landing)],
    LANDED_THRUST: [("outcome", outcome), ("slid in 6 s (m)", distance_m)],
    LANDED_TORQUE: [("outcome", outcome), ("tipped at (s)", tip_instant)],
    TIPPED_RCS: [("under 80 deg at (s)", lambda tr: righting(tr)[0]),
                 ("its rate (deg/s)", lambda tr: righting(tr)[1]),
                 ("spin about up at 1 s (rad/s)", lambda tr: at(tr, yaw_rate_up(tr), 1.0)),
                 ("lowest tilt after (deg)", lowest_after_righting)],
    TIPPED_RCS_LONG: [("lowest tilt after (deg)", lowest_after_righting)],
    TIPPED_RCS_PLANE: [("under 80 deg at (s)", lambda tr: righting(tr)[0])],
    SPIN_SLIDE: [("spin about up at 0.2 s", lambda tr: at(tr, yaw_rate_up(tr), 0.2)),
                 ("at 1 s (rad/s)", lambda tr: at(tr, yaw_rate_up(tr), 1.0)),
                 ("yaw at the end (deg)", lambda tr: float(yaw_deg(tr)[-1])),
                 ("east at the end (m)", lambda tr: float(horizontal_m(tr)[-1, 0])),
                 ("landed at (s)", landing)],
    SKID_EDGE: [("peak tilt (deg)", peak_tilt), ("landed at (s)", landing)],
    SPIN_TOUCHDOWN: [("landed at (s)", landing)],
    EDGE_20_24: [("tilt at 1 s (deg)", lambda tr: at(tr, tilt_deg(tr), 1.0)),
                 ("liftoff (s)", lambda tr: tr.first("liftoff")),
                 ("tipped at (s)", tip_instant)],
    EDGE_20_285: [("tilt at 1 s (deg)", lambda tr: at(tr, tilt_deg(tr), 1.0)),
                  ("liftoff (s)", lambda tr: tr.first("liftoff")),
                  ("tipped at (s)", tip_instant)],
    COMBINED: [("tilt at 1 s (deg)", lambda tr: at(tr, tilt_deg(tr), 1.0)),
               ("liftoff (s)", lambda tr: tr.first("liftoff")),
               ("tipped at (s)", tip_instant)],
}


def table(dts=(0.1, 0.05, 0.005), scenes=None, sim: dict | None = None,
          contact: dict | None = None) -> list[tuple]:
    """Rows (scene, what, reference, the simulation at each dt) of every measure of MEASURES."""
    rows = []
    for sc, measures in MEASURES.items():
        if scenes is not None and sc.name not in scenes:
            continue
        ref = run_reference(sc)
        runs = [run_sim(sc, dt, sim, contact) for dt in dts]
        for what, f in measures:
            vals = [f(ref)] + [f(r) for r in runs]
            rows.append((sc.name, what, *[v if isinstance(v, str) else _fmt(v) for v in vals]))
    return rows


if __name__ == "__main__":  # the table: python -m touchdown.bench.edges3d [dt ...]
    import sys
    dts = tuple(float(x) for x in sys.argv[1:]) or (0.1, 0.05, 0.02, 0.005)
    print("| scene | measure | reference | " + " | ".join(f"dt {d:g}" for d in dts) + " |")
    print("| --- | --- | --- | " + " | ".join("---" for _ in dts) + " |")
    for row in table(dts):
        print("| " + " | ".join(str(x) for x in row) + " |")
