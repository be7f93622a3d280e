"""Stepping methods, chosen by name (``sim.integrator``). Each advances a free ship by one (sub)step h.

A method takes the state y = (p, v, q, omega_b), the step h and the contact evaluation at its start,
and returns a :class:`Stepped`: the new y and each foot's normal impulse over the step (which
bounds its friction). Friction is applied afterwards as an impulse (:mod:`sim.friction`), so every
method shares one friction law.

``semi_implicit_euler`` is the seed's (``velocity += accel dt; position += velocity dt``).
``exponential`` is built for the stiff contact: it solves the pressing feet's linear spring-damper
exactly over the step. ``hybrid`` (the default) steps a purely vertical ship by ``exponential`` and
any other ship by ``rk4`` (:func:`sub_method`). An unknown name is an error, never a silent
fallback. One ship, compiled.
"""
from __future__ import annotations

import math
from typing import NamedTuple

from touchdown.sim.compiled import kernel, separate
from touchdown.sim.contact import NO_FEET, ContactEval, Feet, feet_of, no_contact
from touchdown.sim.dynamics import Holding, Motion, acceleration, contact_at, contact_forces, \
    contact_geometry, contact_inline, derivatives, derivatives_held, ground_at, torque_body
from touchdown.sim.exact import (Flow, Functional, bracketed_root, first_crossing, flow_at,
    flow_start, value_and_rate)
from touchdown.sim.rotation import rotation_step
from touchdown.sim.settings import Integrator
from touchdown.sim.vec import add, div, dot, fmax, mul, norm, quat_add_scaled, quat_integrate, \
    quat_normalize, scale, sub

#: Every method by name, and its code inside the kernels (sim.settings.Integrator). An unknown name
#: is rejected when a scenario is loaded.
METHODS: dict[str, int] = {m.label: int(m) for m in Integrator}
EXPLICIT_EULER, SEMI_IMPLICIT_EULER, VELOCITY_VERLET, RK4, EXPONENTIAL, HYBRID = (int(m) for m in Integrator)


@kernel
def sub_method(method, rough):
    """The method a ship is stepped with: ``hybrid`` is ``rk4`` for a ship near the ground that is
    not purely vertical (``rough``): its rotation and friction carry its motion, which rk4 follows
    at the sub-step the exponential method needs five times smaller for; and ``exponential``
    otherwise (exact for a vertical bounce, one step a tick); every other name is itself
    (MODEL-NOTES 38)."""
    if method == HYBRID:
        return RK4 if rough else EXPONENTIAL
    return method


class Stepped(NamedTuple):
    """What one (sub)step of a method produced."""

    p: tuple
    v: tuple
    q: tuple
    w: tuple
    #: each foot's normal impulse over the step, N s (>= 0): what bounds its friction
    foot_impulse_ns: tuple
    #: the deepest penetration inside the step (-inf where it lies at an end), for a method that
    #: locates it (``located``); otherwise the caller interpolates between the step's ends
    peak_penetration_m: float
    located: bool


@kernel
def _pressing(ce):
    """(max(f_i, 0), |g_i|) for each foot of an evaluation: its force and the length of its
    push (the weight of a quadrature rule multiplies the force first)."""
    f = ce.foot_force_n
    return (fmax(f[0], 0.0), fmax(f[1], 0.0), fmax(f[2], 0.0), fmax(f[3], 0.0)), ce.push_norm


@kernel
def foot_impulses_1(h, ce):
    """Each foot's normal impulse h max(f_i, 0) |g_i| (the rectangle rule on the step's start)."""
    if not ce.touching:
        return (0.0, 0.0, 0.0, 0.0)
    f, g = _pressing(ce)
    return (h * (0.0 + 1.0 * f[0] * g[0]), h * (0.0 + 1.0 * f[1] * g[1]),
            h * (0.0 + 1.0 * f[2] * g[2]), h * (0.0 + 1.0 * f[3] * g[3]))


