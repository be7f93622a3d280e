"""Tipped ships: the pivot model. A ship past ``tipped_angle`` turns about its pivot foot (the
lowest, held where it was when the ship was handed over) as one rigid rotation about the
horizontal axis through it; it rests on its hull at ``tipped_rest_deg`` and is righted when it
turns back under ``tipped_angle`` (sim.phases.pinned). MODEL-NOTES 29. One ship, compiled.
"""
from __future__ import annotations

import math
from typing import NamedTuple

from touchdown.sim.compiled import kernel, separate
from touchdown.sim.frames import body_spin_in_body_frame, surface_velocity
from touchdown.sim.vec import add, angle_between, cos_sinc, cross, dot, fmax, mul, norm, \
    quat_axis_z, quat_from_rotvec, quat_mul, quat_normalize, quat_rotate, quat_rotate_inv, scale, \
    sub, unit


@kernel
def pivot_axis(p, q):
    """The axis a tipped ship turns about: horizontal, normal to the plane of its tilt,
    unit(up x e_z), so that a positive rate tilts it further."""
    return unit(cross(unit(p), quat_axis_z(q)))


@kernel
def rate_from_momentum(omega_radps, m, inertia_b, motion, pivot):
    """The rate about the pivot foot when a ship in contact is handed to the pivot model: the foot
    is held at once (an inelastic impact at the foot), which conserves the angular momentum
    about it, relative to the surface, and keeps of the motion its component about the pivot's
    axis a:

        theta' = a . (I_w omega_rel + m d x v_rel) / I_p,   I_p = a . I_w a + m |a x d|^2,

    d the centre of mass from the pivot. It is the projection of the motion onto rotation about
    a in the kinetic-energy metric, so the kinetic energy after is never more than before.
    ``motion``: the ship's (sim.dynamics.Motion: its angular velocity in the body frame)."""
    p, v, q, w_b = motion
    axis = pivot_axis(p, q)
    v_rel = sub(v, surface_velocity(omega_radps, p))
    w_rel_w = sub(quat_rotate(q, w_b), (0.0, 0.0, omega_radps))
    d = sub(p, pivot)
    axis_b = quat_rotate_inv(q, axis)
    l_rel = add(quat_rotate(q, mul(inertia_b, quat_rotate_inv(q, w_rel_w))),
                scale(cross(d, v_rel), m))
    arm = cross(axis, d)
    i_p = dot(axis_b, mul(inertia_b, axis_b)) + m * dot(arm, arm)
    return dot(axis, l_rel) / i_p


@kernel
def pinned_motion(omega_radps, p, q, pivot, rate):
    """Inertial velocity and body-frame angular velocity of a pinned ship: the body's rotation,
    plus a tipped ship's turn at ``rate`` about its pivot (zero rate: landed, crashed, resting)."""
    spin = scale(pivot_axis(p, q), rate)
    v = add(surface_velocity(omega_radps, p), cross(spin, sub(p, pivot)))
    w = add(body_spin_in_body_frame(omega_radps, q), quat_rotate_inv(q, spin))
    return v, w


#: Fixed-point iterations of the pivot's discrete-gradient step: each gains a factor of about
#: h^2 m g L / (2 I_p) (5e-4 for the default lander at 0.05 s), so four or five reach rounding.
MAX_PIVOT_ITERATIONS = 40
_EPS = 2.220446049250313e-16


class PivotStep(NamedTuple):
    """One tick of a tipped ship's pivot model (body-fixed frame)."""

    pos_bf_m: tuple
    quat_bf: tuple
    rate_radps: float  # + = toppling, at the tick's end
    hull_crash: bool  # the hull met the ground faster than crash_speed
    righted: bool  # back under tipped_angle while turning upright


class _Pivot(NamedTuple):
    """The pose's constants for the potential's difference quotient."""

    p0: tuple
    q0: tuple
    r0: float
    m: float
    inertia_b: tuple
    gm_m3ps2: float
    omega_radps: float
    ad: tuple  # a x d
    aad: tuple  # a x (a x d)
    a_spin: tuple  # a x Omega
    aa_spin: tuple
    spin_b0: tuple  # the body's spin in the ship's frame at the start


@kernel
def _slope(pv, delta):
    """(U(theta_0 + delta) - U(theta_0)) / delta, and the pose's displacement per radian."""
    _, sinc = cos_sinc(delta)
    _, sinc_half = cos_sinc(0.5 * delta)
    one_minus_cos = 0.5 * delta * sinc_half * sinc_half  # (1 - cos delta) / delta
    dp = add(scale(pv.ad, sinc), scale(pv.aad, one_minus_cos))  # (p_1 - p_0) / delta
    p1 = add(pv.p0, scale(dp, delta))
    r1 = norm(p1)
    both = add(p1, pv.p0)
    r0 = pv.r0
    g = pv.m * pv.gm_m3ps2 * dot(dp, both) / (r0 * r1 * (r0 + r1))
    om = pv.omega_radps
    if om != 0.0:
        g = g - 0.5 * pv.m * om * om * (dp[0] * both[0] + dp[1] * both[1])
        # the spin seen from the ship turns the other way: R_a(-delta) e - e over delta
        de = add(scale(pv.a_spin, -sinc), scale(pv.aa_spin, one_minus_cos))
        d_spin_b = quat_rotate_inv(pv.q0, de)
        g = g - 0.5 * dot(d_spin_b, mul(pv.inertia_b, add(scale(pv.spin_b0, 2.0),
                                                           scale(d_spin_b, delta))))
    return g, dp


