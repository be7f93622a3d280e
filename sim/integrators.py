"""Stepping methods, chosen by name (``sim.integrator``). Each advances free ships by one (sub)step h.

A method takes the state y = (p, v, q, omega_b), the step h (a number, or one per ship, shape (N,))
and the contact evaluation at its start, and returns a :class:`Stepped`: the new y and the
normal-force impulse it applied divided by h (the mean normal force over the step, which bounds
the friction impulse). Friction is applied afterwards as an impulse (:mod:`sim.friction`), so every
method shares one friction law.

``semi_implicit_euler`` is the seed's (``velocity += accel dt; position += velocity dt``).
``exponential`` is built for the stiff contact: it solves the pressing feet's linear spring-damper
exactly over the step. An unknown name is an error, never a silent fallback.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from sim import exact, vec
from sim.contact import ContactEval, Four
from sim.dynamics import FreeBodies, acceleration, contact_at, derivatives, torque_body
from sim.rotation import free_rotation

Y = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
Step = float | np.ndarray


@dataclass(frozen=True)
class Stepped:
    """What one (sub)step of a method produced."""

    y: Y
    #: each foot's normal impulse over the step, N s (>= 0): what bounds its friction
    foot_impulse_ns: Four
    #: (N,) deepest penetration inside the step, for methods that locate it exactly (else None:
    #: the caller interpolates between the step's ends); -inf where it lies at an end
    peak_penetration_m: np.ndarray | None = None


#: (free bodies, step h, state y, contact at the start, absorbing, the start's offset in the tick)
Method = Callable[[FreeBodies, Step, Y, ContactEval, np.ndarray, Step], Stepped]


def times(h: Step, x: np.ndarray) -> np.ndarray:
    """h * x for a step that is a number or one per ship (rows of x)."""
    return h * x if np.ndim(h) == 0 else h[:, None] * x


def foot_impulses(h: Step, evals: list[ContactEval], weights: tuple[float, ...]) -> Four:
    """Each foot's normal impulse h sum_k w_k max(f_ik, 0) |g_ik| over the evaluations of a step
    (a quadrature rule: weights sum to one). A pulling absorber gives no friction."""
    if evals[0].feet is None:
        z = np.zeros(evals[0].normal_n.shape)
        return z, z, z, z
    out = []
    for i in range(4):
        acc = 0.0
        for w, ce in zip(weights, evals):
            acc = acc + w * np.maximum(ce.foot_force_n[i], 0.0) * vec.norm(ce.feet.push_w[i])
        out.append(h * acc)
    return tuple(out)


def explicit_euler(fb: FreeBodies, h: Step, y: Y, ce: ContactEval, absorbing, t0: Step
                   ) -> Stepped:
    """y += h f(y): first order, unstable on the undamped spring for any h."""
    p, v, q, w = y
    dp, dv, dq, dw = derivatives(fb, ce, p, v, q, w)
    return Stepped((p + times(h, dp), v + times(h, dv), vec.quat_normalize(q + times(h, dq)),
                    w + times(h, dw)), foot_impulses(h, [ce], (1.0,)))


def semi_implicit_euler(fb: FreeBodies, h: Step, y: Y, ce: ContactEval, absorbing, t0: Step
                        ) -> Stepped:
    """The seed's method: velocities first, then positions with the new velocities."""
    p, v, q, w = y
    _, dv, _, dw = derivatives(fb, ce, p, v, q, w)
    v1 = v + times(h, dv)
    w1 = w + times(h, dw)
    return Stepped((p + times(h, v1), v1, vec.quat_integrate(q, w1, h), w1),
                   foot_impulses(h, [ce], (1.0,)))


def rk4(fb: FreeBodies, h: Step, y: Y, ce: ContactEval, absorbing, t0: Step) -> Stepped:
    """Classical fourth-order Runge-Kutta; the quaternion is renormalised at the end."""
    p, v, q, w = y
    k1 = derivatives(fb, ce, p, v, q, w)

    def stage(kprev, frac):
        ys = tuple(a + times(frac * h, b) for a, b in zip(y, kprev))
        ce_s = contact_at(fb, fb.ground_at(t0 + frac * h), *ys, absorbing)
        return derivatives(fb, ce_s, *ys), ce_s

    k2, c2 = stage(k1, 0.5)
    k3, c3 = stage(k2, 0.5)
    k4, c4 = stage(k3, 1.0)
    out = tuple(a + times(h / 6.0, b1 + 2.0 * b2 + 2.0 * b3 + b4)
                for a, b1, b2, b3, b4 in zip(y, k1, k2, k3, k4))
    return Stepped((out[0], out[1], vec.quat_normalize(out[2]), out[3]),
                   foot_impulses(h, [ce, c2, c3, c4], (1 / 6, 1 / 3, 1 / 3, 1 / 6)))