@kernel
def foot_impulses_2(h, ce0, ce1):
    """Each foot's normal impulse by the trapezoid rule on the step's two ends."""
    if not ce0.touching:
        return (0.0, 0.0, 0.0, 0.0)
    f, g = _pressing(ce0)
    e, k = _pressing(ce1)
    return (h * (0.0 + 0.5 * f[0] * g[0] + 0.5 * e[0] * k[0]),
            h * (0.0 + 0.5 * f[1] * g[1] + 0.5 * e[1] * k[1]),
            h * (0.0 + 0.5 * f[2] * g[2] + 0.5 * e[2] * k[2]),
            h * (0.0 + 0.5 * f[3] * g[3] + 0.5 * e[3] * k[3]))


@kernel
def foot_impulses_4(h, c1, c2, c3, c4):
    """Each foot's normal impulse by RK4's weights on its four evaluations."""
    if not c1.touching:
        return (0.0, 0.0, 0.0, 0.0)
    fa, ga = _pressing(c1)
    fb, gb = _pressing(c2)
    fc, gc = _pressing(c3)
    fd, gd = _pressing(c4)
    w1, w2 = 1 / 6, 1 / 3
    return (h * (0.0 + w1 * fa[0] * ga[0] + w2 * fb[0] * gb[0] + w2 * fc[0] * gc[0]
                 + w1 * fd[0] * gd[0]),
            h * (0.0 + w1 * fa[1] * ga[1] + w2 * fb[1] * gb[1] + w2 * fc[1] * gc[1]
                 + w1 * fd[1] * gd[1]),
            h * (0.0 + w1 * fa[2] * ga[2] + w2 * fb[2] * gb[2] + w2 * fc[2] * gc[2]
                 + w1 * fd[2] * gd[2]),
            h * (0.0 + w1 * fa[3] * ga[3] + w2 * fb[3] * gb[3] + w2 * fc[3] * gc[3]
                 + w1 * fd[3] * gd[3]))


@kernel
def explicit_euler(fb, h, motion, ce, absorbing, t0):
    """y += h f(y): first order, unstable on the undamped spring for any h."""
    p, v, q, w = motion
    dp, dv, dq, dw = derivatives(fb, ce, p, v, q, w)
    return Stepped(add(p, scale(dp, h)), add(v, scale(dv, h)),
                   quat_normalize(quat_add_scaled(q, dq, h)), add(w, scale(dw, h)),
                   foot_impulses_1(h, ce), -math.inf, False)


@kernel
def semi_implicit_euler(fb, h, motion, ce, absorbing, t0):
    """The seed's method: velocities first, then positions with the new velocities."""
    p, v, q, w = motion
    _, dv, _, dw = derivatives(fb, ce, p, v, q, w)
    v1 = add(v, scale(dv, h))
    w1 = add(w, scale(dw, h))
    return Stepped(add(p, scale(v1, h)), v1, quat_integrate(q, w1, h), w1,
                   foot_impulses_1(h, ce), -math.inf, False)


#: m: a ship's centre this much farther from level ground than its feet reach has every foot
#: clear of it by more than any engage threshold (ONSET_MARGIN_M, 1e-6 m) and rounding
CLEAR_MARGIN_M = 1e-3


@kernel
def surely_clear(fb, p):
    """Every foot of a ship at ``p`` is clear of level ground whatever its attitude: the centre is
    farther above the ground than sqrt(a^2 + h^2), the feet's distance from it, plus
    CLEAR_MARGIN_M. Its contact evaluation is then no contact's: no foot presses, so the ground's
    force and moment are exactly +0 either way (sim.contact.evaluate sums +0 and the feet's +-0
    into +0), as are the feet's forces. Only on level ground (the bound would need the slope's
    plane and the bumps' heights elsewhere)."""
    cr = fb.craft
    if not (cr.touching and cr.terrain.level):
        return False
    reach = math.sqrt(cr.leg_radius_m * cr.leg_radius_m + cr.com_height_m * cr.com_height_m)
    return norm(p) - cr.body_radius_m - cr.terrain.base_height_m > reach + CLEAR_MARGIN_M


