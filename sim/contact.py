"""Ground contact of the landing legs: the seed's penalty spring-damper, applied at each foot.

Each of the four feet sits at ``leg_radius`` from the long axis, ``com_height`` below the centre of
mass (body frame: (a dx, a dy, -h)). A foot's penetration is measured along the local radial, as the
seed measures it, ``x = R + h(east, north) - |foot|`` (R the body's radius, h the terrain's height
under the foot), and the ground pushes it out by

    F_i = max(0, k_i x_i + c_i x_i') g_i,   g_i = -grad x_i,   k_i = k / 4,  c_i = c / 4,

with k = 100 m and c = 2 zeta sqrt(k m) (seed, "Ground Reaction Forces" and "Bounce"). On level
ground g_i is the radial unit vector and an upright ship on four feet feels exactly the seed's
single spring k and damper c. On a slope g_i is the terrain's normal (``contact.surface_normal =
"terrain"``, the default; the seed deferred terrain normals, SEED-NOTES and MODEL-NOTES 22), of
length sec(slope): the force is minus the gradient of the potential k_i x_i^2 / 2, so the spring
stores exactly what it takes (a frictionless ship climbing a hill slows as energy says), and the
damper's power is -c_i x_i'^2. ``"radial"`` keeps the seed's radial push on any slope.

Tilted, only the low feet touch, so the ground's push acts at the rim of the footprint: that gives
the restoring moment below the critical tilt and the toppling one above it (SEED-NOTES 5), without
a special case. The critical tilt is atan(a / h) toward a foot (37 degrees for the default lander)
and atan(a / (sqrt(2) h)) toward the edge between two feet (28 degrees).

An impact slower than ``bounce_speed`` is absorbed (SEED-NOTES 1): its contact uses the absorber's
damping ratio and is bilateral while a foot is compressed (no clamp at zero), so it cannot throw the
ship back off the ground.

Velocities are taken relative to the body's surface (``Omega z x p`` subtracted), and the ground is
evaluated at the instant of each evaluation: on a rotating body the terrain moves under the ship.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim import vec
from sim.constants import LEG_DIRECTIONS_BODY
from sim.params import Terrain

Array = np.ndarray
Four = tuple[Array, Array, Array, Array]


@dataclass(frozen=True)
class Ground:
    """The body's surface at one instant (per ship: ``cos_theta``/``sin_theta`` may be arrays (N,))."""

    radius_m: float
    terrain: Terrain
    cos_theta: float | Array  # body rotation angle theta = Omega t, as its cosine and sine
    sin_theta: float | Array
    spin_radps: float = 0.0  # Omega, about the inertial +z axis
    radial: bool = False  # the seed's normal: radial whatever the terrain's slope

    def site_coords(self, point: Array) -> tuple[Array, Array]:
        """(east, north) of inertial points (N,3): their body-fixed (y, z)."""
        return -self.sin_theta * point[:, 0] + self.cos_theta * point[:, 1], point[:, 2]

    def surface_radius_m(self, point: Array) -> Array:
        """Body radius plus terrain height under inertial points (N,3)."""
        east, north = self.site_coords(point)
        return self.radius_m + self.terrain.height_m(east, north)

    def under(self, point: Array) -> tuple[Array, Array]:
        """(x, g): the penetration x = R + h - |p| of points (N,3) and g = -grad x, the direction
        the ground pushes them (unit radial on level ground or with ``radial``)."""
        r = vec.norm(point)
        r_hat = point / r[:, None]
        east, north = self.site_coords(point)
        if self.terrain.flat:
            return self.radius_m + self.terrain.base_height_m - r, r_hat
        h, dh_de, dh_dn = self.terrain.height_and_slope(east, north)
        pen = self.radius_m + h - r
        if self.radial:
            return pen, r_hat
        # grad east = body-fixed y axis in the inertial frame, (-sin, cos, 0); grad north = z
        push = r_hat.copy()
        push[:, 0] += dh_de * self.sin_theta
        push[:, 1] -= dh_de * self.cos_theta
        push[:, 2] -= dh_dn
        return pen, push

    def surface_velocity(self, point: Array) -> Array:
        """Omega z x p: the velocity of the body's surface (a body-fixed point) at p."""
        out = np.zeros_like(point)
        if self.spin_radps != 0.0:
            out[:, 0] = -self.spin_radps * point[:, 1]
            out[:, 1] = self.spin_radps * point[:, 0]
        return out


@dataclass(frozen=True)
class Feet:
    """The four feet at one instant."""

    offset_w: Four  # (N,3) each: from the centre of mass, inertial
    pos_w: Four  # (N,3) each
    pen_m: Four  # (N,) each: penetration (negative: height above the ground)
    push_w: Four  # (N,3) each: g = -grad x, the direction the ground pushes


def body_axes(q: Array) -> tuple[Array, Array, Array]:
    """The body x, y, z axes in the inertial frame: the columns of the rotation matrix of q."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    ex = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)], axis=1)
    ey = np.stack([2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)], axis=1)
    ez = np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=1)
    return ex, ey, ez


def foot_offsets_w(q: Array, leg_radius_m: Array, com_height_m: Array) -> list[Array]:
    """Each foot's position relative to the centre of mass, inertial, four arrays (N,3)."""
    ex, ey, ez = body_axes(q)
    down = vec.scale(ez, -com_height_m)
    out = []
    for dx, dy in LEG_DIRECTIONS_BODY:
        lateral = ex if dx else ey
        sign = dx if dx else dy
        out.append(down + vec.scale(lateral, sign * leg_radius_m))
    return out


