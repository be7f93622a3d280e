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
from touchdown.sim.contact import (FrictionForce, Ground, Legs, Spring, foot_offsets_w, forces,
    geometry, no_contact)
from touchdown.sim.friction import tangent_basis
from touchdown.sim.frames import turned
from touchdown.sim.vec import (add, body_axes, cos_sinc, cross, div, dot, mul, norm, quat_axis_z,
    quat_derivative, quat_rotate, quat_rotate_inv, quat_rotate_inv_of, scale, sub, unit)


class Motion(NamedTuple):
    """A ship's motion: where it is, how it moves, how it is turned and turns."""

    p: tuple  # centre of mass, inertial, m
    v: tuple  # m/s
    q: tuple  # attitude, body -> inertial
    w: tuple  # body-frame angular velocity, rad/s


class Craft(NamedTuple):
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
    #: the method fits a linear spring-damper to the pressing feet (ContactEval's sums)
    linear_model: bool
    #: the method this ship is stepped with this tick (sim.integrators.sub_method)
    method: int
    #: kinetic friction (0 under the seed's law, which acts after the step)
    mu_k: float


class Grip(NamedTuple):
    """How the feet meet the ground over a piece of a sub-step: what the pieces change."""

    #: foot i presses from penetration > -engage_m[i] (sim.contact.evaluate): -inf while the ship
    #: is stepped up to the instant that foot reaches the ground (sim.flight.free_flight)
    engage_m: tuple
    #: the feet whose friction is kinetic over this step: a force (sim.contact.evaluate)
    kinetic: tuple
    #: the holding feet's static friction carried into this step as a force, inertial
    hold_w: tuple
    #: each dragged foot's fixed drag direction (zero: against its slip; sim.contact.FrictionForce)
    drag_dir: tuple


class FreeBody(NamedTuple):
    """One free ship over a tick: its :class:`Craft`, constant through the tick, and its feet's
    :class:`Grip`, which a piece of a sub-step changes (:func:`with_feet`, :func:`with_hold`,
    :func:`with_drag_dir` rebuild that alone)."""

    craft: Craft
    grip: Grip


@constructor
def with_feet(fb, engage_m, kinetic):
    """``fb`` whose foot i presses from penetration > -engage_m[i], its friction kinetic where
    ``kinetic`` says."""
    g = fb.grip
    return FreeBody(fb.craft, Grip(engage_m, kinetic, g.hold_w, g.drag_dir))


@constructor
def with_hold(fb, hold_w):
    """``fb`` with the holding feet's friction ``hold_w`` carried in."""
    g = fb.grip
    return FreeBody(fb.craft, Grip(g.engage_m, g.kinetic, hold_w, g.drag_dir))


@constructor
def with_drag_dir(fb, drag_dir):
    """``fb`` whose dragged feet are dragged against ``drag_dir`` (where not zero)."""
    g = fb.grip
    return FreeBody(fb.craft, Grip(g.engage_m, g.kinetic, g.hold_w, drag_dir))


@constructor
def ground_at(fb, offset_s):
    """The ground ``offset_s`` after the tick's start. On a flat body it looks the same at every
    angle, so the tick's angle serves."""
    cr = fb.craft
    om = cr.body_omega_radps
    if om == 0.0:
        return Ground(cr.body_radius_m, cr.terrain, 1.0, 0.0, 0.0, cr.radial)
    if cr.terrain.level:
        return Ground(cr.body_radius_m, cr.terrain, cr.cos0, cr.sin0, om, cr.radial)
    c, s = turned(cr.cos0, cr.sin0, om, offset_s)
    return Ground(cr.body_radius_m, cr.terrain, c, s, om, cr.radial)


@kernel
def ground_turn(fb, dt_s):
    """(cos, sin) of the angle the body turns through in dt_s (sim.vec.cos_sinc's series)."""
    if fb.craft.body_omega_radps == 0.0:
        return 1.0, 0.0
    d = fb.craft.body_omega_radps * dt_s
    c, sinc = cos_sinc(d)
    return c, d * sinc


@kernel
def contact_inline(fb, ground, motion, absorbing, engage_m):
    """:func:`contact_at` inlined where it is called: in the integrators' stages (2,186 of a
    touchdown's 3,485 evaluations), whose derivatives and held friction then share its rotation,
    offsets and angular velocity, and whose ContactEval is built where it is used instead of
    passed back from a call with ~80 arguments (the same arithmetic: the same bits)."""
    if not fb.craft.touching:
        return no_contact(motion.p)
    return contact_forces(fb, ground, contact_geometry(fb, ground, motion), motion,
                                 absorbing, engage_m)