@kernel
def _rk4_stage(fb, hf, y, k, absorbing, t0):
    """A stage of rk4: the derivatives and the contact at y + hf k (``y``: the step's start,
    sim.dynamics.Motion; ``k``: the last stage's derivatives; ``hf``: the stage's offset, frac h),
    hf after t0."""
    p, v, q, w = y
    ps, vs, qs, ws = add(p, scale(k[0], hf)), add(v, scale(k[1], hf)), \
        quat_add_scaled(q, k[2], hf), add(w, scale(k[3], hf))
    # a stage's contact serves its derivatives and its feet's forces alone: where every foot is
    # surely clear, no contact's (the same bits: surely_clear)
    if surely_clear(fb, ps):
        ce_s = no_contact(ps)
    else:
        ce_s = contact_inline(fb, ground_at(fb, t0 + hf), Motion(ps, vs, qs, ws), absorbing,
                              fb.grip.engage_m)
    return derivatives(fb, ce_s, ps, vs, qs, ws), ce_s


@kernel
def _rk4_combine(a, b1, b2, b3, b4, h6):
    return add(a, scale(add(add(add(b1, scale(b2, 2.0)), scale(b3, 2.0)), b4), h6))


@separate
def rk4(fb, h, motion, ce, absorbing, t0):
    """Classical fourth-order Runge-Kutta; the quaternion is renormalised at the end."""
    p, v, q, w = motion
    y = Motion(p, v, q, w)
    k1 = derivatives(fb, ce, p, v, q, w)
    k2, c2 = _rk4_stage(fb, 0.5 * h, y, k1, absorbing, t0)
    k3, c3 = _rk4_stage(fb, 0.5 * h, y, k2, absorbing, t0)
    k4, c4 = _rk4_stage(fb, h, y, k3, absorbing, t0)
    h6 = h / 6.0
    q_sum = (k1[2][0] + 2.0 * k2[2][0] + 2.0 * k3[2][0] + k4[2][0],
             k1[2][1] + 2.0 * k2[2][1] + 2.0 * k3[2][1] + k4[2][1],
             k1[2][2] + 2.0 * k2[2][2] + 2.0 * k3[2][2] + k4[2][2],
             k1[2][3] + 2.0 * k2[2][3] + 2.0 * k3[2][3] + k4[2][3])
    return Stepped(_rk4_combine(p, k1[0], k2[0], k3[0], k4[0], h6),
                   _rk4_combine(v, k1[1], k2[1], k3[1], k4[1], h6),
                   quat_normalize(quat_add_scaled(q, q_sum, h6)),
                   _rk4_combine(w, k1[3], k2[3], k3[3], k4[3], h6),
                   foot_impulses_4(h, ce, c2, c3, c4), -math.inf, False)


@kernel
def _rk4_stage_held(fb, hf, y, k, absorbing, t0, holding):
    """A stage of :func:`rk4_held`: the derivatives with the held feet's friction, that friction,
    and the contact, at y + hf k (``hf``: frac h)."""
    p, v, q, w = y
    ps, vs, qs, ws = add(p, scale(k[0], hf)), add(v, scale(k[1], hf)), \
        quat_add_scaled(q, k[2], hf), add(w, scale(k[3], hf))
    ground = ground_at(fb, t0 + hf)
    if surely_clear(fb, ps):  # (as in _rk4_stage; no foot is then held either)
        ce_s = no_contact(ps)
    else:
        ce_s = contact_inline(fb, ground, Motion(ps, vs, qs, ws), absorbing, fb.grip.engage_m)
    d, hd = derivatives_held(fb, ground, ce_s, Motion(ps, vs, qs, ws), holding)
    return d, hd, ce_s


@kernel
def _held_impulse(h, a, b, c, d):
    """A foot's static friction impulse over the step by RK4's weights on its four stages."""
    w1, w2 = h / 6.0, h / 3.0
    return (w1 * a[0] + w2 * b[0] + w2 * c[0] + w1 * d[0],
            w1 * a[1] + w2 * b[1] + w2 * c[1] + w1 * d[1],
            w1 * a[2] + w2 * b[2] + w2 * c[2] + w1 * d[2])