@separate
def pivot_step(cfg, pin, m, inertia_b, rcs_torque_body_nm):
    """A tipped ship turns about its pivot foot, a one-degree-of-freedom rotation by theta about
    the horizontal axis a through it:

        I_p theta'' = -dU/dtheta + tau_rcs . a,    I_p = a . I a + m |a x d|^2,

    U the effective potential of the frame turning with the body (point-mass gravity and the
    centrifugal potential, sim.energy). It is stepped with the discrete gradient of U (Gonzalez,
    J. Nonlinear Sci. 6, 1996; McLachlan, Quispel & Robidoux, Phil. Trans. R. Soc. A 357, 1999):

        I_p (theta'_1 - theta'_0) = h (tau - (U(theta_1) - U(theta_0)) / (theta_1 - theta_0)),
        theta_1 - theta_0 = h (theta'_0 + theta'_1) / 2,

    second order and exactly energy-conserving: I_p theta'^2 / 2 + U changes by tau times the
    angle turned and nothing else, through a fall, a slow-down and a turning point alike. The
    difference quotient is formed without cancellation (the pose's change divided by the angle,
    sin and 1 - cos as +,*,/ series), and the implicit step solved by fixed-point iteration
    (MAX_PIVOT_ITERATIONS). The ship rests on its hull at ``tipped_rest_deg``: a turn that would
    pass it stops there (an inelastic impact; crash above crash_speed at the centre of mass).
    Poses are body-fixed: ``pin`` (sim.ship.Pin) holds the pose, the pivot and the rate of turn;
    ``cfg`` is the scene record (the tick, gravity, the body's spin, tipped_rest, crash_speed,
    tipped_angle)."""
    p0, q0, pivot, rate0 = pin
    dt_s, gm_m3ps2, omega_radps = cfg.dt_s, cfg.gm_m3ps2, cfg.omega_radps
    up = unit(p0)
    ez = quat_axis_z(q0)
    axis = pivot_axis(p0, q0)
    d0 = sub(p0, pivot)
    ad = cross(axis, d0)
    aad = cross(axis, ad)
    axis_b = quat_rotate_inv(q0, axis)
    i_p = dot(axis_b, mul(inertia_b, axis_b)) + m * dot(ad, ad)
    tau = dot(quat_rotate(q0, rcs_torque_body_nm), axis)
    spin = (0.0, 0.0, omega_radps)
    a_spin = cross(axis, spin)
    pv = _Pivot(p0, q0, norm(p0), m, inertia_b, gm_m3ps2, omega_radps, ad, aad, a_spin,
                cross(axis, a_spin), quat_rotate_inv(q0, spin))

    half_h2 = 0.5 * dt_s * dt_s
    delta = dt_s * rate0 + half_h2 * (tau - _slope(pv, 0.0)[0]) / i_p
    for _ in range(MAX_PIVOT_ITERATIONS):
        nxt = dt_s * rate0 + half_h2 * (tau - _slope(pv, delta)[0]) / i_p
        settled = abs(nxt - delta) <= 4.0 * _EPS * abs(nxt)
        delta = nxt
        if settled:
            break
    rate1 = 2.0 * delta / dt_s - rate0
    # the hull: the turn stops at tipped_rest_deg (an angle found once, with +,*,/ and sqrt)
    tilt0 = angle_between(ez, up)
    to_rest = fmax(cfg.tipped_rest_rad - tilt0, 0.0)
    hull = delta > to_rest
    g_rest = _slope(pv, to_rest)[0]
    kinetic = 0.5 * i_p * rate0 * rate0 + to_rest * (tau - g_rest)
    speed_at_hull = math.sqrt(fmax(2.0 * kinetic / i_p, 0.0)) * norm(ad)
    hull_crash = hull and speed_at_hull > cfg.crash_speed_mps
    if hull:
        delta = to_rest
        rate1 = 0.0
    dp = _slope(pv, delta)[1]
    p1 = add(p0, scale(dp, delta))
    q1 = quat_normalize(quat_mul(quat_from_rotvec(scale(axis, delta)), q0))
    righted = (not hull_crash and dot(quat_axis_z(q1), unit(p1)) > cfg.cos_tipped and rate1 < 0.0)
    return PivotStep(p1, q1, rate1, hull_crash, righted)