@kernel
def contact_geometry(fb, ground, motion):
    """The feet of ``fb`` at ``motion``'s pose on ``ground`` (sim.contact.geometry: its position
    and attitude alone), which every evaluation at that pose and instant shares."""
    cr = fb.craft
    return geometry(ground, motion.p, motion.q, Legs(cr.leg_radius_m, cr.com_height_m, cr.k_npm))


@kernel
def contact_forces(fb, ground, geo, motion, absorbing, engage_m):
    """The ground's action at ``motion`` on feet at ``geo`` (:func:`contact_geometry` at the same
    pose on ``ground``): sim.contact.forces with ``fb``'s springs and friction, the absorbers'
    dampers while ``absorbing``; no contact's for a ship known to be clear of the ground.
    contact_forces(fb, ground, contact_geometry(fb, ground, m), m, ...) is
    :func:`contact_inline`'s evaluation (sim.contact.evaluate), step for step."""
    cr, g = fb.craft, fb.grip
    if not cr.touching:
        return no_contact(motion.p)
    c_nspm = cr.c_absorb_nspm if absorbing else cr.c_nspm
    return forces(ground, geo, motion, Spring(0.25 * cr.k_npm, 0.25 * c_nspm, absorbing),
                  engage_m, cr.linear_model, FrictionForce(cr.mu_k, g.kinetic, g.hold_w,
                                                           g.drag_dir))


@separate
def contact_at(fb, ground, motion, absorbing, engage_m):
    """The ground's action at one state (``motion``: a :class:`Motion`; ``engage_m``:
    sim.contact.evaluate): :func:`contact_inline` as a function of its own, for the free-flight
    loop's many callers."""
    return contact_inline(fb, ground, motion, absorbing, engage_m)


@kernel
def acceleration(fb, ce, p, q):
    """v': point-mass gravity, thrust along the long axis, and the ground's force."""
    r2 = dot(p, p)
    r = math.sqrt(r2)
    a = scale(p, -fb.craft.gm_m3ps2 / (r2 * r))
    force = add(ce.force_w, scale(quat_axis_z(q), fb.craft.thrust_n))
    m = fb.craft.mass_kg
    return add(a, (force[0] / m, force[1] / m, force[2] / m))


@kernel
def torque_body(fb, ce, q):
    """External torque in the body frame: the ground's, and the RCS's."""
    return add(quat_rotate_inv_of(q, ce.torque_w), fb.craft.rcs_torque_body_nm)


@kernel
def derivatives(fb, ce, p, v, q, w_b):
    """(p', v', q', omega_b') given the contact evaluation ``ce`` at the same instant."""
    i_w = mul(fb.craft.inertia_kgm2, w_b)
    alpha_b = div(sub(torque_body(fb, ce, q), cross(w_b, i_w)), fb.craft.inertia_kgm2)
    return v, acceleration(fb, ce, p, q), quat_derivative(q, w_b), alpha_b


class Held(NamedTuple):
    """The static friction of the feet that hold, as the force of their constraint at one
    instant (:func:`held_friction`)."""

    force_w: tuple  # the whole tangential force, inertial, N
    torque_w: tuple  # its moment about the centre of mass, N m
    feet_w: tuple  # each foot's share (four vectors, inertial, N)
    capped: bool  # the feet could not hold: the force is mu_s times their load
    use: float  # how much of their cones holding would take (> 1: capped)


#: no foot holds
NO_HELD = Held((0.0, 0.0, 0.0), (0.0, 0.0, 0.0),
               ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)), False, 0.0)


class Holding(NamedTuple):
    """The feet whose static friction holds inside a step (as their constraint's force,
    :func:`held_friction`), and the coefficient that bounds it."""

    feet: tuple  # each foot: held (its regime static)
    mu_s: float


