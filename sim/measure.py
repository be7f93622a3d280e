"""The step's own quantities for many recorded instants at once: what ``export``, the view and the
tests read off a logged state (site frame, feet, energy, gravity), computed by the same compiled
functions the step uses, one row at a time. Each row carries its own ship's numbers (leg radius,
inertia, ...) and its own body angle, so a row may be any ship at any tick.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from touchdown.sim.compiled import constructor, entry
from touchdown.sim.contact import Feet, Ground, Legs, feet, height_and_slope
from touchdown.sim.dynamics import Motion
from touchdown.sim.energy import mechanical, total
from touchdown.sim.frames import (Body, body_rotation, effective_gravity, quat_z, rotate_z,
    site_axes)
from touchdown.sim.frames import surface_velocity as _surface_velocity
from touchdown.sim.params import Params, Terrain
from touchdown.sim.settings import SurfaceNormal
from touchdown.sim.vec import angle_between, quat_axis_z, quat_mul, sub, unit

ENERGY_PARTS = ("translational_j", "rotational_j", "gravity_j", "centrifugal_j",
                "centrifugal_spin_j", "spring_j")


def _vec(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=float).reshape(-1, a.shape[-1])


def body_angles(params: Params, t_s: np.ndarray | float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(cos, sin) of the body's angle at each instant (one per row), as the step gets it at a
    tick's start (sim.frames.body_rotation)."""
    t = np.broadcast_to(np.asarray(t_s, dtype=float), (n,))
    om = params.body.omega_radps
    if n == 0:
        return np.zeros(0), np.zeros(0)
    # one call per run of equal instants (rows come tick by tick: a fleet's rows share one)
    starts = np.concatenate(([0], np.flatnonzero(t[1:] != t[:-1]) + 1))
    cs = np.array([body_rotation(om, float(x)) for x in t[starts]]).reshape(-1, 2)
    lengths = np.diff(np.append(starts, n))
    return np.repeat(cs[:, 0], lengths), np.repeat(cs[:, 1], lengths)


@entry
def _terrain_height(terrain, east, north, out):
    g = Ground(0.0, terrain[0], 1.0, 0.0, 0.0, False)
    for i in range(east.shape[0]):
        out[i] = height_and_slope(g, east[i], north[i])[0]


def terrain_height(terrain: Terrain, east_m: np.ndarray, north_m: np.ndarray) -> np.ndarray:
    """The terrain's height at site coordinates, m (sim.contact.height_and_slope)."""
    e = np.ascontiguousarray(east_m, dtype=float)
    n = np.ascontiguousarray(north_m, dtype=float)
    flat_e, flat_n = e.ravel(), np.broadcast_to(n, e.shape).ravel().copy()
    out = np.empty(flat_e.shape[0])
    _terrain_height(terrain.record(), flat_e, flat_n, out)
    return out.reshape(e.shape)


@entry
def _site_frame(radius, om, angles, p, v, out):
    cos_t, sin_t = angles
    pos_out, vel_out = out
    for i in range(p.shape[0]):
        pi = (p[i, 0], p[i, 1], p[i, 2])
        vi = (v[i, 0], v[i, 1], v[i, 2])
        c, s = cos_t[i], sin_t[i]
        a = site_axes(rotate_z(pi, c, -s))
        b = site_axes(rotate_z(sub(vi, _surface_velocity(om, pi)), c, -s))
        pos_out[i, 0], pos_out[i, 1], pos_out[i, 2] = a[0], a[1], a[2] - radius
        vel_out[i, 0], vel_out[i, 1], vel_out[i, 2] = b[0], b[1], b[2]


def site_frame(params: Params, p: np.ndarray, v: np.ndarray, t_s: np.ndarray | float
               ) -> tuple[np.ndarray, np.ndarray]:
    """(east, north, up) of centres of mass (N,3), m, and their velocity relative to the surface
    in the same axes (v_east, v_north, v_up), m/s, at time(s) t_s. The site frame's origin is the
    point of the reference sphere under the site (sim.frames)."""
    p, v = _vec(p), _vec(v)
    c, s = body_angles(params, t_s, p.shape[0])
    pos, vel = np.empty_like(p), np.empty_like(p)
    _site_frame(params.body.radius_m, params.body.omega_radps, (c, s), p, v, (pos, vel))
    return pos, vel


@entry
def _to_site(cos_t, sin_t, v, out):
    for i in range(v.shape[0]):
        a = site_axes(rotate_z((v[i, 0], v[i, 1], v[i, 2]), cos_t[i], -sin_t[i]))
        out[i, 0], out[i, 1], out[i, 2] = a[0], a[1], a[2]


