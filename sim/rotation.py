"""Torque-free rotation of a rigid body over a step: a splitting into exact flows.

Euler's equations for the body-frame angular momentum L (principal moments I_1, I_2, I_3),

    L' = L x omega,   omega = L / I,   q' = 1/2 q (x) (0, omega),

come from the Hamiltonian H = sum_i L_i^2 / (2 I_i). Split it as (Fasso, "Comparison of splitting
algorithms for the rigid body", J. Comput. Phys. 189, 2003)

    H = |L|^2 / (2 I_r)  +  sum_i c_i L_i^2 / 2,      c_i = 1 / I_i - 1 / I_r,

with I_r the median moment. Every part has an exact flow that is a rotation:

* ``|L|^2 / (2 I_r)`` is a Casimir: L stays put in the body frame and the body turns about L by
  |L| t / I_r. It commutes with everything, so it is applied once per step.
* ``c_i L_i^2 / 2``: the body turns about its own axis i by theta = c_i L_i t, and L turns the
  other way about that axis (L_i unchanged).

Each flow keeps |L| and the inertial angular momentum exactly. c_i = 0 for the axis whose moment is
I_r, so an axisymmetric ship (two equal moments) is left with a single axis flow: its step is the
closed-form solution, to rounding, at any step length. For three different moments the two axis
flows do not commute; they are composed symmetrically (Strang) and the Strang step is composed to
fourth order by Yoshida's triple jump (Phys. Lett. A 150, 1990). Measured on a Dzhanibekov spin
(moments 30,000 / 45,000 / 20,000 kg m^2, 1 rad/s about the intermediate axis) at a 0.05 s step:
energy within 4e-10 over 60 s where the Strang step alone drifts by 1e-5, and flips within 1e-7 s
of Euler's equations solved by DOP853.

Everything is +, *, / and sqrt (cos and sin from sim.vec.cos_sinc). One ship, compiled.
"""
from __future__ import annotations

from touchdown.sim.compiled import kernel, separate
from touchdown.sim.vec import (TINY_ANGLE, cos_sinc, quat_from_rotvec, quat_mul, quat_normalize,
    scale)

#: Yoshida's fourth-order triple jump: the Strang step at (w1, w0, w1) of the step, w0 = 1 - 2 w1.
#: (2^(1/3) as a literal: Python's power is libm's pow, whose last bit differs between machines)
_W1 = 1.0 / (2.0 - 1.2599210498948732)
_W0 = 1.0 - 2.0 * _W1


def _composition() -> tuple[tuple[int, float], ...]:
    """The axis flows of one step as (axis, fraction of the step), neighbours on one axis merged."""
    seq: list[tuple[int, float]] = []
    for w in (_W1, _W0, _W1):
        for axis, frac in ((0, 0.5 * w), (1, 0.5 * w), (2, w), (1, 0.5 * w), (0, 0.5 * w)):
            if seq and seq[-1][0] == axis:
                seq[-1] = (axis, seq[-1][1] + frac)
            else:
                seq.append((axis, frac))
    return tuple(seq)


#: 13 flows: x, y, z, y, x, y, z, y, x, y, z, y, x; their axes and fractions of the step
AXIS_FLOWS = _composition()
FLOW_AXES = tuple(axis for axis, _ in AXIS_FLOWS)
FLOW_FRACTIONS = tuple(frac for _, frac in AXIS_FLOWS)
#: the largest |fraction| of the step an axis flow takes (the middle z flow's, |w0| ~ 1.70)
MAX_FRACTION = max(abs(f) for f in FLOW_FRACTIONS)
# (tiny_rotation writes the 13 flows out in this order)
assert FLOW_AXES == (0, 1, 2, 1, 0, 1, 2, 1, 0, 1, 2, 1, 0)


@kernel
def median_moment(inertia):
    """The median of the three principal moments, by min and max only."""
    a, b, c = inertia
    return max(min(a, b), min(max(a, b), c))