@kernel
def _inv_inertia_w(fb, q):
    """I^-1 in the inertial frame, R diag(1 / I_k) R^T = sum_k e_k e_k^T / I_k (e_k: the body
    axes), as its six entries (xx, yy, zz, xy, xz, yz): three products by it cost less than three
    turns into the body frame and back."""
    ex, ey, ez = body_axes(q)
    ia = fb.craft.inertia_kgm2
    a, b, c = 1.0 / ia[0], 1.0 / ia[1], 1.0 / ia[2]
    return (ex[0] * ex[0] * a + ey[0] * ey[0] * b + ez[0] * ez[0] * c,
            ex[1] * ex[1] * a + ey[1] * ey[1] * b + ez[1] * ez[1] * c,
            ex[2] * ex[2] * a + ey[2] * ey[2] * b + ez[2] * ez[2] * c,
            ex[0] * ex[1] * a + ey[0] * ey[1] * b + ez[0] * ez[1] * c,
            ex[0] * ex[2] * a + ey[0] * ey[2] * b + ez[0] * ez[2] * c,
            ex[1] * ex[2] * a + ey[1] * ey[2] * b + ez[1] * ez[2] * c)


@kernel
def _sym_mul(m, x):
    """The symmetric matrix m (six entries, as :func:`_inv_inertia_w` gives them) times x."""
    return (m[0] * x[0] + m[3] * x[1] + m[4] * x[2],
            m[3] * x[0] + m[1] * x[1] + m[5] * x[2],
            m[4] * x[0] + m[5] * x[1] + m[2] * x[2])


@kernel
def held_friction(fb, ground, ce, motion, holding):
    # (``ce``: the contact at this state, whose feet's friction normals serve here)
    """The static friction of the pressing feet of ``holding`` (a :class:`Holding`: those whose
    friction is static over the step, and mu_s) at the state ``motion``, as a constraint force
    inside the integrator (MODEL-NOTES 46): the force at their
    centre of pressure c (loads N_i = F_i |g_i|) and the moment about their load-weighted normal
    n that keep the point of the ship at c from slipping over the ground and the ship from turning
    about n (one held foot: the point alone), i.e. that make those accelerations zero given every
    other force. With t1, t2 spanning the ground's plane at c, r = c - p, the response of the
    point's slip to a unit force along t and of the spin about n to a unit moment is the 3 x 3
    matrix A (A_kl = t_k . (t_l / m + I^-1 (r x t_l) x r), ...), and A x = -b, b the free
    accelerations, gives the force and moment. Four rigid feet at different heights under a
    rocking ship cannot all be held by finite forces (MODEL-NOTES 39); the footprint's three
    in-plane freedoms can, and the feet's own cones are checked after the step by the impulses
    (sim.friction.coulomb), which correct what the step left. Capped at mu_s times the held
    feet's load; each foot's share (the force by load, the moment by load times its lever) is
    what that check starts from."""
    p, v, q, w_b = motion
    return _held_friction(fb, ce, motion, holding, acceleration(fb, ce, p, q),
                          torque_body(fb, ce, q))


