"""Equations of motion of free ships (flying or in contact): a rigid body under point-mass gravity,
main-engine thrust, RCS torque and the ground's contact forces.

    p' = v
    v' = -GM p / |p|^3 + (F_contact + T e_z) / m
    q' = 1/2 q (x) (0, omega_b)
    omega_b' = I^-1 (tau_b - omega_b x I omega_b)          (Euler's equations, principal axes)

The seed takes gravity's torque about the contact point and divides by the inertia about the centre
of mass. Newton-Euler about the centre of mass with the contact force applied at the feet is the same
physics stated without that slip: when a foot holds (friction) and the ship turns about it, the
inertia about the pivot (parallel-axis theorem) comes out by itself (SEED-NOTES 5).
Gravity-gradient torque (order GM I / r^3, ~1e-6 of the contact torques) is neglected.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim import vec
from sim.contact import ContactEval, Ground, evaluate, no_contact
from sim.params import Params


@dataclass(frozen=True)
class FreeBodies:
    """Everything constant over one tick for a subset of free ships (arrays (M,...))."""

    mass_kg: np.ndarray
    inertia_kgm2: np.ndarray  # (M, 3)
    thrust_n: np.ndarray
    rcs_torque_body_nm: np.ndarray  # (M, 3)
    leg_radius_m: np.ndarray
    com_height_m: np.ndarray
    k_npm: np.ndarray
    c_nspm: np.ndarray
    c_absorb_nspm: np.ndarray
    gm_m3ps2: float
    body_radius_m: float
    body_omega_radps: float
    params: Params
    touching: bool  # False: these ships cannot reach the ground this tick; skip the contact work
    #: a foot presses from penetration > -engage_m (per ship or one number); negative while a
    #: ship is stepped up to the instant its feet reach the ground (sim.step.free_flight)
    engage_m: np.ndarray | float = 0.0
    #: the method fits a linear spring-damper to the pressing feet (ContactEval's sums); others
    #: skip that work
    linear_model: bool = False

    def ground_at(self, t_s: float) -> Ground:
        theta = self.body_omega_radps * t_s
        c, s = (1.0, 0.0) if theta == 0.0 else (math.cos(theta), math.sin(theta))
        return Ground(self.body_radius_m, self.params.body.terrain, c, s)


def contact_at(fb: FreeBodies, ground: Ground, p, v, q, w_b, absorbing,
               engage_m: np.ndarray | float | None = None) -> ContactEval:
    """The ground's action at one state. ``ground`` fixes the body's rotation angle: it is taken
    at the start of each sub-step and held over it (Omega h < 1e-6 rad for any real body).
    ``engage_m`` overrides ``fb.engage_m``."""
    if not fb.touching:
        return no_contact(p.shape[0], p)
    omega_w = vec.quat_rotate(q, w_b)
    return evaluate(p, v, q, omega_w, fb.leg_radius_m, fb.com_height_m, fb.k_npm, fb.c_nspm,
                    fb.c_absorb_nspm, absorbing, ground,
                    fb.engage_m if engage_m is None else engage_m, fb.linear_model)


def derivatives(fb: FreeBodies, ce: ContactEval, p, v, q, w_b):
    """(p', v', q', omega_b') given the contact evaluation ``ce`` at the same instant."""
    r2 = vec.dot(p, p)
    r = np.sqrt(r2)
    a = vec.scale(p, -fb.gm_m3ps2 / (r2 * r))
    ez = vec.quat_axis_z(q)
    force = ce.force_w + vec.scale(ez, fb.thrust_n)
    a = a + force / fb.mass_kg[:, None]
    tau_b = vec.quat_rotate_inv(q, ce.torque_w) + fb.rcs_torque_body_nm
    i_w = fb.inertia_kgm2 * w_b
    alpha_b = (tau_b - vec.cross(w_b, i_w)) / fb.inertia_kgm2
    return v, a, vec.quat_derivative(q, w_b), alpha_b
