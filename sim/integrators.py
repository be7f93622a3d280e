"""Stepping methods, chosen by name (``sim.integrator``). Each advances free ships by one (sub)step h.

A method takes the state y = (p, v, q, omega_b), the step h (a number, or one per ship, shape (N,))
and the contact evaluation at its start, and returns the new y and the normal-force impulse it
applied divided by h (the mean normal force over the step, which bounds the friction impulse). Friction is applied afterwards as an impulse
(:mod:`sim.friction`), so every method shares one friction law.

``semi_implicit_euler`` is the seed's (``velocity += accel dt; position += velocity dt``). An unknown
name is an error, never a silent fallback.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from sim import vec
from sim.contact import ContactEval, Ground
from sim.dynamics import FreeBodies, contact_at, derivatives

Y = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
Step = float | np.ndarray
Method = Callable[[FreeBodies, Ground, Step, Y, ContactEval, np.ndarray], tuple[Y, np.ndarray]]


def times(h: Step, x: np.ndarray) -> np.ndarray:
    """h * x for a step that is a number or one per ship (rows of x)."""
    return h * x if np.ndim(h) == 0 else h[:, None] * x


def explicit_euler(fb: FreeBodies, ground: Ground, h: Step, y: Y, ce: ContactEval, absorbing
                   ) -> tuple[Y, np.ndarray]:
    """y += h f(y): first order, unstable on the undamped spring for any h."""
    p, v, q, w = y
    dp, dv, dq, dw = derivatives(fb, ce, p, v, q, w)
    return (p + times(h, dp), v + times(h, dv), vec.quat_normalize(q + times(h, dq)),
            w + times(h, dw)), ce.normal_n


def semi_implicit_euler(fb: FreeBodies, ground: Ground, h: Step, y: Y, ce: ContactEval,
                        absorbing) -> tuple[Y, np.ndarray]:
    """The seed's method: velocities first, then positions with the new velocities."""
    p, v, q, w = y
    _, dv, _, dw = derivatives(fb, ce, p, v, q, w)
    v1 = v + times(h, dv)
    w1 = w + times(h, dw)
    return (p + times(h, v1), v1, vec.quat_integrate(q, w1, h), w1), ce.normal_n


def rk4(fb: FreeBodies, ground: Ground, h: Step, y: Y, ce: ContactEval, absorbing
        ) -> tuple[Y, np.ndarray]:
    """Classical fourth-order Runge-Kutta; the quaternion is renormalised at the end."""
    p, v, q, w = y
    k1 = derivatives(fb, ce, p, v, q, w)

    def stage(kprev, frac):
        ys = tuple(a + times(frac * h, b) for a, b in zip(y, kprev))
        ce_s = contact_at(fb, ground, *ys, absorbing)
        return derivatives(fb, ce_s, *ys), ce_s.normal_n

    k2, n2 = stage(k1, 0.5)
    k3, n3 = stage(k2, 0.5)
    k4, n4 = stage(k3, 1.0)
    out = tuple(a + times(h / 6.0, b1 + 2.0 * b2 + 2.0 * b3 + b4)
                for a, b1, b2, b3, b4 in zip(y, k1, k2, k3, k4))
    normal_mean = (ce.normal_n + 2.0 * n2 + 2.0 * n3 + n4) / 6.0
    return (out[0], out[1], vec.quat_normalize(out[2]), out[3]), normal_mean


def velocity_verlet(fb: FreeBodies, ground: Ground, h: Step, y: Y, ce: ContactEval, absorbing
                    ) -> tuple[Y, np.ndarray]:
    """Kick-drift-kick (second order, symplectic for position-only forces). The closing kick
    evaluates the force at the new position with the half-step velocity, the usual explicit form
    when the force also depends on velocity (the damper)."""
    p, v, q, w = y
    _, a0, _, al0 = derivatives(fb, ce, p, v, q, w)
    v_half = v + times(0.5 * h, a0)
    w_half = w + times(0.5 * h, al0)
    p1 = p + times(h, v_half)
    q1 = vec.quat_integrate(q, w_half, h)
    ce1 = contact_at(fb, ground, p1, v_half, q1, w_half, absorbing)
    _, a1, _, al1 = derivatives(fb, ce1, p1, v_half, q1, w_half)
    v1 = v_half + times(0.5 * h, a1)
    w1 = w_half + times(0.5 * h, al1)
    return (p1, v1, q1, w1), 0.5 * (ce.normal_n + ce1.normal_n)


#: Every method by name; an unknown name is rejected when a scenario is loaded.
METHODS: dict[str, Method] = {
    "explicit_euler": explicit_euler,
    "semi_implicit_euler": semi_implicit_euler,
    "velocity_verlet": velocity_verlet,
    "rk4": rk4,
}


def method(name: str) -> Method:
    try:
        return METHODS[name]
    except KeyError:
        raise ValueError(f"unknown integrator {name!r}; known: {', '.join(sorted(METHODS))}") from None