class SteppedHeld(NamedTuple):
    """A step of :func:`rk4_held`, and the held feet's static friction impulse over it (each
    foot's, inertial, N s)."""

    stepped: Stepped
    held_impulse_w: tuple


# (inlined into its one caller, sim.flight.substep: no call passing a ContactEval and a FreeBody
# by value; session15-glue)
@kernel
def rk4_held(fb, h, motion, ce, absorbing, t0, holding):
    """:func:`rk4` with the static friction of the feet of ``holding`` (sim.dynamics.Holding)
    inside the step as the force of
    their constraint (sim.dynamics.held_friction, MODEL-NOTES 46), at every stage: a held foot's
    friction then follows the ship's motion at the method's order, where a force carried from the
    last step and corrected by an impulse after this one was first order in the step."""
    y = motion
    p, v, q, w = motion
    k1, f1 = derivatives_held(fb, ground_at(fb, t0), ce, motion, holding)
    k2, f2, c2 = _rk4_stage_held(fb, 0.5 * h, y, k1, absorbing, t0, holding)
    k3, f3, c3 = _rk4_stage_held(fb, 0.5 * h, y, k2, absorbing, t0, holding)
    k4, f4, c4 = _rk4_stage_held(fb, h, y, k3, absorbing, t0, holding)
    h6 = h / 6.0
    q_sum = (k1[2][0] + 2.0 * k2[2][0] + 2.0 * k3[2][0] + k4[2][0],
             k1[2][1] + 2.0 * k2[2][1] + 2.0 * k3[2][1] + k4[2][1],
             k1[2][2] + 2.0 * k2[2][2] + 2.0 * k3[2][2] + k4[2][2],
             k1[2][3] + 2.0 * k2[2][3] + 2.0 * k3[2][3] + k4[2][3])
    st = Stepped(_rk4_combine(p, k1[0], k2[0], k3[0], k4[0], h6),
                 _rk4_combine(v, k1[1], k2[1], k3[1], k4[1], h6),
                 quat_normalize(quat_add_scaled(q, q_sum, h6)),
                 _rk4_combine(w, k1[3], k2[3], k3[3], k4[3], h6),
                 foot_impulses_4(h, ce, c2, c3, c4), -math.inf, False)
    a, b, c, d = f1.feet_w, f2.feet_w, f3.feet_w, f4.feet_w
    return SteppedHeld(st, (_held_impulse(h, a[0], b[0], c[0], d[0]),
                            _held_impulse(h, a[1], b[1], c[1], d[1]),
                            _held_impulse(h, a[2], b[2], c[2], d[2]),
                            _held_impulse(h, a[3], b[3], c[3], d[3])))


@kernel
def _turn(fb, q, w, tau_b, h):
    """The rotation's kick and drift: a half kick of the external torque, then the exact
    torque-free flow (sim.rotation). Returns the new attitude and the body-frame angular momentum
    before the closing half kick."""
    l_half = add(mul(fb.craft.inertia_kgm2, w), scale(tau_b, 0.5 * h))
    return rotation_step(q, l_half, fb.craft.inertia_kgm2, h)


@kernel
def pressed(ce):
    """Some foot pushes at this evaluation (its force then depends on the velocities)."""
    f = ce.foot_force_n
    return ce.touching and (f[0] != 0.0 or f[1] != 0.0 or f[2] != 0.0 or f[3] != 0.0)


