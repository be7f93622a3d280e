"""Tipped ships: the pivot model. A ship past ``tipped_angle`` turns about its pivot foot (the
lowest, held where it was when the ship was handed over) as one rigid rotation about the
horizontal axis through it; it rests on its hull at ``tipped_rest_deg`` and is righted when it
turns back under ``tipped_angle`` (sim.step.pinned). MODEL-NOTES 29.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim import vec
from sim.frames import body_spin_in_body_frame, inertia, surface_spin_w, surface_velocity
from sim.params import Params
from sim.state import State


def pivot_axis(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The axis a tipped ship turns about: horizontal, normal to the plane of its tilt,
    unit(up x e_z), so that a positive rate tilts it further."""
    return vec.unit(vec.cross(vec.unit(p), vec.quat_axis_z(q)))


def pivot_rate_from_momentum(params: Params, m: np.ndarray, inertia_b: np.ndarray, p, v, q, w_b,
                             pivot: np.ndarray) -> np.ndarray:
    """The rate about the pivot foot when a ship in contact is handed to the pivot model: the foot
    is held at once (an inelastic impact at the foot), which conserves the angular momentum
    about it, relative to the surface, and keeps of the motion its component about the pivot's
    axis a:

        theta' = a . (I_w omega_rel + m d x v_rel) / I_p,   I_p = a . I_w a + m |a x d|^2,

    d the centre of mass from the pivot. It is the projection of the motion onto rotation about
    a in the kinetic-energy metric, so the kinetic energy after is never more than before."""
    axis = pivot_axis(p, q)
    spin_w = surface_spin_w(params, p.shape[0])
    v_rel = v - surface_velocity(params, p)
    w_rel_w = vec.quat_rotate(q, w_b) - spin_w
    d = p - pivot
    axis_b = vec.quat_rotate_inv(q, axis)
    l_rel = vec.quat_rotate(q, inertia_b * vec.quat_rotate_inv(q, w_rel_w)) + vec.scale(
        vec.cross(d, v_rel), m)
    arm = vec.cross(axis, d)
    i_p = vec.dot(axis_b, inertia_b * axis_b) + m * vec.dot(arm, arm)
    return vec.dot(axis, l_rel) / i_p


