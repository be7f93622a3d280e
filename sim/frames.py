"""Frames and the body's rotation: the inertial frame centred on the body (where ships move), the
body-fixed frame turning with it at Omega about +z (where pinned ships rest and the terrain is),
and the landing-site frame (east, north, up) in which positions are reported.

The site is the body-fixed +x axis: east is body-fixed +y, north +z, and up is +x measured from the
reference sphere (``body.radius``), so the site frame's origin is the point of the sphere under the
site. The body's rotation angle at a tick's start comes from one scalar call shared by every
ship (:func:`body_rotation`, outside the kernels: sim.trig, not libm); an instant inside the tick
adds its small angle with sim.vec's +,*,/ series (:func:`turned`), so a ship's frame depends on
its own instants alone.
One ship's functions, compiled (sim.compiled).
"""
from __future__ import annotations

import math
from typing import NamedTuple

from touchdown.sim import trig
from touchdown.sim.compiled import kernel
from touchdown.sim.vec import cos_sinc, dot, quat_mul, quat_rotate_inv


class Body(NamedTuple):
    """The body as the kernels see it: a point mass GM with its reference sphere (``body.radius``:
    the site frame's origin, and where gravity's potential is zero), turning at Omega about +z."""

    gm_m3ps2: float
    radius_m: float
    omega_radps: float


def body_rotation(omega_radps: float, t_s: float) -> tuple[float, float]:
    """(cos, sin) of the body's rotation angle Omega t at a tick's start: one scalar call per
    tick, shared by every ship, so it cannot make ships differ; sim.trig's, not libm's, whose
    last bits differ between machines (log format 6)."""
    theta = omega_radps * t_s
    return (1.0, 0.0) if theta == 0.0 else trig.cos_sin(theta)


@kernel
def turned(cos0, sin0, omega_radps, offset_s):
    """(cos, sin) of the body's angle ``offset_s`` after the angle (cos0, sin0): the small angle
    Omega offset from the series, composed with the tick's."""
    if omega_radps == 0.0:
        return 1.0, 0.0
    d = omega_radps * offset_s
    cd, sinc_d = cos_sinc(d)
    sd = d * sinc_d
    return cos0 * cd - sin0 * sd, sin0 * cd + cos0 * sd


@kernel
def rotate_z(v, c, s):
    """Rotate a vector by the angle of cosine c and sine s about +z."""
    return (c * v[0] - s * v[1], s * v[0] + c * v[1], v[2])


@kernel
def quat_z(c, s):
    """The quaternion of the rotation about +z whose angle has cosine c and sine s (half-angle
    formulas: sqrt only)."""
    ch = math.sqrt(max(0.0, 0.5 * (1.0 + c)))
    sh = math.copysign(math.sqrt(max(0.0, 0.5 * (1.0 - c))), s)
    return (ch, 0.0, 0.0, sh)


@kernel
def pin_pose(p, q, c, s):
    """Inertial pose -> body-fixed pose at body angle (c, s)."""
    if c == 1.0 and s == 0.0:
        return p, q
    return rotate_z(p, c, -s), quat_mul(quat_z(c, -s), q)


@kernel
def surface_velocity(omega_radps, p):
    """Omega z x p: velocity of the body's surface (or a pinned ship) at p."""
    if omega_radps == 0.0:
        return (0.0, 0.0, 0.0)
    return (-omega_radps * p[1], omega_radps * p[0], 0.0)


@kernel
def body_spin_in_body_frame(omega_radps, q):
    """The body's spin (0, 0, Omega) expressed in the ship's body frame."""
    if omega_radps == 0.0:
        return (0.0, 0.0, 0.0)
    return quat_rotate_inv(q, (0.0, 0.0, omega_radps))


@kernel
def effective_gravity(gm_m3ps2, omega2, p):
    """Gravity plus the centrifugal acceleration of the frame turning with the body,
    -GM p / r^3 + Omega^2 (p_x, p_y, 0), m/s^2: what a ship held on the surface weighs by. The
    same expression in the inertial and the body-fixed frames (both turn about z)."""
    r2 = dot(p, p)
    k = -gm_m3ps2 / (r2 * math.sqrt(r2))
    g = (p[0] * k, p[1] * k, p[2] * k)
    if omega2 != 0.0:
        return (g[0] + omega2 * p[0], g[1] + omega2 * p[1], g[2])
    return g


@kernel
def inertia(inertia0_kgm2, mass0_kg, mass_kg):
    """Principal inertia scaled with the wet mass (fuel spread like the structure)."""
    f = mass_kg / mass0_kg
    return (inertia0_kgm2[0] * f, inertia0_kgm2[1] * f, inertia0_kgm2[2] * f)


@kernel
def site_axes(v_bf):
    """A body-fixed vector in the site's axes: (east, north, up) = body-fixed (y, z, x)."""
    return (v_bf[1], v_bf[2], v_bf[0])