@kernel
def velocity_verlet(fb, h, motion, ce, absorbing, t0):
    """Kick-drift-kick (second order, symplectic for position-only forces). The closing kick
    needs the force at the end, whose dampers depend on the end's velocities: it is evaluated with
    the half-step velocities, then once more with the velocities that gives (one fixed-point pass;
    with the half-step ones alone, the usual explicit form, a tilted touchdown's rotation is only
    first order in the step). The rotation's drift is the exact torque-free flow (Dullweber,
    Leimkuhler & McLachlan, J. Chem. Phys. 107, 1997)."""
    p, v, q, w = motion
    a0 = acceleration(fb, ce, p, q)
    v_half = add(v, scale(a0, 0.5 * h))
    p1 = add(p, scale(v_half, h))
    q1, l_pre = _turn(fb, q, w, torque_body(fb, ce, q), h)
    w_pre = div(l_pre, fb.craft.inertia_kgm2)
    ground1 = ground_at(fb, t0 + h)
    ce1 = contact_at(fb, ground1, Motion(p1, v_half, q1, w_pre), absorbing, fb.grip.engage_m)
    v1 = add(v_half, scale(acceleration(fb, ce1, p1, q1), 0.5 * h))
    w1 = div(add(l_pre, scale(torque_body(fb, ce1, q1), 0.5 * h)), fb.craft.inertia_kgm2)
    if pressed(ce1):  # the dampers at the end, at the end's velocities (see _damped_end)
        ce1 = contact_at(fb, ground1, Motion(p1, v1, q1, w1), absorbing, fb.grip.engage_m)
        v1 = add(v_half, scale(acceleration(fb, ce1, p1, q1), 0.5 * h))
        w1 = div(add(l_pre, scale(torque_body(fb, ce1, q1), 0.5 * h)), fb.craft.inertia_kgm2)
    return Stepped(p1, v1, q1, w1, foot_impulses_2(h, ce, ce1), -math.inf, False)


class Released(NamedTuple):
    """The spring-damper's flow over a step until the spring lets go, ballistic after."""

    x_m: float  # height gained over the step
    v_mps: float  # x' at the step's end
    a_mps2: float  # x'' at the step's end
    t_acted_s: float  # how long the spring acted (the step, if it never let go)
    v_released_mps: float  # x' when it let go


class SteppedEnd(NamedTuple):
    """A step, and the last contact evaluation it made at its end (for the evaluations after it
    at the same state: sim.flight.vertical_flight's guard)."""

    stepped: Stepped
    ce: ContactEval  # at the end's pose, at the instant t0 + h
    motion: Motion  # the motion it was evaluated at (the end's velocities, or the drift's)
    engage: tuple  # the engage thresholds it was evaluated with
    feet: Feet  # the feet at the end's pose (sim.contact.feet's numbers; NO_FEET if clear)


class KickedEnd(NamedTuple):
    """:func:`closing_kick`'s results."""

    v: tuple  # v1
    w: tuple  # w1
    kick_force_w: tuple  # the force_w of the evaluation the kick was taken from
    kick_foot_force_n: tuple  # and its feet's forces
    ce: ContactEval  # the last contact evaluated at the end
    motion: Motion  # the motion it was evaluated at
    engage: tuple  # the engage thresholds it was evaluated with
    feet: Feet  # the feet at the end's pose (its geometry's; NO_FEET if clear of the ground)


class Kick(NamedTuple):
    """The exponential step's closing half kick (:func:`closing_kick`)."""

    l_pre: tuple  # the body-frame angular momentum after the drift (before the kick)
    n_hat: tuple  # the spring axis
    a_n: float  # the flow's acceleration along it at the step's end (the model's force)
    h: float  # the step


@kernel
def _kicked(fb, ce1, m_pre, kick):
    """(v1, w1): :func:`closing_kick`'s half kick from the contact ``ce1`` at the step's end."""
    p1, v_pre, q1, _ = m_pre
    l_pre, n_hat, a_n, h = kick
    a1 = acceleration(fb, ce1, p1, q1)
    return (add(v_pre, scale(sub(a1, scale(n_hat, a_n)), 0.5 * h)),
            div(add(l_pre, scale(torque_body(fb, ce1, q1), 0.5 * h)), fb.craft.inertia_kgm2))


