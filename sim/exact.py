"""The contact's linear spring-damper solved exactly over a step, and roots located on that solution.

While a set of feet presses, the motion of the centre of mass along the local vertical is the
forced damped oscillator

    x'' + c1 x' + w2 x = b0 + b1 t            (x: height gained since the step began, m)

with w2 = K / m, c1 = C / m for the pressing feet's summed stiffness K and damping C, b0 the
constant part of the force per unit mass (gravity, thrust, the springs' load at the start) and
b1 the rate at which rotation alone changes the springs' load (Hairer, Lubich & Wanner, "Geometric
Numerical Integration", II.5: the exact flow of the linear part). Its solution is

    x(t) = P0 + P1 t + z(t),   P1 = b1 / w2,   P0 = (b0 - c1 P1) / w2,
    z(t) = e^{-s t} [ Cb(t) z0 + Sb(t) (z0' + s z0) ],
    z'(t) = e^{-s t} [ Cb(t) z0' - Sb(t) (w2 z0 + s z0') ],      s = c1 / 2,

where Cb(t) = cos(b t) and Sb(t) = sin(b t) / b with b^2 = w2 - s^2 (the exponential of the 2x2
system matrix; b^2 < 0 turns them into cosh and sinh/b, b^2 = 0 into 1 and t). With nothing pressing
(w2 = 0) the motion is the parabola x = x0 + x0' t + b0 t^2 / 2.

Every function here is evaluated with IEEE +, *, / only: e^{-y}, cos and sin/x come from Taylor
polynomials on an argument halved a bounded number of times, then doubled back
(e^{2y} = (e^y)^2, cos 2u = 2 cos^2 u - 1, sin 2u / 2u = (sin u / u) cos u), never from libm.
One ship, compiled (sim.compiled).
"""
from __future__ import annotations

import math
from typing import NamedTuple

from touchdown.sim.compiled import kernel, separate
from touchdown.sim.vec import fmax, fmin


def _factorial(k: int) -> float:
    return float(math.factorial(k))


# Taylor coefficients in the halved argument: e^{-y} for 0 <= y <= 1/2, and cos u, sin(u)/u in
# z = -u^2 for |z| <= 1/2; the first term left out is below 1e-17 of the sum there.
_EXP = tuple((-1.0) ** k / _factorial(k) for k in range(17))
_COS = tuple(1.0 / _factorial(2 * k) for k in range(10))
_SINC = tuple(1.0 / _factorial(2 * k + 1) for k in range(10))
_HALF_RANGE = 0.5
#: fixed bound on argument halvings: 2^60 covers any finite e^{-s t} and b t of a step
MAX_HALVINGS = 60
#: fixed bound on root-finding iterations; each one at least halves the bracket, so 64 would reach
#: any double, and Newton converges in about six for the roots met here
MAX_ROOT_ITERATIONS = 64
#: most sub-intervals a step is scanned in for the first sign change of an event function
MAX_SCAN_POINTS = 16
_EPS = 2.220446049250313e-16  # the double's machine epsilon
_TWO_PI = 2.0 * 3.141592653589793


@kernel
def _horner(coeffs, x):
    """sum_k coeffs[k] x^k, by Horner's rule from the highest term."""
    n = len(coeffs)
    acc = coeffs[n - 1]
    for k in range(n - 2, -1, -1):
        acc = acc * x + coeffs[k]
    return acc


@kernel
def decay_cos_sinc(s, b2, t):
    """(e^{-s t}, Cb(t), Sb(t)) for s >= 0, any real b^2 = w2 - s^2 and t >= 0.

    t is halved k times (k the fewest that bring s t and |b^2| t^2 within 1/2, at most
    MAX_HALVINGS), the series are summed there, and the results doubled k times. (sim.vec's
    cos_sinc, for attitudes, takes a real angle only; here b^2 may be negative, an overdamped
    contact, and the decay e^{-s t} comes with it.)"""
    y = s * t
    z = -b2 * t * t
    k = 0
    for _ in range(MAX_HALVINGS):
        if not (y > _HALF_RANGE or abs(z) > _HALF_RANGE):
            break
        y = 0.5 * y
        z = 0.25 * z
        k += 1
    e = _horner(_EXP, y)
    c = _horner(_COS, z)
    sinc = _horner(_SINC, z)
    sb = t * math.ldexp(1.0, -k) * sinc  # Sb(t_k) = t_k sinc, t_k = t / 2^k
    for _ in range(k):
        e = e * e
        sb = 2.0 * sb * c
        c = 2.0 * c * c - 1.0
    return e, c, sb


class Flow(NamedTuple):
    """x'' + c1 x' + w2 x = b0 + b1 t from (x0, v0) at t = 0; w2 = 0 means ballistic (then c1
    and b1 must be 0)."""

    w2: float  # 1/s^2
    c1: float  # 1/s
    b0: float  # m/s^2
    b1: float  # m/s^3
    x0: float  # m
    v0: float  # m/s