def feet(pos_m: Array, quat: Array, leg_radius_m: Array, com_height_m: Array,
         ground: Ground) -> Feet:
    """Where the feet are, how deep, and which way the ground would push them."""
    offsets = foot_offsets_w(quat, leg_radius_m, com_height_m)
    pos, pen, push = [], [], []
    for offset in offsets:
        foot = pos_m + offset
        x, g = ground.under(foot)
        pos.append(foot)
        pen.append(x)
        push.append(g)
    return Feet(tuple(offsets), tuple(pos), tuple(pen), tuple(push))


def lowest_foot_penetration(pos_m: Array, quat: Array, leg_radius_m: Array,
                            com_height_m: Array, ground: Ground) -> Array:
    """Penetration of the deepest foot (negative: height of the lowest foot above its ground);
    the same numbers as :func:`evaluate`'s ``max_penetration_m``, without the forces."""
    ft = feet(pos_m, quat, leg_radius_m, com_height_m, ground)
    deepest = ft.pen_m[0]
    for x in ft.pen_m[1:]:
        deepest = np.maximum(deepest, x)
    return deepest


@dataclass(frozen=True)
class ContactEval:
    """The ground's action on each ship at one instant."""

    feet: Feet | None  # None: ships known to be clear of the ground (no contact work done)
    foot_force_n: Four  # (N,) each: k x + c x' of each foot (clamped at 0 unless absorbing)
    force_w: Array  # (N, 3) total force, inertial
    torque_w: Array  # (N, 3) its moment about the centre of mass, inertial
    normal_n: Array  # (N,) sum of the feet's force magnitudes (< 0 only while absorbing)
    max_penetration_m: Array  # (N,) deepest foot (negative: lowest foot's height above ground)
    lowest_foot_w: Array  # (N, 3) the deepest (or lowest) foot
    # The pressing feet (those whose force is not clamped away) as one linear spring-damper along
    # the centre of mass's radial n, for the exact method (sim.integrators.exponential): with
    # gamma_i = g_i . n, the sums of k_i gamma_i^2, c_i gamma_i^2, k_i gamma_i x_i and
    # k_i gamma_i x_i' (zeros unless asked for: evaluate's linear_model).
    stiffness_npm: Array  # (N,)
    damping_nspm: Array  # (N,)
    spring_load_n: Array  # (N,)
    spring_load_rate_nps: Array  # (N,)


def evaluate(pos_m: Array, vel_mps: Array, quat: Array, omega_w: Array, leg_radius_m: Array,
             com_height_m: Array, k_npm: Array, c_nspm: Array, c_absorb_nspm: Array,
             absorbing: Array, ground: Ground, engage_m: Array | float = 0.0,
             linear_model: bool = False) -> ContactEval:
    """Normal force, its moment, and penetration for every ship (see the module docstring).

    ``engage_m``: a foot counts as touching from ``x > -engage_m``; a step that starts exactly
    at the surface crossing passes a micrometre so that rounding cannot leave out the damper's
    jump at its first stage. ``linear_model``: also sum the pressing feet's stiffness, damping,
    load and load rate along the radial (zeros otherwise)."""
    n = pos_m.shape[0]
    force = np.zeros((n, 3))
    torque = np.zeros((n, 3))
    normal = np.zeros(n)
    max_pen = np.full(n, -np.inf)
    lowest = np.zeros((n, 3))
    stiff, damp, load, load_rate = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    k_leg = 0.25 * k_npm
    c_leg = np.where(absorbing, 0.25 * c_absorb_nspm, 0.25 * c_nspm)
    ft = feet(pos_m, quat, leg_radius_m, com_height_m, ground)
    n_hat = vec.unit(pos_m) if linear_model else None
    forces = []
    for offset, foot, pen, push in zip(ft.offset_w, ft.pos_w, ft.pen_m, ft.push_w):
        v_foot = vel_mps + vec.cross(omega_w, offset) - ground.surface_velocity(foot)
        pen_rate = -vec.dot(push, v_foot)
        f = k_leg * pen + c_leg * pen_rate
        if linear_model:
            pressing = (pen > -engage_m) & (absorbing | (f > 0.0))
            gamma = vec.dot(push, n_hat)
            k_g = np.where(pressing, k_leg * gamma, 0.0)
            stiff += k_g * gamma
            damp += np.where(pressing, c_leg * gamma * gamma, 0.0)
            load += k_g * pen
            load_rate += k_g * pen_rate
        f = np.where(absorbing, f, np.maximum(f, 0.0))
        f = np.where(pen > -engage_m, f, 0.0)
        forces.append(f)
        f_vec = vec.scale(push, f)
        force += f_vec
        torque += vec.cross(offset, f_vec)
        normal += f * vec.norm(push)
        deeper = pen > max_pen
        lowest = np.where(deeper[:, None], foot, lowest)
        max_pen = np.where(deeper, pen, max_pen)
    return ContactEval(ft, tuple(forces), force, torque, normal, max_pen, lowest, stiff, damp,
                       load, load_rate)


def no_contact(n: int, pos_m: Array) -> ContactEval:
    """The evaluation of ships known to be clear of the ground for the whole step."""
    z3, z1 = np.zeros((n, 3)), np.zeros(n)
    return ContactEval(None, (z1, z1, z1, z1), z3, z3, z1, np.full(n, -np.inf), pos_m, z1, z1,
                       z1, z1)