@separate
def closing_kick(fb, ground1, m_pre, kick, absorbing):
    """The exponential step's end: the contact at the drift's end ``m_pre`` = (p1, v_pre, q1,
    w_pre) on ``ground1``, and the closing half kick from it, across n and along n the residual
    between the true force and the flow's model (``kick``: a :class:`Kick`),

        v1 = v_pre + (a1 - n a_n) h / 2,   L1 = L_pre + tau1 h / 2;

    where a foot presses there, the dampers' forces (and torque) at the end's own rates: the kick
    again from the contact at (p1, v1, q1, w1), as in velocity_verlet. Both evaluations are at
    one pose and instant: the feet are looked up once (sim.dynamics.contact_geometry), the forces
    phase taken twice (the same bits as two whole evaluations). Returns (v1, w1, the last
    contact evaluated, the motion it was evaluated at)."""
    p1, v_pre, q1, w_pre = m_pre
    engage = fb.grip.engage_m
    if not fb.craft.touching:
        return clear_kick(fb, m_pre, kick)
    geo = contact_geometry(fb, ground1, m_pre)
    ce1 = contact_forces(fb, ground1, geo, m_pre, absorbing, engage)
    v1, w1 = _kicked(fb, ce1, m_pre, kick)
    m1 = m_pre
    if pressed(ce1):
        m1 = Motion(p1, v1, q1, w1)
        ce1 = contact_forces(fb, ground1, geo, m1, absorbing, engage)
        v1, w1 = _kicked(fb, ce1, m_pre, kick)
    return KickedEnd(v1, w1, ce1.force_w, ce1.foot_force_n, ce1, m1, engage, feet_of(geo))


@kernel
def clear_kick(fb, m_pre, kick):
    """:func:`closing_kick` of a ship known to be clear of the ground (``fb.craft.touching``
    False: no contact evaluated, no_contact's at the drift's end), inlined where it is called:
    a flying ship's step pays no call that passes the FreeBody and the results through memory."""
    ce1 = no_contact(m_pre.p)
    v1, w1 = _kicked(fb, ce1, m_pre, kick)
    return KickedEnd(v1, w1, ce1.force_w, ce1.foot_force_n, ce1, m_pre, fb.grip.engage_m,
                     NO_FEET)