@kernel
def axis_flow(q, l_b, coef, axis, t):
    """Flow of c L_axis^2 / 2 for time t: the body turns about its ``axis`` by theta = c L_axis t,
    and L turns by -theta about it."""
    theta = coef * l_b[axis] * t
    c_half, sinc_half = cos_sinc(0.5 * theta)
    s_half = 0.5 * theta * sinc_half
    w, x, y, z = q
    # q (x) (cos theta/2, sin theta/2 e_axis), written out for each axis
    if axis == 0:
        q1 = (w * c_half - x * s_half, x * c_half + w * s_half, y * c_half + z * s_half,
              z * c_half - y * s_half)
    elif axis == 1:
        q1 = (w * c_half - y * s_half, x * c_half - z * s_half, y * c_half + w * s_half,
              z * c_half + x * s_half)
    else:
        q1 = (w * c_half - z * s_half, x * c_half + y * s_half, y * c_half - x * s_half,
              z * c_half + w * s_half)
    c_full = c_half * c_half - s_half * s_half
    s_full = 2.0 * s_half * c_half
    lx, ly, lz = l_b
    if axis == 0:
        l1 = (lx, c_full * ly + s_full * lz, c_full * lz - s_full * ly)
    elif axis == 1:
        l1 = (c_full * lx - s_full * lz, ly, c_full * lz + s_full * lx)
    else:
        l1 = (c_full * lx + s_full * ly, c_full * ly - s_full * lx, lz)
    return q1, l1


@kernel
def tiny_axis_flow(q, l_b, axis, s_half):
    """:func:`axis_flow` where its half angle s_half = theta / 2 is below vec.TINY_ANGLE (zero
    included): there cos_sinc gives (1.0, 1.0) exactly, so c_half = 1.0, s_half = theta / 2 and,
    with s_half^2 < 2^-54, c_full = 1 - s_half^2 = 1.0 and s_full = 2 s_half; every product by
    1.0 is its other factor bit for bit (signed zeros included), so the flow below, without them,
    is axis_flow's to the last bit (tests/test_rotation_tiny.py compares them)."""
    w, x, y, z = q
    s_full = 2.0 * s_half
    lx, ly, lz = l_b
    if axis == 0:
        return ((w - x * s_half, x + w * s_half, y + z * s_half, z - y * s_half),
                (lx, ly + s_full * lz, lz - s_full * ly))
    if axis == 1:
        return ((w - y * s_half, x - z * s_half, y + w * s_half, z + x * s_half),
                (lx - s_full * lz, ly, lz + s_full * lx))
    return ((w - z * s_half, x + y * s_half, y - x * s_half, z + w * s_half),
            (lx + s_full * ly, ly - s_full * lx, lz))


@kernel
def tiny_turn(q, phi):
    """quat_mul(q, quat_from_rotvec(phi)) where every component of phi is below 2^-28 in size
    (zero included): then |phi| / 2 < vec.TINY_ANGLE, cos_sinc gives (1.0, 1.0) and the turn's
    quaternion is (1.0, phi / 2); the product without its factors 1.0 (bit for bit the same,
    signed zeros included; tests/test_rotation_tiny.py)."""
    aw, ax, ay, az = q
    bx, by, bz = phi[0] * 0.5, phi[1] * 0.5, phi[2] * 0.5
    return (aw - ax * bx - ay * by - az * bz,
            aw * bx + ax + ay * bz - az * by,
            aw * by - ax * bz + ay + az * bx,
            aw * bz + ax * by - ay * bx + az)


#: below it in size every component of a turn's rotation vector leaves its half angle under
#: vec.TINY_ANGLE (|phi| / 2 <= sqrt(3) 2^-29 < 2^-27): :func:`tiny_turn`
TINY_COMPONENT = 2.0 ** -28


@kernel
def rotation_flows(q, l_b, inertia, h):
    """Attitude and body-frame angular momentum after a torque-free step of length h. Exact for an
    axisymmetric body; fourth order otherwise (module docstring). An axis flow whose coefficient
    is zero is the identity and is skipped. A turn too small for cos_sinc's series (a ship that
    does not spin, or turns at rounding's rate: an upright bounce's 1e-10 rad/s) takes
    :func:`tiny_turn` and :func:`tiny_axis_flow`: the same bits without the products by 1.0."""
    i_ref = median_moment(inertia)
    coef = (1.0 / inertia[0] - 1.0 / i_ref, 1.0 / inertia[1] - 1.0 / i_ref,
            1.0 / inertia[2] - 1.0 / i_ref)
    phi = scale(l_b, h / i_ref)
    if (abs(phi[0]) < TINY_COMPONENT and abs(phi[1]) < TINY_COMPONENT
            and abs(phi[2]) < TINY_COMPONENT):
        q = tiny_turn(q, phi)
    else:
        q = quat_mul(q, quat_from_rotvec(phi))
    for k in range(len(FLOW_AXES)):
        axis = FLOW_AXES[k]
        if coef[axis] != 0.0:
            theta = coef[axis] * l_b[axis] * (FLOW_FRACTIONS[k] * h)
            if abs(0.5 * theta) < TINY_ANGLE:
                q, l_b = tiny_axis_flow(q, l_b, axis, 0.5 * theta)
            else:
                q, l_b = axis_flow(q, l_b, coef[axis], axis, FLOW_FRACTIONS[k] * h)
    return quat_normalize(q), l_b