@kernel
def flow_at(flow, t):
    """(x, x', x'') at time t."""
    x = flow.x0 + t * (flow.v0 + 0.5 * flow.b0 * t)
    v = flow.v0 + flow.b0 * t
    if flow.w2 > 0.0:
        w2 = flow.w2
        p1 = flow.b1 / w2
        p0 = (flow.b0 - flow.c1 * p1) / w2
        s = 0.5 * flow.c1
        z0 = flow.x0 - p0
        zd0 = flow.v0 - p1
        e, c, sb = decay_cos_sinc(s, w2 - s * s, t)
        z = e * (c * z0 + sb * (zd0 + s * z0))
        zd = e * (c * zd0 - sb * (w2 * z0 + s * zd0))
        x = p0 + p1 * t + z
        v = p1 + zd
    a = flow.b0 + flow.b1 * t - flow.c1 * v - flow.w2 * x
    return x, v, a


@kernel
def flow_start(flow):
    """(x, x', x'') at t = 0, without evaluating the solution."""
    return flow.x0, flow.v0, flow.b0 - flow.c1 * flow.v0 - flow.w2 * flow.x0


class Functional(NamedTuple):
    """g(t) = cx x(t) + cv x'(t) + ca x''(t) + c0 + ct t along a flow: a force, a height or a
    speed whose zero is an event (separation, maximum compression)."""

    cx: float
    cv: float
    ca: float
    c0: float
    ct: float


@kernel
def value_and_rate(g, flow, t, x, v, a):
    """g(t) and g'(t), given (x, x', x'') at t."""
    jerk = flow.b1 - flow.c1 * a - flow.w2 * v  # d/dt of x''
    value = g.cx * x + g.cv * v + g.ca * a + g.c0 + g.ct * t
    rate = g.cx * v + g.cv * a + g.ca * jerk + g.ct
    return value, rate


@kernel
def value_and_rate_at(g, flow, t):
    """g(t) and g'(t)."""
    x, v, a = flow_at(flow, t)
    return value_and_rate(g, flow, t, x, v, a)


@kernel
def scan(flow, t_end):
    """(points, horizon): scan (0, horizon] in ``points`` equal sub-intervals for an event's first
    sign change. The first zero of a damped oscillation plus a constant comes within one period
    of the motion (2 pi / b underdamped; 2 pi / (w / 2) otherwise, the slowest an extremum can
    come), so the horizon is the step or that period, whichever is shorter, and each sub-interval
    a quarter period at most: 1 to MAX_SCAN_POINTS points. Ballistic (w2 = 0): one."""
    s = 0.5 * flow.c1
    w_scale2 = fmax(flow.w2 - s * s, 0.25 * flow.w2)
    if not w_scale2 > 0.0:
        return 1, t_end
    period = _TWO_PI / math.sqrt(w_scale2)
    horizon = period if period < t_end else t_end
    n = fmin(fmax(float(math.ceil(4.0 * horizon / period)), 1.0), float(MAX_SCAN_POINTS))
    return int(n), horizon


@separate
def first_crossing(flow, g, t_end, g_start, g_end):
    """The first scanned sub-interval (:func:`scan`) over which g changes sign:
    (crossed, t_lo, t_hi, g_lo, g_hi). ``g_start`` and ``g_end`` are g at 0 and at t_end; the scan
    evaluates only the points in between (none when one interval covers the step)."""
    points, horizon = scan(flow, t_end)
    prev_t, prev_g = 0.0, g_start
    for j in range(1, points + 1):
        at_end = j == points and horizon == t_end
        if at_end:
            t_j, g_j = t_end, g_end
        else:
            t_j = horizon * (j / points)
            g_j = value_and_rate_at(g, flow, t_j)[0]
        if (prev_g > 0.0 and g_j < 0.0) or (prev_g < 0.0 and g_j > 0.0):
            return True, prev_t, t_j, prev_g, g_j
        prev_t, prev_g = t_j, g_j
    return False, 0.0, t_end, g_start, g_end


@separate
def bracketed_root(flow, g, t_lo, t_hi, g_lo, g_hi):
    """The root of g in (t_lo, t_hi), where g changes sign (g_lo = g(t_lo), g_hi = g(t_hi) of
    opposite signs). Safeguarded Newton: a Newton step that leaves the bracket is replaced by
    bisection, the bracket shrinks every iteration, and the search stops once its step has fallen
    to a few ulps (at most MAX_ROOT_ITERATIONS)."""
    lo, hi = t_lo, t_hi
    rising = g_hi > g_lo
    t = t_lo + (t_hi - t_lo) * (g_lo / (g_lo - g_hi))  # regula falsi start
    if not (t > lo and t < hi):
        t = 0.5 * (lo + hi)
    for _ in range(MAX_ROOT_ITERATIONS):
        val, rate = value_and_rate_at(g, flow, t)
        below = val < 0.0 if rising else val > 0.0  # the root lies after t
        if below:
            lo = t
        else:
            hi = t
        newton = t - val / (rate if rate != 0.0 else 1.0)
        inside = rate != 0.0 and newton > lo and newton < hi
        t_new = newton if inside else 0.5 * (lo + hi)
        step_small = abs(t_new - t) <= 4.0 * _EPS * hi
        if val == 0.0:
            break
        t = t_new
        if step_small or hi - lo <= 4.0 * _EPS * hi:
            break
    return t