def _turn(fb: FreeBodies, q, w, tau_b, h: Step):
    """The rotation's kick and drift: a half kick of the external torque, then the exact
    torque-free flow (sim.rotation). Returns the new attitude and the body-frame angular momentum
    before the closing half kick."""
    l_half = fb.inertia_kgm2 * w + times(0.5 * h, tau_b)
    return free_rotation(q, l_half, fb.inertia_kgm2, h)


def velocity_verlet(fb: FreeBodies, h: Step, y: Y, ce: ContactEval, absorbing, t0: Step
                    ) -> Stepped:
    """Kick-drift-kick (second order, symplectic for position-only forces). The closing kick
    evaluates the force at the new position with the half-step velocity, the usual explicit form
    when the force also depends on velocity (the damper). The rotation's drift is the exact
    torque-free flow (Dullweber, Leimkuhler & McLachlan, J. Chem. Phys. 107, 1997)."""
    p, v, q, w = y
    a0 = acceleration(fb, ce, p, q)
    v_half = v + times(0.5 * h, a0)
    p1 = p + times(h, v_half)
    q1, l_pre = _turn(fb, q, w, torque_body(fb, ce, q), h)
    w_pre = l_pre / fb.inertia_kgm2
    ce1 = contact_at(fb, fb.ground_at(t0 + h), p1, v_half, q1, w_pre, absorbing)
    v1 = v_half + times(0.5 * h, acceleration(fb, ce1, p1, q1))
    w1 = (l_pre + times(0.5 * h, torque_body(fb, ce1, q1))) / fb.inertia_kgm2
    return Stepped((p1, v1, q1, w1), foot_impulses(h, [ce, ce1], (0.5, 0.5)))


def exponential(fb: FreeBodies, h: Step, y: Y, ce: ContactEval, absorbing, t0: Step
                ) -> Stepped:
    """Exact flow of the contact's spring-damper, split (Strang) with a kick of everything else.

    Along n, the local vertical at the step's start (held fixed over the step), the pressing feet
    are one linear spring-damper, fitted at the start from the contact evaluation: with x the
    height gained since the start,

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
    sim.stability)."""
    p, v, q, w = y
    n_hat = vec.unit(p)
    m = fb.mass_kg
    h_arr = np.broadcast_to(np.asarray(h, dtype=float), m.shape)
    a0 = acceleration(fb, ce, p, q)
    a0_n = vec.dot(a0, n_hat)
    v_n0 = vec.dot(v, n_hat)
    v_half = v + times(0.5 * h, a0 - vec.scale(n_hat, a0_n))  # across n only
    q1, l_pre = _turn(fb, q, w, torque_body(fb, ce, q), h)
    w_pre = l_pre / fb.inertia_kgm2

    force0_n = vec.dot(ce.force_w, n_hat)
    a_free = a0_n - force0_n / m  # gravity and thrust along n
    flow, k_u = _spring_flow(ce, m, a_free, v_n0, force0_n)
    pressing = flow.w2 > 0.0
    x_h, v_h, acc_h, t_act, v_act = _until_released(flow, ce, absorbing, a_free, k_u, h_arr)
    sep = t_act < h_arr
    peak = _deepest(flow, ce, k_u, v_n0, t_act, v_act)
    impulse_per_kg = np.where(pressing, v_act - v_n0 - a_free * t_act, 0.0)

    # drift: along n by the flow, across n with the half-kicked velocity
    v_across = v_half - vec.scale(n_hat, v_n0)
    p1 = p + vec.scale(n_hat, x_h) + times(h, v_across)
    v_pre = v_across + vec.scale(n_hat, v_h)
    ce1 = contact_at(fb, fb.ground_at(t0 + h), p1, v_pre, q1, w_pre, absorbing)
    a1 = acceleration(fb, ce1, p1, q1)
    # closing kick: across n, and along n the residual between the true force and the model's
    v1 = v_pre + times(0.5 * h, a1 - vec.scale(n_hat, acc_h))
    w1 = (l_pre + times(0.5 * h, torque_body(fb, ce1, q1))) / fb.inertia_kgm2
    return Stepped((p1, v1, q1, w1),
                   _exact_foot_impulses(fb, ce, ce1, n_hat, h_arr, impulse_per_kg, pressing, sep,
                                        acc_h, a_free),
                   peak)


def _exact_foot_impulses(fb, ce, ce1, n_hat, h, impulse_per_kg, pressing, sep, acc_h, a_free
                         ) -> Four:
    """Each foot's normal impulse for the exponential step: the total along n is the flow's
    (plus the closing kick's residual, for a foot that lifted or pressed during the step); it is
    shared among the feet as the trapezoid rule on their forces at the step's ends shares it."""
    if ce.feet is None:
        return foot_impulses(h, [ce], (1.0,))
    m = fb.mass_kg
    model_end_n = np.where(pressing & ~sep, m * (acc_h - a_free), 0.0)
    total_n = m * impulse_per_kg + 0.5 * h * (vec.dot(ce1.force_w, n_hat) - model_end_n)
    trap_n = 0.5 * h * (vec.dot(ce.force_w, n_hat) + vec.dot(ce1.force_w, n_hat))
    scale = total_n / np.where(trap_n != 0.0, trap_n, 1.0)
    scale = np.where(trap_n != 0.0, scale, 1.0)
    shares = foot_impulses(h, [ce, ce1], (0.5, 0.5))
    return tuple(np.maximum(scale * j, 0.0) for j in shares)


