"""A ship's mechanical energy, in the frame that turns with the body (telemetry: ``energy_j``).

    E = T + R + U_g + U_c + S,

    T   = m |v - Omega x p|^2 / 2                     translation relative to the surface
    R   = (w - Omega_b) . I (w - Omega_b) / 2          rotation relative to the surface
                                                      (w, Omega_b: the ship's and the body's
                                                      angular velocities in the ship's frame)
    U_g = m GM (1/R_ref - 1/r)                         point-mass gravity, zero on the reference
                                                      sphere r = R_ref (``body.radius``)
    U_c = -m Omega^2 (rho^2 - R_ref^2) / 2 - Omega_b . I Omega_b / 2
                                                      the rotating frame's centrifugal potential
                                                      (rho: distance from the spin axis), zero for
                                                      the centre of mass on the reference sphere's
                                                      equator, plus its rotational part
    S   = sum over feet of k_i x_i^2 / 2, x_i > 0     what the contact springs store

E is the Jacobi integral of the rotating frame (Landau & Lifshitz, Mechanics, section 39): with
everything fixed to the body (gravity, terrain) E_inertial - Omega . L_inertial, which the motion
conserves with no thrust, no RCS and no dissipation; the dampers, friction and every
inelastic transition (touchdown, landing, a fall onto the side) can only lower it. On a body that
does not spin U_c = 0 and E is the ordinary energy. The velocities of landed, tipped and crashed
ships are those of their pinned motion (zero relative to the surface, except a tipped ship turning
about its pivot).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim import vec
from sim.contact import Ground, feet

Array = np.ndarray


@dataclass(frozen=True)
class Energy:
    """The parts of E (J, one per ship); ``total_j`` adds them in this order."""

    translational_j: Array
    rotational_j: Array
    gravity_j: Array
    centrifugal_j: Array  # the centre of mass's: -m Omega^2 (rho^2 - R^2) / 2
    centrifugal_spin_j: Array  # the rotation's: -Omega_b . I Omega_b / 2
    spring_j: Array

    @property
    def total_j(self) -> Array:
        return self.translation_j + self.rotation_j + self.spring_j

    @property
    def translation_j(self) -> Array:
        """The centre of mass's part; in free flight it is conserved on its own."""
        return (self.translational_j + self.gravity_j) + self.centrifugal_j

    @property
    def rotation_j(self) -> Array:
        """The rotation's part (E_rot - Omega . L_rot); in free flight conserved on its own."""
        return self.rotational_j + self.centrifugal_spin_j


def mechanical(gm_m3ps2: float, radius_m: float, spin_radps: float, stiffness_per_kg: float,
               leg_radius_m: Array, com_height_m: Array, mass_kg: Array, inertia_kgm2: Array,
               p: Array, v: Array, q: Array, w_b: Array, ground: Ground) -> Energy:
    """E of ships at pose (p, q) with inertial velocities (v, w_b); ``ground`` at that instant."""
    spin_b = vec.quat_rotate_inv(q, np.broadcast_to(np.array([0.0, 0.0, spin_radps]), p.shape))
    v_rel = v - ground.surface_velocity(p)
    w_rel = w_b - spin_b
    r = vec.norm(p)
    trans = 0.5 * mass_kg * vec.dot(v_rel, v_rel)
    rot = 0.5 * vec.dot(w_rel, inertia_kgm2 * w_rel)
    grav = mass_kg * gm_m3ps2 * ((r - radius_m) / (radius_m * r))
    if spin_radps != 0.0:
        rho2_minus_r2 = p[:, 0] * p[:, 0] + p[:, 1] * p[:, 1] - radius_m * radius_m
        cent = -0.5 * mass_kg * spin_radps * spin_radps * rho2_minus_r2
        cent_spin = -0.5 * vec.dot(spin_b, inertia_kgm2 * spin_b)
    else:
        cent = cent_spin = np.zeros_like(r)
    ft = feet(p, q, leg_radius_m, com_height_m, ground)
    k_leg = 0.25 * stiffness_per_kg * mass_kg
    spring = np.zeros_like(r)
    for x in ft.pen_m:
        spring = spring + np.where(x > 0.0, 0.5 * k_leg * x * x, 0.0)
    return Energy(trans, rot, grav, cent, cent_spin, spring)


def at(params, t_s: float, p: Array, v: Array, q: Array, w_b: Array, mass_kg: Array) -> Energy:
    """E of ships of ``params`` (all of them, in order) in a recorded state at time t_s: what
    ``export`` reports as energy_j, and what the property tests hold to."""
    from sim.frames import ground_at

    sh, body = params.ships, params.body
    inertia = sh.inertia0_kgm2 * (mass_kg / sh.mass0_kg)[:, None]
    return mechanical(body.gm_m3ps2, body.radius_m, body.omega_radps,
                      params.contact.stiffness_per_kg, sh.leg_radius_m, sh.com_height_m, mass_kg,
                      inertia, p, v, q, w_b, ground_at(params, t_s))