def to_site(v: np.ndarray, cos_t: np.ndarray, sin_t: np.ndarray) -> np.ndarray:
    """Inertial vectors (N,3) at body angles (cos, sin) into site axes (east, north, up)."""
    v = _vec(v)
    out = np.empty_like(v)
    _to_site(np.ascontiguousarray(cos_t, float), np.ascontiguousarray(sin_t, float), v, out)
    return out


@entry
def _site_quats(cos_t, sin_t, q, out):
    # the site frame's axes (east, north, up) are the body-fixed (y, z, x): (0.5, -0.5, -0.5, -0.5)
    # turns body-fixed vectors into site-frame ones (a turn of -120 degrees about (1, 1, 1))
    perm = (0.5, -0.5, -0.5, -0.5)
    for i in range(q.shape[0]):
        c, s = cos_t[i], sin_t[i]
        undo = quat_z(c, -s)  # rotation by -theta about z
        qs = quat_mul(perm, quat_mul(undo, (q[i, 0], q[i, 1], q[i, 2], q[i, 3])))
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = qs[1], qs[2], qs[3], qs[0]


def site_quats_xyzw(q: np.ndarray, cos_t: np.ndarray, sin_t: np.ndarray) -> np.ndarray:
    """Attitudes (N,4, w x y z, body -> inertial) as body -> site quaternions in x y z w."""
    q = _vec(q)
    out = np.empty_like(q)
    _site_quats(np.ascontiguousarray(cos_t, float), np.ascontiguousarray(sin_t, float), q, out)
    return out


class Grounds(NamedTuple):
    """The ground under each row: sim.contact.Ground at the row's own body angle (``cos_theta[i]``,
    ``sin_theta[i]``), on the scene's body and terrain."""

    body: Body  # sim.frames.Body
    terrain: np.ndarray  # one record of sim.contact.TERRAIN_DTYPE (an array of one)
    radial: bool  # the seed's radial normal on any slope
    cos_theta: np.ndarray  # one per row
    sin_theta: np.ndarray


def _grounds(params: Params, cos_t: np.ndarray, sin_t: np.ndarray) -> Grounds:
    body = params.body
    return Grounds(Body(float(body.gm_m3ps2), float(body.radius_m), float(body.omega_radps)),
                   params.terrain, params.contact.surface_normal == SurfaceNormal.RADIAL,
                   np.ascontiguousarray(cos_t, float), np.ascontiguousarray(sin_t, float))


@constructor
def _row_ground(grounds, i):
    """Row i's ground (a Ground holds a record: built where it is used, sim.compiled)."""
    body = grounds.body
    return Ground(body.radius_m, grounds.terrain[0], grounds.cos_theta[i], grounds.sin_theta[i],
                  body.omega_radps, grounds.radial)


@entry
def _feet(grounds, p, q, leg, height, out):
    for i in range(p.shape[0]):
        ft = feet(_row_ground(grounds, i), (p[i, 0], p[i, 1], p[i, 2]),
                  (q[i, 0], q[i, 1], q[i, 2], q[i, 3]), leg[i], height[i])
        for k in range(4):
            out.pen_m[i, k] = ft.pen_m[k]
            for j in range(3):
                out.offset_w[i, k, j] = ft.offset_w[k][j]
                out.pos_w[i, k, j] = ft.pos_w[k][j]
                out.push_w[i, k, j] = ft.push_w[k][j]


def feet_at(params: Params, p: np.ndarray, q: np.ndarray, leg_radius_m: np.ndarray,
            com_height_m: np.ndarray, cos_t: np.ndarray, sin_t: np.ndarray
            ) -> dict[str, np.ndarray]:
    """The four feet of each row (sim.contact.feet): ``offset_w``, ``pos_w``, ``push_w`` (N,4,3)
    and ``pen_m`` (N,4)."""
    p, q = _vec(p), _vec(q)
    n = p.shape[0]
    out = Feet(np.empty((n, 4, 3)), np.empty((n, 4, 3)), np.empty((n, 4)), np.empty((n, 4, 3)))
    _feet(_grounds(params, cos_t, sin_t), p, q,
          np.broadcast_to(np.asarray(leg_radius_m, float), (n,)).copy(),
          np.broadcast_to(np.asarray(com_height_m, float), (n,)).copy(), out)
    return out._asdict()