def _spring_flow(ce: ContactEval, m: np.ndarray, a_free: np.ndarray, v_n0: np.ndarray,
                 force0_n: np.ndarray) -> tuple[exact.Flow, np.ndarray]:
    """The pressing feet as one spring-damper along n, fitted at the step's start, and K U (the
    rate at which rotation alone loads the springs: sum k_i gamma_i u_i). x is the height gained;
    ``force0_n`` the feet's force along n at the start."""
    stiff, damp = ce.stiffness_npm, ce.damping_nspm
    k_u = -(ce.spring_load_rate_nps + stiff * v_n0)
    flow = exact.Flow(w2=stiff / m, c1=damp / m, b0=a_free + (force0_n + damp * v_n0) / m,
                      b1=-k_u / m, x0=np.zeros_like(m), v0=v_n0)
    return flow, k_u


def _until_released(flow: exact.Flow, ce: ContactEval, absorbing: np.ndarray,
                    a_free: np.ndarray, k_u: np.ndarray, h: np.ndarray):
    """The flow over the step, until the spring lets go and ballistic after: the normal force per
    unit mass (x'' - a_free) reaching zero, or, for an absorbed (bilateral) contact, the pressing
    feet's mean penetration reaching zero. Returns (x, x', x'') at the step's end, how long the
    spring acted, and x' when it let go."""
    x_h, v_h, acc_h = flow.at(h)
    pressing = flow.w2 > 0.0
    safe_k = np.where(pressing, ce.stiffness_npm, 1.0)
    let_go = exact.Functional(
        cx=np.where(absorbing, -1.0, 0.0), ca=np.where(absorbing, 0.0, 1.0),
        c0=np.where(absorbing, ce.spring_load_n / safe_k, -a_free),
        ct=np.where(absorbing, -k_u / safe_k, 0.0))
    g0, _ = let_go.value_and_rate(flow, np.zeros_like(h), flow.start())
    g_h, _ = let_go.value_and_rate(flow, h, (x_h, v_h, acc_h))
    t_act = h.copy()
    v_act = v_h.copy()
    c = np.flatnonzero(pressing & (g0 > 0.0))
    if c.size:
        crossed, lo, hi, g_lo, g_hi = exact.first_crossing(
            flow.take(c), let_go.take(c), h[c], g0[c], g_h[c])
        i, k = c[crossed], np.flatnonzero(crossed)
        if i.size:
            t_act[i] = exact.bracketed_root(flow.take(i), let_go.take(i), lo[k], hi[k], g_lo[k],
                                            g_hi[k])
            x_s, v_act[i], _ = flow.take(i).at(t_act[i])
            tail = h[i] - t_act[i]
            x_h[i] = x_s + tail * (v_act[i] + 0.5 * a_free[i] * tail)
            v_h[i] = v_act[i] + a_free[i] * tail
            acc_h[i] = a_free[i]
    return x_h, v_h, acc_h, t_act, v_act


def _deepest(flow: exact.Flow, ce: ContactEval, k_u: np.ndarray, v_n0: np.ndarray,
             t_act: np.ndarray, v_act: np.ndarray) -> np.ndarray:
    """The deepest penetration inside the step, where x' first turns from down to up while the
    spring acts (-inf where it lies at an end of the step)."""
    peak = np.full(v_n0.shape, -np.inf)
    d = np.flatnonzero((flow.w2 > 0.0) & (v_n0 < 0.0))
    if d.size:
        speed = exact.Functional(cv=1.0)
        turned, lo, hi, g_lo, g_hi = exact.first_crossing(flow.take(d), speed, t_act[d], v_n0[d],
                                                          v_act[d])
        i, k = d[turned], np.flatnonzero(turned)
        if i.size:
            fl = flow.take(i)
            t_pk = exact.bracketed_root(fl, speed, lo[k], hi[k], g_lo[k], g_hi[k])
            x_pk, _, _ = fl.at(t_pk)
            peak[i] = ce.max_penetration_m[i] - x_pk - (k_u[i] / ce.stiffness_npm[i]) * t_pk
    return peak


#: Every method by name; an unknown name is rejected when a scenario is loaded.
METHODS: dict[str, Method] = {
    "explicit_euler": explicit_euler,
    "semi_implicit_euler": semi_implicit_euler,
    "velocity_verlet": velocity_verlet,
    "rk4": rk4,
    "exponential": exponential,
}


def method(name: str) -> Method:
    try:
        return METHODS[name]
    except KeyError:
        raise ValueError(f"unknown integrator {name!r}; known: {', '.join(sorted(METHODS))}") from None
