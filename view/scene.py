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

from logs import LogError
from logs.mcap_log import LogReader, fleet_params, scenario_of
from sim import fields, measure
from sim.measure import ENERGY_PARTS
from sim.params import Params


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


def read_run(path: str | Path, label: str | None = None, ship_id: str | None = None) -> Run:
    """Read a log into columns. ``ship_id`` keeps one ship (LogError if the log has none such)."""
    path = Path(path)
    with LogReader(path) as reader:
        scn, _ = scenario_of(reader)
        params = fleet_params(reader, scn)  # every ship the log held, in key order
        ids = reader.ship_table().ids
        if ship_id is not None and ship_id not in ids:
            raise LogError(f"{path}: no ship {ship_id!r} (ships: {', '.join(ids[:10])}"
                           f"{', ...' if len(ids) > 10 else ''})")
        cols: dict[str, list[np.ndarray]] = {}
        ticks: list[int] = []
        keys: list[np.ndarray] = []
        # what a log holds on every tick (sim.fields), bar the commands
        drawn = [f for f in fields.FIELDS if not f.keyframe_only and f.record != "inputs"]
        names = tuple(f.in_log for f in drawn)
        width = {f.in_log: f.per_ship for f in drawn}
        for td in reader.ticks():
            a = td.arrays
            n = td.ship_count
            ticks.append(td.tick)
            keys.append(td.keys)
            for name in names:
                arr = a.get(name)
                if arr is None:  # a format-1 log: velocities on keyframes only, no guard
                    arr = np.full(n * width.get(name, 1), np.nan)
                cols.setdefault(name, []).append(
                    np.asarray(arr, float).reshape(n, width.get(name, 1)))  # n may be 0
        if not ticks:
            raise LogError(f"{path}: the log holds no tick")
        from logs.export import what_was_read
        note = what_was_read(reader, ticks[-1])
        events = tuple(
            RunEvent(ev.tick, ev.t_s, ev.ship_id, ev.event, ev.from_state, ev.to_state,
                     ev.v_radial_mps, ev.ship.tilt_deg)
            for ev in reader.events() if ship_id is None or ev.ship_id == ship_id)
    # every ship-tick in one array per field, then each ship's rows (its ticks: it may join late
    # or leave early) by one stable sort on the key
    per_tick = np.array([k.size for k in keys])
    all_keys = np.concatenate(keys)
    all_ticks = np.repeat(np.asarray(ticks, dtype=np.int64), per_tick)
    flat = {k: np.concatenate(v) for k, v in cols.items()}
    order = np.argsort(all_keys, kind="stable")
    bounds = np.searchsorted(all_keys[order], np.arange(len(ids) + 1))
    wanted = [ids.index(ship_id)] if ship_id is not None else range(len(ids))
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
    return Run(label or path.stem, path, params, dt, tuple(tracks), events, note)


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
    e = measure.energy(params, i, t_s, p, v, q, w, mass)
    cos_tilt = np.clip(col["cos_tilt"], -1.0, 1.0)
    series = {
        "altitude_m": col["altitude_m"], "penetration_m": col["penetration_m"],
        "peak_penetration_m": col["peak_penetration_m"],
        # as export computes it (libm's acos, not numpy's: the same digits in both)
        "tilt_deg": np.array([math.degrees(math.acos(x)) for x in cos_tilt.tolist()]),
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
    H = params.body.terrain.height_m(E.ravel(), N.ravel()).reshape(E.shape)
    up = sphere + H * np.sqrt(np.maximum(R * R - rho2, 0.0)) / R  # along the radial, projected
    verts = np.stack([E.ravel(), N.ravel(), up.ravel()], axis=1)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c2, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    tris = np.concatenate([np.stack([a, b, c2], 1), np.stack([a, c2, d], 1)])
    return verts, tris.astype(np.uint32)

