"""Equations of motion of free ships (flying or in contact): a rigid body under point-mass gravity,
main-engine thrust, RCS torque and the ground's contact forces.

    p' = v
    v' = -GM p / |p|^3 + (F_contact + T e_z) / m
    q' = 1/2 q (x) (0, omega)
    L' = L x omega + tau_b,   L = I omega          (Euler's equations, principal body axes)

The seed takes gravity's torque about the contact point and divides by the inertia about the centre
of mass. Newton-Euler about the centre of mass with the contact force applied at the feet is the same
physics stated without that slip: when a foot holds (friction) and the ship turns about it, the
inertia about the pivot (parallel-axis theorem) comes out by itself (SEED-NOTES 5).
Gravity-gradient torque (order GM I / r^3, ~1e-6 of the contact torques) is neglected.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim import vec
from sim.contact import ContactEval, Ground, evaluate, no_contact
from sim.frames import body_rotation
from sim.params import Params

Array = np.ndarray


@dataclass(frozen=True)
class FreeBodies:
    """Everything constant over one tick for a subset of free ships (arrays (M,...))."""

    mass_kg: Array
    inertia_kgm2: Array  # (M, 3)
    thrust_n: Array
    rcs_torque_body_nm: Array  # (M, 3)
    leg_radius_m: Array
    com_height_m: Array
    k_npm: Array
    c_nspm: Array
    c_absorb_nspm: Array
    gm_m3ps2: float
    body_radius_m: float
    body_omega_radps: float
    params: Params
    touching: bool  # False: these ships cannot reach the ground this tick; skip the contact work
    t_tick_s: float = 0.0  # the tick's start; instants within it are given as offsets from it
    #: a foot presses from penetration > -engage_m (per ship or one number); negative while a
    #: ship is stepped up to the instant its feet reach the ground (sim.step.free_flight)
    engage_m: Array | float = 0.0
    #: the method fits a linear spring-damper to the pressing feet (ContactEval's sums); others
    #: skip that work
    linear_model: bool = False

    def ground_at(self, offset_s: float | Array) -> Ground:
        """The ground at ``t_tick + offset`` (offset a number or one per ship). The tick's angle
        Omega t comes from one scalar libm call shared by every ship; the offset's small angle is
        added with cos_sinc's +,*,/ series, so a ship's ground depends on its own offset alone."""
        body = self.params.body
        om = self.body_omega_radps
        radial = self.params.contact.surface_normal == "radial"
        if om == 0.0:
            return Ground(self.body_radius_m, body.terrain, 1.0, 0.0, 0.0, radial)
        c0, s0 = body_rotation(self.params, self.t_tick_s)
        if body.terrain.flat:  # the sphere looks the same at every angle
            return Ground(self.body_radius_m, body.terrain, c0, s0, om, radial)
        d = np.broadcast_to(np.asarray(om * np.asarray(offset_s, dtype=float)),
                            self.mass_kg.shape)
        cd, sinc_d = vec.cos_sinc(d)
        sd = d * sinc_d
        return Ground(self.body_radius_m, body.terrain, c0 * cd - s0 * sd, s0 * cd + c0 * sd, om,
                      radial)


    def ground_turn(self, dt_s: float | Array) -> tuple[float | Array, float | Array]:
        """(cos, sin) of the angle the body turns through in dt_s (a number or one per ship),
        with cos_sinc's series (per ship, so no ship depends on its neighbours)."""
        if self.body_omega_radps == 0.0:
            return 1.0, 0.0
        d = np.broadcast_to(np.asarray(self.body_omega_radps * np.asarray(dt_s, dtype=float)),
                            self.mass_kg.shape)
        c, sinc = vec.cos_sinc(d)
        return c, d * sinc


def contact_at(fb: FreeBodies, ground: Ground, p, v, q, w_b, absorbing,
               engage_m: Array | float | None = None) -> ContactEval:
    """The ground's action at one state. ``engage_m`` overrides ``fb.engage_m``."""
    if not fb.touching:
        return no_contact(p.shape[0], p)
    omega_w = vec.quat_rotate(q, w_b)
    return evaluate(p, v, q, omega_w, fb.leg_radius_m, fb.com_height_m, fb.k_npm, fb.c_nspm,
                    fb.c_absorb_nspm, absorbing, ground,
                    fb.engage_m if engage_m is None else engage_m, fb.linear_model)


def acceleration(fb: FreeBodies, ce: ContactEval, p, q) -> Array:
    """v': point-mass gravity, thrust along the long axis, and the ground's force."""
    r2 = vec.dot(p, p)
    r = np.sqrt(r2)
    a = vec.scale(p, -fb.gm_m3ps2 / (r2 * r))
    force = ce.force_w + vec.scale(vec.quat_axis_z(q), fb.thrust_n)
    return a + force / fb.mass_kg[:, None]


def torque_body(fb: FreeBodies, ce: ContactEval, q) -> Array:
    """External torque in the body frame: the ground's, and the RCS's."""
    return vec.quat_rotate_inv(q, ce.torque_w) + fb.rcs_torque_body_nm


def derivatives(fb: FreeBodies, ce: ContactEval, p, v, q, w_b):
    """(p', v', q', omega_b') given the contact evaluation ``ce`` at the same instant."""
    i_w = fb.inertia_kgm2 * w_b
    alpha_b = (torque_body(fb, ce, q) - vec.cross(w_b, i_w)) / fb.inertia_kgm2
    return v, acceleration(fb, ce, p, q), vec.quat_derivative(q, w_b), alpha_b
