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
about its pivot). One ship, compiled (sim.compiled).
"""
from __future__ import annotations

import math
from typing import NamedTuple

from touchdown.sim.compiled import kernel, separate
from touchdown.sim.contact import feet, surface_velocity
from touchdown.sim.vec import dot, mul, norm, quat_rotate_inv_of, sub


class Energy(NamedTuple):
    """The parts of E (J); :func:`total` adds them in a fixed order."""

    translational_j: float
    rotational_j: float
    gravity_j: float
    centrifugal_j: float  # the centre of mass's: -m Omega^2 (rho^2 - R^2) / 2
    centrifugal_spin_j: float  # the rotation's: -Omega_b . I Omega_b / 2
    spring_j: float


@kernel
def translation(e):
    """The centre of mass's part; in free flight it is conserved on its own."""
    return e.translational_j + e.gravity_j + e.centrifugal_j


@kernel
def rotation(e):
    """The rotation's part (E_rot - Omega . L_rot); in free flight conserved on its own."""
    return e.rotational_j + e.centrifugal_spin_j


@kernel
def total(e):
    return translation(e) + rotation(e) + e.spring_j


@separate
def mechanical(body, mass_kg, inertia_kgm2, legs, motion, ground, may_touch):
    """E of a ship of mass m and principal inertia I on its ``legs`` (sim.contact.Legs), in
    ``motion`` (pose (p, q), inertial velocities (v, w_b): sim.dynamics.Motion) over the ``body``
    (sim.frames.Body) and its ``ground`` at that instant. ``may_touch`` False: a ship known to be
    clear of the ground (its springs store nothing, and its feet are not looked for)."""
    p, v, q, w_b = motion
    far = -math.inf
    pen = (feet(ground, p, q, legs.leg_radius_m, legs.com_height_m).pen_m if may_touch
           else (far, far, far, far))
    return mechanical_at(body, mass_kg, inertia_kgm2, legs.k_npm, motion, ground, pen)


@kernel
def mechanical_at(body, mass_kg, inertia_kgm2, k_npm, motion, ground, pen_m):
    """:func:`mechanical` with the feet's penetrations ``pen_m`` given (a contact evaluation's at
    the same state, sim.contact.evaluate: the same bits as sim.contact.feet's; -inf for a ship
    clear of the ground), so that a guard at an evaluated state does not look its feet up again;
    the springs of the legs (k / 4 each) store k x^2 / 8 at each foot in the ground."""
    gm_m3ps2, radius_m, spin_radps = body
    p, v, q, w_b = motion
    spin_b = quat_rotate_inv_of(q, (0.0, 0.0, spin_radps))
    v_rel = sub(v, surface_velocity(ground, p))
    w_rel = sub(w_b, spin_b)
    r = norm(p)
    trans = 0.5 * mass_kg * dot(v_rel, v_rel)
    rot = 0.5 * dot(w_rel, mul(inertia_kgm2, w_rel))
    grav = mass_kg * gm_m3ps2 * ((r - radius_m) / (radius_m * r))
    cent = cent_spin = 0.0
    if spin_radps != 0.0:
        rho2_minus_r2 = p[0] * p[0] + p[1] * p[1] - radius_m * radius_m
        cent = -0.5 * mass_kg * spin_radps * spin_radps * rho2_minus_r2
        cent_spin = -0.5 * dot(spin_b, mul(inertia_kgm2, spin_b))
    spring = 0.0
    k_leg = 0.25 * k_npm
    for i in range(4):
        x = pen_m[i]
        spring = spring + (0.5 * k_leg * x * x if x > 0.0 else 0.0)
    return Energy(trans, rot, grav, cent, cent_spin, spring)