@kernel
def exponential_end(fb, h, motion, ce, absorbing, t0):
    """Exact flow of the contact's spring-damper, split (Strang) with a kick of everything else.

    Along n, the direction the touching feet push at the step's start (the local vertical on level
    ground, the slope's normal on a slope: sim.contact.spring_axis; held fixed over the step), the
    pressing feet are one linear spring-damper, fitted at the start from the contact evaluation:
    with x the distance gained along n since the start,

        m x'' = m a_free + N0 + C v0 - K x - C x' - (K U) t

    (K, C: the pressing feet's summed stiffness and damping along n; N0 their force along n at the
    start; v0 = v . n; K U the rate at which rotation alone loads the springs; a_free gravity and
    thrust along n). This is solved in closed form (:mod:`sim.exact`), with the instant the spring
    lets go located inside the step (the normal force reaching zero; for an absorbed contact, the
    feet reaching the surface) and the ballistic arc after it. The deepest penetration is located
    too.

    Around that flow, velocity-Verlet half kicks apply what the flow leaves out: torques (contact
    and RCS), forces across n, and the residual along n between the true force at the end and the
    model's (point-mass gravity's change, a foot that began to press). The rotation between the
    kicks is the exact torque-free flow (sim.rotation). Second order in general; exact to rounding
    for an upright ship bouncing on level ground, at any step: the bounce needs no sub-steps at
    all. Stability: the flow is unconditionally stable (|e^{-zeta w h}| < 1), so the only step
    limit left is that of the kicks on the rocking modes (velocity Verlet's, on w_rock; see
    sim.stability). Returns a :class:`SteppedEnd`: the step, and the last contact it evaluated
    at its end."""
    p, v, q, w = motion
    n_hat = ce.axis
    m = fb.craft.mass_kg
    a0 = acceleration(fb, ce, p, q)
    a0_n = dot(a0, n_hat)
    v_n0 = dot(v, n_hat)
    v_half = add(v, scale(sub(a0, scale(n_hat, a0_n)), 0.5 * h))  # across n only
    q1, l_pre = _turn(fb, q, w, torque_body(fb, ce, q), h)
    w_pre = div(l_pre, fb.craft.inertia_kgm2)

    force0_n = dot(ce.force_w, n_hat)
    a_free = a0_n - force0_n / m  # gravity and thrust along n
    flow, k_u = spring_flow(ce, m, a_free, v_n0, force0_n)
    pressing = flow.w2 > 0.0
    rel = until_released(flow, ce, absorbing, a_free, k_u, h)
    sep = rel.t_acted_s < h
    peak = deepest(flow, ce, k_u, v_n0, rel.t_acted_s, rel.v_released_mps)
    impulse_per_kg = rel.v_released_mps - v_n0 - a_free * rel.t_acted_s if pressing else 0.0
    # the model's force along n at the end: the flow's while the spring still acts
    model_end_n = m * (rel.a_mps2 - a_free) if pressing and not sep else 0.0

    # drift: along n by the flow, across n with the half-kicked velocity
    v_across = sub(v_half, scale(n_hat, v_n0))
    p1 = add(add(p, scale(n_hat, rel.x_m)), scale(v_across, h))
    v_pre = add(v_across, scale(n_hat, rel.v_mps))
    # closing kick: across n, and along n the residual between the true force and the model's
    m_pre, kick = Motion(p1, v_pre, q1, w_pre), Kick(l_pre, n_hat, rel.a_mps2, h)
    if fb.craft.touching:
        ke = closing_kick(fb, ground_at(fb, t0 + h), m_pre, kick, absorbing)
    else:
        ke = clear_kick(fb, m_pre, kick)
    return SteppedEnd(Stepped(p1, ke.v, q1, ke.w,
                              exact_foot_impulses(ce, with_forces(ke.ce, ke.kick_force_w,
                                                                  ke.kick_foot_force_n),
                                                  n_hat, h, m * impulse_per_kg, model_end_n),
                              peak, True), ke.ce, ke.motion, ke.engage, ke.feet)


@kernel
def with_forces(ce, force_w, foot_force_n):
    """``ce`` with the total force and the feet's forces of another evaluation at the same pose
    (what :func:`exact_foot_impulses` reads of the closing kick's evaluation, with the pose's
    ``touching`` and ``push_norm``)."""
    return ContactEval(ce.touching, ce.pen_m, ce.pen_rate_mps, foot_force_n, ce.push_norm, force_w,
                       ce.torque_w, ce.normal_n, ce.slip_w, ce.friction_n, ce.max_penetration_m,
                       ce.lowest_foot_w, ce.axis, ce.stiffness_npm, ce.damping_nspm,
                       ce.spring_load_n, ce.spring_load_rate_nps, ce.lowest_gamma, ce.normal_w)


@kernel
def exponential(fb, h, motion, ce, absorbing, t0):
    """:func:`exponential_end`'s step alone."""
    return exponential_end(fb, h, motion, ce, absorbing, t0).stepped


@kernel
def exact_foot_impulses(ce, ce1, n_hat, h, flow_impulse_ns, model_end_n):
    """Each foot's normal impulse for the exponential step: the total along n is the flow's
    (``flow_impulse_ns``), plus the closing kick's residual between the feet's force along n at
    the step's end and the model's there (``model_end_n``: for a foot that lifted or pressed
    during the step); it is shared among the feet as the trapezoid rule on their forces at the
    step's ends shares it."""
    if not ce.touching:
        return (0.0, 0.0, 0.0, 0.0)
    end_n = dot(ce1.force_w, n_hat)
    total_n = flow_impulse_ns + 0.5 * h * (end_n - model_end_n)
    trap_n = 0.5 * h * (dot(ce.force_w, n_hat) + end_n)
    f = total_n / trap_n if trap_n != 0.0 else 1.0
    j = foot_impulses_2(h, ce, ce1)
    return (fmax(f * j[0], 0.0), fmax(f * j[1], 0.0), fmax(f * j[2], 0.0), fmax(f * j[3], 0.0))


