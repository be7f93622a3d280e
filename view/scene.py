"""What a view draws, read from a log as columns (one array per quantity, over ticks): no Rerun here.

Everything is expressed in the landing-site frame (east, north, up; sim.frames): Rerun stores
positions as float32, which 1.7e6 m from the body's centre step by about 0.1 m and would hide a
millimetre's sag; a metre from the site they step by 6e-8 m. Derived quantities come from the
logged state through the same ``sim`` functions the step and ``export`` use (site frame, energy,
the feet), with the parameters of the log's own recorded scenario.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from touchdown.logs import LogError, derived
from touchdown.logs.reader import LogReader
from touchdown.logs.rebuild import fleet_params, scenario_of
from touchdown.sim import fields, measure
from touchdown.sim.dynamics import Motion
from touchdown.sim.enums import SurfaceState
from touchdown.sim.measure import ENERGY_PARTS
from touchdown.sim.params import Params


#: The seed's client display: CONTACT yellow, TIPPED red ("Client Display"); the others ours.
#: Every view colours a ship's state so (Rerun's, Foxglove's).
STATE_COLORS = {
    SurfaceState.FLYING: (120, 170, 255),
    SurfaceState.CONTACT: (255, 210, 0),
    SurfaceState.LANDED: (60, 200, 90),
    SurfaceState.TIPPED: (230, 40, 40),
    SurfaceState.CRASHED: (130, 0, 120),
}


@dataclass(frozen=True)
class LanderShape:
    """A lander as the views draw it, in its own frame (origin at the centre of mass, z along
    the long axis), from its leg radius ``a`` and centre-of-mass height ``h`` (the feet are at
    z = -h, a from the axis: the footprint the contact model uses): a descent stage (a box, in
    its state's colour), an ascent stage (an ellipsoid), four legs from the descent stage to
    the feet, footpads, and the footprint the topple turns about."""

    descent_center: tuple[float, float, float]
    descent_half: tuple[float, float, float]
    ascent_center: tuple[float, float, float]
    ascent_half: tuple[float, float, float]
    leg_tops: tuple[tuple[float, float, float], ...]
    feet: tuple[tuple[float, float, float], ...]
    pad_radius: float
    leg_radius: float  # the legs' thickness (radius), m

    @staticmethod
    def of(a: float, h: float) -> "LanderShape":
        feet = ((a, 0.0, -h), (0.0, a, -h), (-a, 0.0, -h), (0.0, -a, -h))
        return LanderShape(
            descent_center=(0.0, 0.0, -0.35 * h), descent_half=(0.55 * a, 0.55 * a, 0.3 * h),
            ascent_center=(0.0, 0.0, 0.2 * h), ascent_half=(0.4 * a, 0.4 * a, 0.35 * h),
            leg_tops=tuple((0.55 * x, 0.55 * y, -0.2 * h) for x, y, _ in feet), feet=feet,
            pad_radius=0.12 * a, leg_radius=0.03 * a)


@dataclass(frozen=True)
class ShipTrack:
    """One ship's run, one entry per recorded tick (T of them)."""

    ship_id: str
    player_id: str
    leg_radius_m: float
    com_height_m: float
    max_thrust_n: float
    tick: np.ndarray  # (T,) int64
    t_s: np.ndarray  # (T,)
    state: np.ndarray  # (T,) int8, SurfaceState
    pos_site_m: np.ndarray  # (T,3) centre of mass: east, north, up
    quat_site_xyzw: np.ndarray  # (T,4) attitude in the site frame (Rerun's order)
    up_site: np.ndarray  # (T,3) local vertical (radial unit vector) in the site frame
    feet_site_m: np.ndarray  # (T,4,3) the four feet
    lowest_foot_site_m: np.ndarray  # (T,3) where the ground pushes (the deepest foot)
    gravity_site_mps2: np.ndarray  # (T,3) effective gravity (gravity plus centrifugal)
    thrust_site_n: np.ndarray  # (T,3) the engine's force, along the body's long axis
    slip_site_mps: np.ndarray  # (T,3) velocity relative to the surface (NaN where not logged)
    series: dict[str, np.ndarray] = field(default_factory=dict)  # name -> (T,)

    @cached_property
    def changes(self) -> np.ndarray:
        """(T,) bool: entries whose state differs from the one before (the first included)."""
        out = np.ones(self.state.shape[0], dtype=bool)
        out[1:] = self.state[1:] != self.state[:-1]
        return out


@dataclass(frozen=True)
class RunEvent:
    tick: int
    t_s: float
    ship_id: str
    event: str
    from_state: int
    to_state: int
    v_radial_mps: float
    tilt_deg: float


@dataclass(frozen=True)
class Run:
    """A log as a view needs it: its ships' tracks, its events, and the thresholds to draw."""

    label: str
    path: Path
    params: Params
    dt_s: float
    ships: tuple[ShipTrack, ...]
    events: tuple[RunEvent, ...]
    partial_note: str  # "" when the whole log was read
    #: the whole fleet at a glance (a log of more than one ship), else None
    overview: "FleetOverview | None" = None
    #: ships in the log (``ships`` holds those drawn in full)
    fleet_size: int = 0
    #: the file's MCAP structure is damaged, its content read all the same ("" if not)
    structure_note: str = ""



    @property
    def critical_tilt_foot_deg(self) -> np.ndarray:
        """Topple angle toward a foot, atan(a / h) (MODEL-NOTES 31), per ship."""
        sh = self.params.ships
        return np.degrees(np.arctan2(sh.leg_radius_m, sh.com_height_m))

    @property
    def critical_tilt_edge_deg(self) -> np.ndarray:
        """... and toward the edge between two feet, atan(a / (sqrt(2) h))."""
        sh = self.params.ships
        return np.degrees(np.arctan2(sh.leg_radius_m, math.sqrt(2.0) * sh.com_height_m))


@dataclass(frozen=True)
class FleetOverview:
    """Every ship of a log, in little memory: how many ships are in each state at every tick,
    and every ship's position and state at ``frames`` sampled ticks (every ``stride``-th)."""

    tick: np.ndarray  # (T,) every tick read
    t_s: np.ndarray  # (T,)
    counts: np.ndarray  # (T, 5) ships per SurfaceState
    frame_tick: np.ndarray  # (F,) the sampled ticks
    frame_t_s: np.ndarray  # (F,)
    frame_rows: np.ndarray  # (F,) ships at each sampled tick
    pos_site_m: np.ndarray  # (sum rows, 3) float32, east, north, up
    state: np.ndarray  # (sum rows,) uint8
    stride: int


#: sampled ticks of a fleet's positions at most (each holds every ship)
OVERVIEW_FRAMES = 200


def read_run(path: str | Path, label: str | None = None, ship_id: str | None = None,
             max_ships: int = 16) -> Run:
    """Read a log into columns, holding only what is drawn: the first ``max_ships`` ships (or
    ``ship_id`` alone; LogError if the log has none such) in full, and for a fleet its overview
    (FleetOverview). The log is decoded a block of ticks at a time (LogReader.blocks)."""
    path = Path(path)
    with LogReader(path) as reader:
        scn, _ = scenario_of(reader)
        params = fleet_params(reader, scn)  # every ship the log held, in key order
        ids = reader.ship_table().ids
        if ship_id is not None and ship_id not in ids:
            raise LogError(f"{path}: no ship {ship_id!r} (ships: {', '.join(ids[:10])}"
                           f"{', ...' if len(ids) > 10 else ''})")
        wanted = [ids.index(ship_id)] if ship_id is not None else list(
            range(min(len(ids), max_ships)))
        wanted_keys = np.asarray(wanted, np.int64)
        # what a log holds on every tick (sim.fields), bar the commands
        drawn = [f for f in fields.FIELDS if not f.keyframe_only and f.record != "inputs"]
        names = tuple(f.in_log for f in drawn)
        width = {f.in_log: f.per_ship for f in drawn}
        cols: dict[str, list[np.ndarray]] = {name: [] for name in names}
        ticks: list[np.ndarray] = []
        keys: list[np.ndarray] = []
        fleet = _OverviewBuilder(params, reader) if len(ids) > 1 and ship_id is None else None
        last_tick = None
        held = fields.EVERY_TICK_BY_FORMAT[reader.log_format] + \
            fields.KEYFRAME_BY_FORMAT[reader.log_format]
        for b in reader.blocks(wanted=tuple(n for n in names if n in held), reuse=True):
            last_tick = int(b.ticks[-1])
            if fleet is not None:
                fleet.add(b)
            rows = np.flatnonzero(np.isin(b.keys, wanted_keys))
            tick_rows = b.tick_of_row()[rows]
            ticks.append(tick_rows)
            keys.append(b.keys[rows])
            tick_index = np.repeat(np.arange(b.ticks.shape[0]), b.counts)[rows]
            for name in names:
                w = width.get(name, 1)
                col = b.columns.get(name)
                if col is None:  # a format-1 log: no guard
                    cols[name].append(np.full((rows.size, w), np.nan))
                    continue
                a = np.asarray(col[rows], float).reshape(rows.size, w)
                held = b.present[name][tick_index]
                if not held.all():  # a format-1 log: velocities on keyframes only
                    a[~held] = np.nan
                cols[name].append(a)
        if last_tick is None:
            raise LogError(f"{path}: the log holds no tick")
        from touchdown.logs.export import what_was_read
        note = what_was_read(reader, last_tick)
        damage = reader.structure_note()
        shown = {ids[k] for k in wanted}
        events = tuple(
            RunEvent(ev.tick, ev.t_s, ev.ship_id, ev.event, ev.from_state, ev.to_state,
                     ev.v_radial_mps, ev.ship.tilt_deg)
            for ev in reader.events() if ev.ship_id in shown)
    # the drawn ships' rows, each ship's (its ticks: it may join late or leave early) by one
    # stable sort on the key
    all_keys = np.concatenate(keys)
    all_ticks = np.concatenate(ticks)
    flat = {k: np.concatenate(v) for k, v in cols.items()}
    order = np.argsort(all_keys, kind="stable")
    bounds = np.searchsorted(all_keys[order], np.arange(len(ids) + 1))
    dt = params.sim.dt_s
    tracks = []
    for key in wanted:
        rows = order[bounds[key]:bounds[key + 1]]
        if rows.size == 0:
            continue  # joined after the part of the log that was read
        tick = all_ticks[rows]
        t_s = tick * dt
        c, s = measure.body_angles(params, t_s, tick.shape[0])
        col = {k: v[rows, 0] if v.shape[1] == 1 else v[rows] for k, v in flat.items()}
        tracks.append(_track(params, key, col, tick, t_s, c, s))
    return Run(label or path.stem, path, params, dt, tuple(tracks), events, note,
               fleet.done() if fleet is not None else None, len(ids),
               f"{path}: {damage}" if damage else "")


class _OverviewBuilder:
    """Gathers a FleetOverview block by block."""

    def __init__(self, params: Params, reader: LogReader):
        self.params = params
        sr = reader.scenario
        span = max(1, (sr.n_ticks if not sr.open_ended else 0) - reader.start_tick)
        self.stride = max(1, -(-span // OVERVIEW_FRAMES))
        self.start = reader.start_tick
        self.tick, self.t_s, self.counts = [], [], []
        self.f_tick, self.f_t, self.f_rows, self.pos, self.state = [], [], [], [], []

    def add(self, b) -> None:
        n = len(SurfaceState)
        idx = np.repeat(np.arange(b.ticks.shape[0]), b.counts)
        st = b.columns["surface_state"].reshape(-1).astype(np.int64)
        self.counts.append(np.bincount(idx * n + st, minlength=b.ticks.shape[0] * n)
                           .reshape(-1, n).astype(np.int32))
        self.tick.append(b.ticks)
        self.t_s.append(b.t_s)
        pick = np.flatnonzero((b.ticks - self.start) % self.stride == 0)
        if pick.size == 0:
            return
        rows = np.concatenate([np.arange(b.row_off[k], b.row_off[k + 1]) for k in pick])
        t = np.repeat(b.t_s[pick], b.counts[pick])
        c, s = measure.body_angles(self.params, t, rows.size)
        pos = measure.to_site(b.columns["pos_m"][rows], c, s)
        pos[:, 2] -= self.params.body.radius_m
        self.pos.append(pos.astype(np.float32))
        self.state.append(st[rows].astype(np.uint8))
        self.f_tick.append(b.ticks[pick])
        self.f_t.append(b.t_s[pick])
        self.f_rows.append(b.counts[pick])

    def done(self) -> FleetOverview:
        cat = lambda xs, dt: np.concatenate(xs) if xs else np.zeros(0, dt)  # noqa: E731
        return FleetOverview(
            cat(self.tick, np.int64), cat(self.t_s, float),
            np.concatenate(self.counts) if self.counts else np.zeros((0, len(SurfaceState))),
            cat(self.f_tick, np.int64), cat(self.f_t, float), cat(self.f_rows, np.int64),
            np.concatenate(self.pos) if self.pos else np.zeros((0, 3), np.float32),
            cat(self.state, np.uint8), self.stride)


def _track(params: Params, i: int, col: dict[str, np.ndarray], tick: np.ndarray,
           t_s: np.ndarray, c: np.ndarray, s: np.ndarray) -> ShipTrack:
    """Ship ``i`` of ``params`` (its key), from its own columns over the ticks ``tick``."""
    sh, body = params.ships, params.body
    T = tick.shape[0]
    p, q, v, w = col["pos_m"], col["quat"], col["vel_mps"], col["omega_body_radps"]
    mass = col["mass_kg"]
    a = float(sh.leg_radius_m[i])
    h = float(sh.com_height_m[i])
    pos_site = measure.to_site(p, c, s)  # each tick at its own body angle
    pos_site[:, 2] -= body.radius_m
    ft = measure.feet_at(params, p, q, a, h, c, s)
    feet_site = np.stack([measure.to_site(ft["offset_w"][:, k], c, s) for k in range(4)], axis=1)
    feet_site = feet_site + pos_site[:, None, :]
    deepest = np.argmax(ft["pen_m"], axis=1)
    lowest = feet_site[np.arange(T), deepest]
    r = np.sqrt(np.einsum("ij,ij->i", p, p))
    up_site = measure.to_site(p / r[:, None], c, s)
    g_site = measure.to_site(measure.gravity(params, p), c, s)
    w_, x_, y_, z_ = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    ez = np.stack([2 * (x_ * z_ + w_ * y_), 2 * (y_ * z_ - w_ * x_), 1 - 2 * (x_ * x_ + y_ * y_)], 1)
    thrust = ez * (col["throttle"] * float(sh.max_thrust_n[i]))[:, None]
    slip = measure.to_site(v - measure.surface_velocity(params, p), c, s)
    e = measure.energy(params, i, t_s, Motion(p, v, q, w), mass)
    series = {
        "altitude_m": col["altitude_m"], "penetration_m": col["penetration_m"],
        "peak_penetration_m": col["peak_penetration_m"],
        "tilt_deg": derived.tilt_deg(col["cos_tilt"]),  # as export computes it
        "v_radial_mps": col["v_radial_mps"], "v_tangential_mps": col["v_tangential_mps"],
        "normal_force_n": col["normal_force_n"], "friction_force_n": col["friction_force_n"],
        "fuel_kg": col["fuel_kg"], "mass_kg": mass, "throttle": col["throttle"],
        "energy_j": e["total_j"], "energy_guard_j": col["energy_guard_j"],
    }
    for part in ENERGY_PARTS:
        series[part] = e[part]
    return ShipTrack(
        ship_id=params.ships.ship_id[i], player_id=params.ships.player_id[i], leg_radius_m=a,
        com_height_m=h, max_thrust_n=float(sh.max_thrust_n[i]), tick=tick, t_s=t_s,
        state=col["surface_state"].astype(np.int8), pos_site_m=pos_site,
        quat_site_xyzw=measure.site_quats_xyzw(q, c, s), up_site=up_site, feet_site_m=feet_site,
        lowest_foot_site_m=lowest, gravity_site_mps2=g_site,
        thrust_site_n=measure.to_site(thrust, c, s), slip_site_mps=slip, series=series)


#: the half-angle of the cone a view's camera must hold every ship in (a 3-D view's vertical
#: field of view is wider; its narrower side keeps this much at the usual aspect ratios)
EYE_HALF_ANGLE_DEG = 20.0
#: where the camera looks from, relative to what it frames: from the south-west, above
EYE_DIRECTION = (-0.55, -0.75, 0.65)


def framing_eye(points: np.ndarray, half_angle_deg: float = EYE_HALF_ANGLE_DEG,
                least_radius_m: float = 5.0) -> tuple[np.ndarray, np.ndarray]:
    """(eye position, look target) of a camera that holds every one of ``points`` (N,3, site
    frame) in the cone of ``half_angle_deg`` about its line of sight: the target the centre of
    their bounding box, the eye on EYE_DIRECTION at the distance where the box's bounding
    sphere (at least ``least_radius_m``) fits that cone. A view that frames its scene by the
    data shown at one moment leaves out a ship that is elsewhere then, or comes later."""
    pts = np.asarray(points, float).reshape(-1, 3)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if pts.shape[0] == 0:
        pts = np.zeros((1, 3))
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    target = 0.5 * (lo + hi)
    radius = max(least_radius_m, float(np.linalg.norm(hi - lo)) * 0.5)
    d = np.asarray(EYE_DIRECTION, float)
    d /= np.linalg.norm(d)
    distance = radius / math.sin(math.radians(half_angle_deg))
    return target + distance * d, target


def terrain_grid(params: Params, east_m: tuple[float, float], north_m: tuple[float, float],
                 n: int = 81) -> tuple[np.ndarray, np.ndarray]:
    """The body's surface over a rectangle of the site frame: vertices (n*n, 3) and triangles.
    Height: the terrain's above the reference sphere, which falls away from the site as
    sqrt(R^2 - e^2 - n^2) - R (the site frame is the sphere's tangent plane)."""
    e = np.linspace(east_m[0], east_m[1], n)
    nn = np.linspace(north_m[0], north_m[1], n)
    E, N = np.meshgrid(e, nn, indexing="xy")
    R = params.body.radius_m
    rho2 = E * E + N * N
    sphere = -rho2 / (R + np.sqrt(np.maximum(R * R - rho2, 0.0)))  # sqrt(R^2 - rho^2) - R
    H = measure.terrain_height(params.body.terrain, E.ravel(), N.ravel()).reshape(E.shape)
    up = sphere + H * np.sqrt(np.maximum(R * R - rho2, 0.0)) / R  # along the radial, projected
    verts = np.stack([E.ravel(), N.ravel(), up.ravel()], axis=1)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c2, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    tris = np.concatenate([np.stack([a, b, c2], 1), np.stack([a, c2, d], 1)])
    return verts, tris.astype(np.uint32)

