"""Ground contact of the landing legs: the seed's penalty spring-damper, applied at each foot.

Each of the four feet sits at ``leg_radius`` from the long axis, ``com_height`` below the centre of
mass (body frame: (a dx, a dy, -h)). A foot below the terrain under it is pushed out along the local
radial direction (the seed keeps the surface normal radial) by

    F_i = max(0, k_i x_i + c_i x_i'),  x_i = surface_r(foot) - |foot|,  k_i = k / 4, c_i = c / 4,

with k = 100 m and c = 2 zeta sqrt(k m) (seed, "Ground Reaction Forces" and "Bounce"). An upright
ship on four feet feels exactly the seed's single spring k and damper c. Tilted, only the low feet
touch, so the ground's push acts at the rim of the footprint: that gives the restoring moment below
the critical tilt atan(leg_radius / com_height) and the toppling one above it (SEED-NOTES 5),
without a special case.

An impact slower than ``bounce_speed`` is absorbed (SEED-NOTES 1): its contact uses the absorber's
damping ratio and is bilateral while a foot is compressed (no clamp at zero), so it cannot throw the
ship back off the ground.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim import vec
from sim.constants import LEG_DIRECTIONS_BODY
from sim.params import Terrain


@dataclass(frozen=True)
class Ground:
    """What the contact needs to know about the body at one instant."""

    radius_m: float
    terrain: Terrain
    cos_theta: float  # body rotation angle theta = Omega t, as its cosine and sine
    sin_theta: float

    def surface_radius_m(self, point: np.ndarray) -> np.ndarray:
        """Body radius plus terrain height under inertial points (N,3)."""
        # body-fixed coordinates: rotate by -theta about z; east = y_bf, north = z_bf
        east = -self.sin_theta * point[:, 0] + self.cos_theta * point[:, 1]
        north = point[:, 2]
        return self.radius_m + self.terrain.height_m(east, north)


@dataclass(frozen=True)
class ContactEval:
    """The ground's action on each ship at one instant."""

    force_w: np.ndarray  # (N, 3) total normal force, inertial
    torque_w: np.ndarray  # (N, 3) its moment about the centre of mass, inertial
    normal_n: np.ndarray  # (N,) sum of the feet's normal forces (may be < 0 only while absorbing)
    max_penetration_m: np.ndarray  # (N,) deepest foot (negative: lowest foot's height above ground)
    cop_w: np.ndarray  # (N, 3) centre of pressure; the lowest foot where nothing presses
    lowest_foot_w: np.ndarray  # (N, 3) the deepest (or lowest) foot
    # The pressing feet (those whose force is not clamped away) as one linear spring-damper, for
    # the exact method (sim.integrators.exponential): sums over them of k_i, c_i, k_i x_i, k_i x_i'
    # (zeros unless asked for: evaluate's linear_model).
    stiffness_npm: np.ndarray  # (N,)
    damping_nspm: np.ndarray  # (N,)
    spring_load_n: np.ndarray  # (N,)
    spring_load_rate_nps: np.ndarray  # (N,)


def body_axes(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The body x, y, z axes in the inertial frame: the columns of the rotation matrix of q."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    ex = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)], axis=1)
    ey = np.stack([2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)], axis=1)
    ez = np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=1)
    return ex, ey, ez


def foot_offsets_w(q: np.ndarray, leg_radius_m: np.ndarray, com_height_m: np.ndarray
                   ) -> list[np.ndarray]:
    """Each foot's position relative to the centre of mass, inertial, four arrays (N,3)."""
    ex, ey, ez = body_axes(q)
    down = vec.scale(ez, -com_height_m)
    out = []
    for dx, dy in LEG_DIRECTIONS_BODY:
        lateral = ex if dx else ey
        sign = dx if dx else dy
        out.append(down + vec.scale(lateral, sign * leg_radius_m))
    return out