@kernel
def _tiny_flow(q, l_b, coef, axis, t):
    """One of free_rotation's axis flows (coefficient ``coef`` on ``axis``, for time t) known
    to be tiny (:func:`rotation_step`): skipped where the coefficient is zero, as there."""
    if coef == 0.0:
        return q, l_b
    theta = coef * l_b[axis] * t
    return tiny_axis_flow(q, l_b, axis, 0.5 * theta)


@kernel
def tiny_rotation(q, l_b, coef, i_ref, h):
    """:func:`free_rotation` of a turn known to be tiny throughout (:func:`rotation_step`),
    written out flow by flow (FLOW_AXES' order): the same operations on the same operands, with
    no loop over the flows, no branch on their axes and no test of each angle."""
    q = tiny_turn(q, scale(l_b, h / i_ref))
    q, l_b = _tiny_flow(q, l_b, coef[0], 0, FLOW_FRACTIONS[0] * h)
    q, l_b = _tiny_flow(q, l_b, coef[1], 1, FLOW_FRACTIONS[1] * h)
    q, l_b = _tiny_flow(q, l_b, coef[2], 2, FLOW_FRACTIONS[2] * h)
    q, l_b = _tiny_flow(q, l_b, coef[1], 1, FLOW_FRACTIONS[3] * h)
    q, l_b = _tiny_flow(q, l_b, coef[0], 0, FLOW_FRACTIONS[4] * h)
    q, l_b = _tiny_flow(q, l_b, coef[1], 1, FLOW_FRACTIONS[5] * h)
    q, l_b = _tiny_flow(q, l_b, coef[2], 2, FLOW_FRACTIONS[6] * h)
    q, l_b = _tiny_flow(q, l_b, coef[1], 1, FLOW_FRACTIONS[7] * h)
    q, l_b = _tiny_flow(q, l_b, coef[0], 0, FLOW_FRACTIONS[8] * h)
    q, l_b = _tiny_flow(q, l_b, coef[1], 1, FLOW_FRACTIONS[9] * h)
    q, l_b = _tiny_flow(q, l_b, coef[2], 2, FLOW_FRACTIONS[10] * h)
    q, l_b = _tiny_flow(q, l_b, coef[1], 1, FLOW_FRACTIONS[11] * h)
    q, l_b = _tiny_flow(q, l_b, coef[0], 0, FLOW_FRACTIONS[12] * h)
    return quat_normalize(q), l_b


@separate
def rotation_step(q, l_b, inertia, h):
    """:func:`free_rotation`, written out flow by flow (:func:`tiny_rotation`) for a turn known to
    be tiny throughout (a ship that does not spin, or turns at rounding's rate: every flying tick
    of an upright bounce, every tick far above of a ship at rest in attitude), else its loop. (A
    call of its own, as free_rotation was: inlined at the integrators' sites, the 13 flows made
    LLVM's SROA on step_ticks run for minutes.) Tiny: every
    component of the Casimir turn's rotation vector under TINY_COMPONENT (tiny_turn's condition),
    and every axis flow's half angle under TINY_ANGLE, which sum|c_i| |L|_1 MAX_FRACTION |h| <
    TINY_ANGLE bounds with a factor 2 to spare (|L|_1 grows by at most 1 + 2|s_half| < 1 + 2^-26
    a tiny flow; theta's two roundings). The same bits either way (tests/test_rotation_tiny.py)."""
    i_ref = median_moment(inertia)
    coef = (1.0 / inertia[0] - 1.0 / i_ref, 1.0 / inertia[1] - 1.0 / i_ref,
            1.0 / inertia[2] - 1.0 / i_ref)
    phi = scale(l_b, h / i_ref)
    c_1 = abs(coef[0]) + abs(coef[1]) + abs(coef[2])  # (>= max |c_i|; nan stays nan)
    l_1 = abs(l_b[0]) + abs(l_b[1]) + abs(l_b[2])
    if (abs(phi[0]) < TINY_COMPONENT and abs(phi[1]) < TINY_COMPONENT
            and abs(phi[2]) < TINY_COMPONENT
            and c_1 * l_1 * (MAX_FRACTION * abs(h)) < TINY_ANGLE):
        return tiny_rotation(q, l_b, coef, i_ref, h)
    return rotation_flows(q, l_b, inertia, h)


@separate
def free_rotation(q, l_b, inertia, h):
    """:func:`rotation_flows` as a call of its own (the loop over the flows, each tiny one by
    tiny_axis_flow); the integrators call :func:`rotation_step`."""
    return rotation_flows(q, l_b, inertia, h)