@kernel
def spring_flow(ce, m, a_free, v_n0, force0_n):
    """The pressing feet as one spring-damper along n, fitted at the step's start, and K U (the
    rate at which rotation alone loads the springs: sum k_i gamma_i u_i). x is the height gained;
    ``force0_n`` the feet's force along n at the start."""
    stiff, damp = ce.stiffness_npm, ce.damping_nspm
    k_u = -(ce.spring_load_rate_nps + stiff * v_n0)
    flow = Flow(stiff / m, damp / m, a_free + (force0_n + damp * v_n0) / m, -k_u / m, 0.0, v_n0)
    return flow, k_u


@kernel
def until_released(flow, ce, absorbing, a_free, k_u, h):
    """The flow over the step, until the spring lets go and ballistic after: the normal force per
    unit mass (x'' - a_free) reaching zero, or, for an absorbed (bilateral) contact, the pressing
    feet's mean penetration reaching zero."""
    x_h, v_h, acc_h = flow_at(flow, h)
    if not flow.w2 > 0.0:
        return Released(x_h, v_h, acc_h, h, v_h)
    k = ce.stiffness_npm
    if absorbing:
        let_go = Functional(-1.0, 0.0, 0.0, ce.spring_load_n / k, -k_u / k)
    else:
        let_go = Functional(0.0, 0.0, 1.0, -a_free, 0.0)
    x0, v0, a0 = flow_start(flow)
    g0 = value_and_rate(let_go, flow, 0.0, x0, v0, a0)[0]
    if not g0 > 0.0:
        return Released(x_h, v_h, acc_h, h, v_h)
    g_h = value_and_rate(let_go, flow, h, x_h, v_h, acc_h)[0]
    crossed, lo, hi, g_lo, g_hi = first_crossing(flow, let_go, h, g0, g_h)
    if not crossed:
        return Released(x_h, v_h, acc_h, h, v_h)
    t_act = bracketed_root(flow, let_go, lo, hi, g_lo, g_hi)
    x_s, v_act, _ = flow_at(flow, t_act)
    tail = h - t_act
    return Released(x_s + tail * (v_act + 0.5 * a_free * tail), v_act + a_free * tail, a_free,
                    t_act, v_act)


@kernel
def deepest(flow, ce, k_u, v_n0, t_act, v_act):
    """The deepest penetration inside the step, where x' first turns from down to up while the
    spring acts (-inf where it lies at an end of the step)."""
    if not (flow.w2 > 0.0 and v_n0 < 0.0):
        return -math.inf
    speed = Functional(0.0, 1.0, 0.0, 0.0, 0.0)
    turned, lo, hi, g_lo, g_hi = first_crossing(flow, speed, t_act, v_n0, v_act)
    if not turned:
        return -math.inf
    t_pk = bracketed_root(flow, speed, lo, hi, g_lo, g_hi)
    x_pk = flow_at(flow, t_pk)[0]
    return ce.max_penetration_m - ce.lowest_gamma * x_pk - (k_u / ce.stiffness_npm) * t_pk


@kernel
def advance(method, fb, h, motion, ce, absorbing, t0):
    """One (sub)step of the method coded ``method`` (:data:`METHODS`) from ``motion`` (p, v, q,
    w: sim.dynamics.Motion)."""
    if method == EXPONENTIAL:
        return exponential(fb, h, motion, ce, absorbing, t0)
    if method == RK4:
        return rk4(fb, h, motion, ce, absorbing, t0)
    if method == VELOCITY_VERLET:
        return velocity_verlet(fb, h, motion, ce, absorbing, t0)
    if method == SEMI_IMPLICIT_EULER:
        return semi_implicit_euler(fb, h, motion, ce, absorbing, t0)
    return explicit_euler(fb, h, motion, ce, absorbing, t0)