def lowest_foot_penetration(pos_m: np.ndarray, quat: np.ndarray, leg_radius_m: np.ndarray,
                            com_height_m: np.ndarray, ground: Ground) -> np.ndarray:
    """Penetration of the deepest foot (negative: height of the lowest foot above its ground);
    the same numbers as :func:`evaluate`'s ``max_penetration_m``, without the forces."""
    deepest = np.full(pos_m.shape[0], -np.inf)
    for offset in foot_offsets_w(quat, leg_radius_m, com_height_m):
        foot = pos_m + offset
        deepest = np.maximum(deepest, ground.surface_radius_m(foot) - vec.norm(foot))
    return deepest


def evaluate(pos_m: np.ndarray, vel_mps: np.ndarray, quat: np.ndarray, omega_w: np.ndarray,
             leg_radius_m: np.ndarray, com_height_m: np.ndarray, k_npm: np.ndarray,
             c_nspm: np.ndarray, c_absorb_nspm: np.ndarray, absorbing: np.ndarray,
             ground: Ground, engage_m: np.ndarray | float = 0.0,
             linear_model: bool = False) -> ContactEval:
    """Normal force, its moment, and penetration for every ship (see the module docstring).

    ``engage_m``: a foot counts as touching from ``pen > -engage_m``; a step that starts exactly
    at the surface crossing passes a micrometre so that rounding cannot leave out the damper's
    jump at its first stage. ``linear_model``: also sum the pressing feet's stiffness, damping,
    load and load rate (zeros otherwise)."""
    n = pos_m.shape[0]
    force = np.zeros((n, 3))
    torque = np.zeros((n, 3))
    normal = np.zeros(n)
    weight = np.zeros(n)
    cop = np.zeros((n, 3))
    max_pen = np.full(n, -np.inf)
    lowest = np.zeros((n, 3))
    stiff, damp, load, load_rate = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    k_leg = 0.25 * k_npm
    c_leg = np.where(absorbing, 0.25 * c_absorb_nspm, 0.25 * c_nspm)
    for offset in foot_offsets_w(quat, leg_radius_m, com_height_m):
        foot = pos_m + offset
        r_foot = vec.norm(foot)
        n_hat = foot / r_foot[:, None]
        pen = ground.surface_radius_m(foot) - r_foot
        v_foot = vel_mps + vec.cross(omega_w, offset)
        pen_rate = -vec.dot(v_foot, n_hat)
        f = k_leg * pen + c_leg * pen_rate
        if linear_model:
            pressing = (pen > -engage_m) & (absorbing | (f > 0.0))
            stiff += np.where(pressing, k_leg, 0.0)
            damp += np.where(pressing, c_leg, 0.0)
            load += np.where(pressing, k_leg * pen, 0.0)
            load_rate += np.where(pressing, k_leg * pen_rate, 0.0)
        f = np.where(absorbing, f, np.maximum(f, 0.0))
        f = np.where(pen > -engage_m, f, 0.0)
        f_vec = vec.scale(n_hat, f)
        force += f_vec
        torque += vec.cross(offset, f_vec)
        normal += f
        a = np.abs(f)
        weight += a
        cop += vec.scale(foot, a)
        deeper = pen > max_pen
        lowest = np.where(deeper[:, None], foot, lowest)
        max_pen = np.where(deeper, pen, max_pen)
    pressed = weight > 0.0
    cop = np.where(pressed[:, None], cop / np.where(pressed, weight, 1.0)[:, None], lowest)
    return ContactEval(force, torque, normal, max_pen, cop, lowest, stiff, damp, load, load_rate)


def no_contact(n: int, pos_m: np.ndarray) -> ContactEval:
    """The evaluation of ships known to be clear of the ground for the whole step."""
    z3, z1 = np.zeros((n, 3)), np.zeros(n)
    return ContactEval(z3, z3, z1, np.full(n, -np.inf), pos_m, pos_m, z1, z1, z1, z1)