@kernel
def _held_friction(fb, ce, motion, holding, a0, tau_b):
    """:func:`held_friction` given the free acceleration ``a0`` (:func:`acceleration`) and the
    body-frame torque ``tau_b`` (:func:`torque_body`) at the same state, which its caller
    :func:`derivatives_held` needs too."""
    p, v, q, w_b = motion
    held, mu_s = holding
    if not ce.touching:
        return NO_HELD
    n_sum = 0.0
    c = (0.0, 0.0, 0.0)
    nrm = (0.0, 0.0, 0.0)
    count = 0
    off = foot_offsets_w(q, fb.craft.leg_radius_m, fb.craft.com_height_m)
    for i in range(4):
        load = ce.foot_force_n[i] * ce.push_norm[i]
        if held[i] and load > 0.0:
            foot = add(p, off[i])
            nf = ce.normal_w[i]
            n_sum = n_sum + load
            c = add(c, scale(foot, load))
            nrm = add(nrm, scale(nf, load))
            count += 1
    if count == 0:
        return NO_HELD
    c = scale(c, 1.0 / n_sum)
    nrm = unit(nrm)
    t1, t2 = tangent_basis(nrm)
    m = fb.craft.mass_kg
    omega_w = quat_rotate(q, w_b)
    r = sub(c, p)
    i_w = mul(fb.craft.inertia_kgm2, w_b)
    alpha_w = quat_rotate(q, div(sub(tau_b, cross(w_b, i_w)), fb.craft.inertia_kgm2))
    spin = (0.0, 0.0, fb.craft.body_omega_radps)
    acc = add(add(a0, cross(alpha_w, r)), cross(omega_w, cross(omega_w, r)))
    acc = sub(acc, cross(spin, add(v, cross(omega_w, r))))  # the ground under c accelerates too
    b1, b2, b3 = dot(t1, acc), dot(t2, acc), dot(alpha_w, nrm)
    inv_i = _inv_inertia_w(fb, q)
    u1 = _sym_mul(inv_i, cross(r, t1))
    u2 = _sym_mul(inv_i, cross(r, t2))
    a11 = 1.0 / m + dot(t1, cross(u1, r))
    a12 = dot(t1, cross(u2, r))
    a22 = 1.0 / m + dot(t2, cross(u2, r))
    x3 = 0.0
    if count == 1:
        det = a11 * a22 - a12 * a12
        x1 = -(a22 * b1 - a12 * b2) / det
        x2 = -(a11 * b2 - a12 * b1) / det
    else:
        u3 = _sym_mul(inv_i, nrm)
        a13 = dot(t1, cross(u3, r))
        a23 = dot(t2, cross(u3, r))
        a33 = dot(nrm, u3)
        # Cramer's rule on the symmetric 3 x 3
        c11 = a22 * a33 - a23 * a23
        c12 = a13 * a23 - a12 * a33
        c13 = a12 * a23 - a13 * a22
        det = a11 * c11 + a12 * c12 + a13 * c13
        c22 = a11 * a33 - a13 * a13
        c23 = a12 * a13 - a11 * a23
        c33 = a11 * a22 - a12 * a12
        x1 = -(c11 * b1 + c12 * b2 + c13 * b3) / det
        x2 = -(c12 * b1 + c22 * b2 + c23 * b3) / det
        x3 = -(c13 * b1 + c23 * b2 + c33 * b3) / det
    force = add(scale(t1, x1), scale(t2, x2))
    # each foot's share: the force by load, the moment by load times lever
    lever2 = 0.0
    reach = 0.0  # sum of N_i |d_i|: the most moment the feet could give about c, over mu_s
    if count > 1:
        for i in range(4):
            load = ce.foot_force_n[i] * ce.push_norm[i]
            if held[i] and load > 0.0:
                d = sub(add(p, off[i]), c)
                d = sub(d, scale(nrm, dot(d, nrm)))
                lever2 = lever2 + load * dot(d, d)
                reach = reach + load * norm(d)
    # what the feet's cones allow, in the force and the moment together: |F| / (mu_s N) +
    # |M| / (mu_s sum N_i |d_i|) <= 1 (each foot's friction spent on one or the other)
    use = norm(force) / (mu_s * n_sum)
    if reach > 0.0:
        use = use + abs(x3) / (mu_s * reach)
    capped = use > 1.0
    if capped:  # the footprint cannot hold: the feet's cones will let it slip
        force = scale(force, 1.0 / use)
        x3 = x3 / use
    torque = add(cross(r, force), scale(nrm, x3))
    z = (0.0, 0.0, 0.0)
    shares = (z, z, z, z)
    for i in range(4):
        load = ce.foot_force_n[i] * ce.push_norm[i]
        if held[i] and load > 0.0:
            f_i = scale(force, load / n_sum)
            if lever2 > 0.0:
                d = sub(add(p, off[i]), c)
                d = sub(d, scale(nrm, dot(d, nrm)))
                f_i = add(f_i, scale(cross(nrm, d), x3 * load / lever2))
            shares = (f_i if i == 0 else shares[0], f_i if i == 1 else shares[1],
                      f_i if i == 2 else shares[2], f_i if i == 3 else shares[3])
    return Held(force, torque, shares, capped, use)


@kernel
def derivatives_held(fb, ground, ce, motion, holding):
    """(p', v', q', omega_b') with the held feet's static friction (:func:`held_friction`) among
    the forces, and that friction (``ground``: the ground at the instant of ``ce``)."""
    p, v, q, w_b = motion
    a0 = acceleration(fb, ce, p, q)
    tau_b = torque_body(fb, ce, q)
    hf = _held_friction(fb, ce, motion, holding, a0, tau_b)
    i_w = mul(fb.craft.inertia_kgm2, w_b)
    tau = add(tau_b, quat_rotate_inv(q, hf.torque_w))
    alpha_b = div(sub(tau, cross(w_b, i_w)), fb.craft.inertia_kgm2)
    acc = add(a0, scale(hf.force_w, 1.0 / fb.craft.mass_kg))
    return (v, acc, quat_derivative(q, w_b), alpha_b), hf
