"""Frames and the body's rotation: the inertial frame centred on the body (where ships move), the
body-fixed frame turning with it at Omega about +z (where pinned ships rest and the terrain is),
and the landing-site frame (east, north, up) in which positions are reported.

The site is the body-fixed +x axis: east is body-fixed +y, north +z, and up is +x measured from the
reference sphere (``body.radius``), so the site frame's origin is the point of the sphere under the
site. The body's rotation angle at an instant comes from one scalar libm call shared by every ship.
"""
from __future__ import annotations

import math

import numpy as np

from sim import contact, vec
from sim.params import Params
from sim.state import State

_Z = np.array([0.0, 0.0, 1.0])


def body_rotation(params: Params, t_s: float) -> tuple[float, float]:
    """(cos, sin) of the body's rotation angle Omega t. One scalar libm call per instant, shared by
    every ship, so it cannot make ships differ."""
    theta = params.body.omega_radps * t_s
    return (1.0, 0.0) if theta == 0.0 else (math.cos(theta), math.sin(theta))


def ground_at(params: Params, t_s: float) -> contact.Ground:
    """The ground at one instant shared by the batch (tick ends)."""
    c, s = body_rotation(params, t_s)
    return contact.Ground(params.body.radius_m, params.body.terrain, c, s,
                          params.body.omega_radps, params.contact.surface_normal == "radial")


def rotate_z(v: np.ndarray, c: float, s: float) -> np.ndarray:
    """Rotate inertial vectors (N,3) by angle (c = cos, s = sin) about +z."""
    out = v.copy()
    out[:, 0] = c * v[:, 0] - s * v[:, 1]
    out[:, 1] = s * v[:, 0] + c * v[:, 1]
    return out


def quat_z(c: float, s: float, n: int) -> np.ndarray:
    """Quaternions (n,4) of the rotation about +z whose angle has cosine c and sine s (half-angle
    formulas: sqrt only)."""
    ch = math.sqrt(max(0.0, 0.5 * (1.0 + c)))
    sh = math.copysign(math.sqrt(max(0.0, 0.5 * (1.0 - c))), s)
    q = np.zeros((n, 4))
    q[:, 0] = ch
    q[:, 3] = sh
    return q


def pin_pose(p: np.ndarray, q: np.ndarray, c: float, s: float) -> tuple[np.ndarray, np.ndarray]:
    """Inertial pose -> body-fixed pose at body angle (c, s)."""
    if c == 1.0 and s == 0.0:
        return p.copy(), q.copy()
    return rotate_z(p, c, -s), vec.quat_mul(quat_z(c, -s, p.shape[0]), q)


def surface_velocity(params: Params, p: np.ndarray) -> np.ndarray:
    """Omega z x p: velocity of the body's surface (or a pinned ship) at p."""
    om = params.body.omega_radps
    out = np.zeros_like(p)
    if om == 0.0:
        return out
    out[:, 0] = -om * p[:, 1]
    out[:, 1] = om * p[:, 0]
    return out


def surface_spin_w(params: Params, n: int) -> np.ndarray:
    return np.broadcast_to(_Z * params.body.omega_radps, (n, 3))


def body_spin_in_body_frame(params: Params, q: np.ndarray) -> np.ndarray:
    """The body's spin (0, 0, Omega) expressed in each ship's body frame."""
    if params.body.omega_radps == 0.0:
        return np.zeros((q.shape[0], 3))
    return vec.quat_rotate_inv(q, np.broadcast_to(_Z * params.body.omega_radps, (q.shape[0], 3)))


def effective_gravity(params: Params, p: np.ndarray) -> np.ndarray:
    """Gravity plus the centrifugal acceleration of the frame turning with the body,
    -GM p / r^3 + Omega^2 (p_x, p_y, 0), m/s^2: what a ship held on the surface weighs by. The
    same expression in the inertial and the body-fixed frames (both turn about z)."""
    r2 = vec.dot(p, p)
    g = vec.scale(p, -params.body.gm_m3ps2 / (r2 * np.sqrt(r2)))
    om2 = params.body.omega_radps ** 2
    if om2 != 0.0:
        g[:, 0] += om2 * p[:, 0]
        g[:, 1] += om2 * p[:, 1]
    return g


def inertia(params: Params, st: State) -> np.ndarray:
    """Principal inertia (N,3), scaled with the wet mass (fuel spread like the structure)."""
    return params.ships.inertia0_kgm2 * (st.mass_kg / params.ships.mass0_kg)[:, None]


def site_frame(params: Params, p: np.ndarray, v: np.ndarray, t_s: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """(east, north, up) of centres of mass (N,3), m, and their velocity relative to the surface
    in the same axes (v_east, v_north, v_up), m/s, at time t_s."""
    c, s = body_rotation(params, t_s)
    pos = site_axes(rotate_z(p, c, -s))
    pos[:, 2] -= params.body.radius_m
    return pos, site_axes(rotate_z(v - surface_velocity(params, p), c, -s))


def site_axes(v_bf: np.ndarray) -> np.ndarray:
    """Body-fixed vectors (N,3) in the site's axes: (east, north, up) = body-fixed (y, z, x)."""
    return np.stack([v_bf[:, 1], v_bf[:, 2], v_bf[:, 0]], axis=1)
