"""Equations of motion of a free ship (flying or in contact): a rigid body under point-mass gravity,
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
One ship's functions, compiled (sim.compiled).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from touchdown.sim.compiled import constructor, kernel, separate
from touchdown.sim.contact import FrictionForce, Ground, Legs, evaluate, no_contact
from touchdown.sim.frames import turned
from touchdown.sim.vec import (add, cos_sinc, cross, div, dot, mul, quat_axis_z, quat_derivative,
    quat_rotate_inv, scale, sub)


class Motion(NamedTuple):
    """A ship's motion: where it is, how it moves, how it is turned and turns."""

    p: tuple  # centre of mass, inertial, m
    v: tuple  # m/s
    q: tuple  # attitude, body -> inertial
    w: tuple  # body-frame angular velocity, rad/s


class FreeBody(NamedTuple):
    """Everything about one free ship that is constant over a tick, and the ground it may meet."""

    mass_kg: float
    inertia_kgm2: tuple  # principal moments, body frame
    thrust_n: float  # main engine, along body +z
    rcs_torque_body_nm: tuple
    leg_radius_m: float
    com_height_m: float
    k_npm: float  # the seed's k = stiffness_per_kg m
    c_nspm: float  # c = 2 zeta sqrt(k m)
    c_absorb_nspm: float  # the absorbers' damper (SEED-NOTES 1)
    gm_m3ps2: float
    body_radius_m: float
    body_omega_radps: float
    terrain: np.record  # sim.contact.TERRAIN_DTYPE
    radial: bool  # the seed's radial normal on any slope
    cos0: float  # the body's angle at the tick's start
    sin0: float
    #: False: this ship cannot reach the ground this tick; skip the contact work
    touching: bool
    #: foot i presses from penetration > -engage_m[i] (sim.contact.evaluate): -inf while the ship
    #: is stepped up to the instant that foot reaches the ground (sim.step.free_flight)
    engage_m: tuple
    #: the method fits a linear spring-damper to the pressing feet (ContactEval's sums)
    linear_model: bool
    #: the method this ship is stepped with this tick (sim.integrators.sub_method)
    method: int
    #: kinetic friction (0 under the seed's law, which acts after the step)
    mu_k: float
    #: the feet whose friction is kinetic over this step: a force (sim.contact.evaluate)
    kinetic: tuple
    #: the holding feet's static friction carried into this step as a force, inertial
    hold_w: tuple


@constructor
def with_feet(fb, engage_m, kinetic):
    """``fb`` whose foot i presses from penetration > -engage_m[i], its friction kinetic where
    ``kinetic`` says."""
    return FreeBody(fb.mass_kg, fb.inertia_kgm2, fb.thrust_n, fb.rcs_torque_body_nm,
                    fb.leg_radius_m, fb.com_height_m, fb.k_npm, fb.c_nspm, fb.c_absorb_nspm,
                    fb.gm_m3ps2, fb.body_radius_m, fb.body_omega_radps,
                    fb.terrain, fb.radial, fb.cos0, fb.sin0, fb.touching,
                    engage_m, fb.linear_model, fb.method, fb.mu_k, kinetic, fb.hold_w)


@constructor
def with_hold(fb, hold_w):
    """``fb`` with the holding feet's friction ``hold_w`` carried in."""
    return FreeBody(fb.mass_kg, fb.inertia_kgm2, fb.thrust_n, fb.rcs_torque_body_nm,
                    fb.leg_radius_m, fb.com_height_m, fb.k_npm, fb.c_nspm, fb.c_absorb_nspm,
                    fb.gm_m3ps2, fb.body_radius_m, fb.body_omega_radps,
                    fb.terrain, fb.radial, fb.cos0, fb.sin0, fb.touching, fb.engage_m,
                    fb.linear_model, fb.method, fb.mu_k, fb.kinetic, hold_w)


@constructor
def ground_at(fb, offset_s):
    """The ground ``offset_s`` after the tick's start. On a flat body it looks the same at every
    angle, so the tick's angle serves."""
    om = fb.body_omega_radps
    if om == 0.0:
        return Ground(fb.body_radius_m, fb.terrain, 1.0, 0.0, 0.0, fb.radial)
    if fb.terrain.level:
        return Ground(fb.body_radius_m, fb.terrain, fb.cos0, fb.sin0, om, fb.radial)
    c, s = turned(fb.cos0, fb.sin0, om, offset_s)
    return Ground(fb.body_radius_m, fb.terrain, c, s, om, fb.radial)


@kernel
def ground_turn(fb, dt_s):
    """(cos, sin) of the angle the body turns through in dt_s (sim.vec.cos_sinc's series)."""
    if fb.body_omega_radps == 0.0:
        return 1.0, 0.0
    d = fb.body_omega_radps * dt_s
    c, sinc = cos_sinc(d)
    return c, d * sinc


@separate
def contact_at(fb, ground, p, v, q, w_b, absorbing, engage_m):
    """The ground's action at one state (``engage_m``: sim.contact.evaluate)."""
    if not fb.touching:
        return no_contact(p)
    return evaluate(ground, Motion(p, v, q, w_b), Legs(fb.leg_radius_m, fb.com_height_m, fb.k_npm),
                    fb.c_absorb_nspm if absorbing else fb.c_nspm, absorbing, engage_m,
                    fb.linear_model, FrictionForce(fb.mu_k, fb.kinetic, fb.hold_w))


@kernel
def acceleration(fb, ce, p, q):
    """v': point-mass gravity, thrust along the long axis, and the ground's force."""
    r2 = dot(p, p)
    r = math.sqrt(r2)
    a = scale(p, -fb.gm_m3ps2 / (r2 * r))
    force = add(ce.force_w, scale(quat_axis_z(q), fb.thrust_n))
    m = fb.mass_kg
    return add(a, (force[0] / m, force[1] / m, force[2] / m))


@kernel
def torque_body(fb, ce, q):
    """External torque in the body frame: the ground's, and the RCS's."""
    return add(quat_rotate_inv(q, ce.torque_w), fb.rcs_torque_body_nm)


@kernel
def derivatives(fb, ce, p, v, q, w_b):
    """(p', v', q', omega_b') given the contact evaluation ``ce`` at the same instant."""
    i_w = mul(fb.inertia_kgm2, w_b)
    alpha_b = div(sub(torque_body(fb, ce, q), cross(w_b, i_w)), fb.inertia_kgm2)
    return v, acceleration(fb, ce, p, q), quat_derivative(q, w_b), alpha_b