@entry
def _energy(grounds, legs, mass, inertia, motion, out):
    # legs, motion: sim.contact.Legs and sim.dynamics.Motion of arrays, a row each
    p, v, q, w = motion
    for i in range(p.shape[0]):
        e = mechanical(grounds.body, mass[i], (inertia[i, 0], inertia[i, 1], inertia[i, 2]),
                       Legs(legs.leg_radius_m[i], legs.com_height_m[i], legs.k_npm[i]),
                       Motion((p[i, 0], p[i, 1], p[i, 2]), (v[i, 0], v[i, 1], v[i, 2]),
                              (q[i, 0], q[i, 1], q[i, 2], q[i, 3]), (w[i, 0], w[i, 1], w[i, 2])),
                       _row_ground(grounds, i), True)
        out[i, 0], out[i, 1], out[i, 2] = e.translational_j, e.rotational_j, e.gravity_j
        out[i, 3], out[i, 4], out[i, 5] = e.centrifugal_j, e.centrifugal_spin_j, e.spring_j
        out[i, 6] = total(e)


def energy(params: Params, ship: np.ndarray, t_s: np.ndarray | float, motion: Motion,
           mass_kg: np.ndarray) -> dict[str, np.ndarray]:
    """sim.energy of recorded states: row i is ship ``ship[i]`` of ``params`` at time ``t_s[i]``
    (or one time for all), moving as row i of ``motion`` (a sim.dynamics.Motion of arrays:
    positions, velocities, attitudes, body rates). Returns each part of :data:`ENERGY_PARTS` and
    ``total_j``."""
    p, v, q, w = (_vec(x) for x in motion)
    n = p.shape[0]
    ship = np.broadcast_to(np.asarray(ship, dtype=np.int64), (n,))
    sh = params.ships
    mass = np.broadcast_to(np.asarray(mass_kg, float), (n,)).copy()
    inertia = sh.inertia0_kgm2[ship] * (mass / sh.mass0_kg[ship])[:, None]
    c, s = body_angles(params, t_s, n)
    legs = Legs(sh.leg_radius_m[ship].copy(), sh.com_height_m[ship].copy(),
                sh.stiffness_per_kg[ship] * mass)  # k = (k/m) m, as sim.step's FreeBody
    out = np.empty((n, 7))
    _energy(_grounds(params, c, s), legs, mass, np.ascontiguousarray(inertia),
            Motion(p, v, q, w), out)
    parts = {name: out[:, k] for k, name in enumerate(ENERGY_PARTS)}
    parts["total_j"] = out[:, 6]
    return parts


@entry
def _gravity(gm, om2, p, out):
    for i in range(p.shape[0]):
        g = effective_gravity(gm, om2, (p[i, 0], p[i, 1], p[i, 2]))
        out[i, 0], out[i, 1], out[i, 2] = g[0], g[1], g[2]


def gravity(params: Params, p: np.ndarray) -> np.ndarray:
    """Effective gravity at each point (N,3), m/s^2 (sim.frames.effective_gravity)."""
    p = _vec(p)
    out = np.empty_like(p)
    om = params.body.omega_radps
    _gravity(params.body.gm_m3ps2, om * om, p, out)
    return out


@entry
def _surface_velocity_rows(om, p, out):
    for i in range(p.shape[0]):
        u = _surface_velocity(om, (p[i, 0], p[i, 1], p[i, 2]))
        out[i, 0], out[i, 1], out[i, 2] = u[0], u[1], u[2]


def surface_velocity(params: Params, p: np.ndarray) -> np.ndarray:
    """Omega z x p at each point (N,3), m/s (sim.frames.surface_velocity)."""
    p = _vec(p)
    out = np.empty_like(p)
    _surface_velocity_rows(params.body.omega_radps, p, out)
    return out


@entry
def _tilt_rows(p, q, out):
    for i in range(p.shape[0]):
        ez = quat_axis_z((q[i, 0], q[i, 1], q[i, 2], q[i, 3]))
        out[i] = angle_between(ez, unit((p[i, 0], p[i, 1], p[i, 2])))


def tilt_from_vertical_rad(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The long axis's tilt from local vertical at each row, rad: the angle between the body z
    axis of q (N,4, w x y z) and p / |p| (N,3), by sim.vec.angle_between. IEEE +, *, / and sqrt
    in a fixed order: the same bits on every machine, where acos(ez . r_hat) by numpy and libm
    took the host's BLAS kernel and libm (log format 6, logs.header)."""
    p, q = _vec(p), _vec(q)
    out = np.empty(p.shape[0])
    _tilt_rows(p, q, out)
    return out