def pinned_motion(params: Params, p: np.ndarray, q: np.ndarray, pivot: np.ndarray,
                  rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inertial velocity and body-frame angular velocity of pinned ships: the body's rotation,
    plus a tipped ship's turn at ``rate`` about its pivot (zero rate: landed, crashed, resting)."""
    spin = vec.scale(pivot_axis(p, q), rate)
    v = surface_velocity(params, p) + vec.cross(spin, p - pivot)
    w = body_spin_in_body_frame(params, q) + vec.quat_rotate_inv(q, spin)
    return v, w


#: Fixed-point iterations of the pivot's discrete-gradient step: each gains a factor of about
#: h^2 m g L / (2 I_p) (5e-4 for the default lander at 0.05 s), so four or five reach rounding.
MAX_PIVOT_ITERATIONS = 40


@dataclass(frozen=True)
class PivotStep:
    """One tick of the tipped ships' pivot model (body-fixed frame)."""

    pos_bf_m: np.ndarray
    quat_bf: np.ndarray
    rate_radps: np.ndarray  # + = toppling, at the tick's end
    hull_crash: np.ndarray  # the hull met the ground faster than crash_speed
    righted: np.ndarray  # back under tipped_angle while turning upright


def pivot_step(params: Params, st: State, rcs_torque_body_nm: np.ndarray) -> PivotStep:
    """Tipped ships turn about their pivot foot, a one-degree-of-freedom rotation by theta about
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
    pass it stops there (an inelastic impact; crash above crash_speed at the centre of mass)."""
    cp, dt = params.contact, params.sim.dt_s
    gm, om = params.body.gm_m3ps2, params.body.omega_radps
    p0, q0, pivot = st.pin_pos_bf_m, st.pin_quat_bf, st.pin_pivot_bf_m
    m = st.mass_kg
    i_b = inertia(params, st)
    rate0 = st.pivot_rate_radps
    up = vec.unit(p0)
    ez = vec.quat_axis_z(q0)
    axis = pivot_axis(p0, q0)
    d0 = p0 - pivot
    ad = vec.cross(axis, d0)
    aad = vec.cross(axis, ad)
    axis_b = vec.quat_rotate_inv(q0, axis)
    i_p = vec.dot(axis_b, i_b * axis_b) + m * vec.dot(ad, ad)
    tau = vec.dot(vec.quat_rotate(q0, rcs_torque_body_nm), axis)
    r0 = vec.norm(p0)
    spin = np.broadcast_to(np.array([0.0, 0.0, om]), p0.shape)
    a_spin = vec.cross(axis, spin)
    aa_spin = vec.cross(axis, a_spin)
    spin_b0 = vec.quat_rotate_inv(q0, spin)

    def slope(delta):
        """(U(theta_0 + delta) - U(theta_0)) / delta, and the pose's displacement per radian."""
        _, sinc = vec.cos_sinc(delta)
        _, sinc_half = vec.cos_sinc(0.5 * delta)
        one_minus_cos = 0.5 * delta * sinc_half * sinc_half  # (1 - cos delta) / delta
        dp = vec.scale(ad, sinc) + vec.scale(aad, one_minus_cos)  # (p_1 - p_0) / delta
        p1 = p0 + vec.scale(dp, delta)
        r1 = vec.norm(p1)
        both = p1 + p0
        g = m * gm * vec.dot(dp, both) / (r0 * r1 * (r0 + r1))
        if om != 0.0:
            g = g - 0.5 * m * om * om * (dp[:, 0] * both[:, 0] + dp[:, 1] * both[:, 1])
            # the spin seen from the ship turns the other way: R_a(-delta) e - e over delta
            de = vec.scale(a_spin, -sinc) + vec.scale(aa_spin, one_minus_cos)
            d_spin_b = vec.quat_rotate_inv(q0, de)
            g = g - 0.5 * vec.dot(d_spin_b, i_b * (2.0 * spin_b0 + vec.scale(d_spin_b, delta)))
        return g, dp

    half_h2 = 0.5 * dt * dt
    delta = dt * rate0 + half_h2 * (tau - slope(np.zeros_like(m))[0]) / i_p
    done = np.zeros(m.shape, dtype=bool)
    for _ in range(MAX_PIVOT_ITERATIONS):
        nxt = dt * rate0 + half_h2 * (tau - slope(delta)[0]) / i_p
        settled = np.abs(nxt - delta) <= 4.0 * np.finfo(float).eps * np.abs(nxt)
        delta = np.where(done, delta, nxt)
        done = done | settled
        if done.all():
            break
    rate1 = 2.0 * delta / dt - rate0
    # the hull: the turn stops at tipped_rest_deg (an angle found once, with +,*,/ and sqrt)
    tilt0 = vec.angle(vec.norm(vec.cross(ez, up)), vec.dot(ez, up))
    to_rest = np.maximum(math.radians(cp.tipped_rest_deg) - tilt0, 0.0)
    hull = delta > to_rest
    g_rest, _ = slope(to_rest)
    kinetic = 0.5 * i_p * rate0 * rate0 + to_rest * (tau - g_rest)
    speed_at_hull = np.sqrt(np.maximum(2.0 * kinetic / i_p, 0.0)) * vec.norm(ad)
    hull_crash = hull & (speed_at_hull > cp.crash_speed_mps)
    delta = np.where(hull, to_rest, delta)
    rate1 = np.where(hull, 0.0, rate1)
    _, dp = slope(delta)
    p1 = p0 + vec.scale(dp, delta)
    q1 = vec.quat_normalize(vec.quat_mul(vec.quat_from_rotvec(vec.scale(axis, delta)), q0))
    righted = (~hull_crash & (vec.dot(vec.quat_axis_z(q1), vec.unit(p1)) > cp.cos_tipped)
               & (rate1 < 0.0))
    return PivotStep(p1, q1, rate1, hull_crash, righted)
