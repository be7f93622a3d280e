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
(e^{2y} = (e^y)^2, cos 2u = 2 cos^2 u - 1, sin 2u / 2u = (sin u / u) cos u). numpy's vectorised
exp/sin/cos take other code paths on other SIMD widths, and even between the body and the tail of
one array; these polynomials give every ship the same bits wherever it sits in a batch.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

Array = np.ndarray

# Taylor coefficients in the halved argument: e^{-y} for 0 <= y <= 1/2, and cos u, sin(u)/u in
# z = -u^2 for |z| <= 1/2; the first term left out is below 1e-17 of the sum there.
_EXP = tuple((-1.0) ** k / float(np.prod(np.arange(1, k + 1))) for k in range(17))
_COS = tuple(1.0 / float(np.prod(np.arange(1, 2 * k + 1))) for k in range(10))
_SINC = tuple(1.0 / float(np.prod(np.arange(1, 2 * k + 2))) for k in range(10))
_HALF_RANGE = 0.5
#: fixed bound on argument halvings: 2^60 covers any finite e^{-s t} and b t of a step
MAX_HALVINGS = 60
#: fixed bound on root-finding iterations; each one at least halves the bracket, so 64 would reach
#: any double, and Newton converges in about six for the roots met here
MAX_ROOT_ITERATIONS = 64


def _horner(coeffs: tuple[float, ...], x: Array) -> Array:
    acc = np.full(x.shape, coeffs[-1])
    for c in coeffs[-2::-1]:
        acc = acc * x + c
    return acc


def decay_cos_sinc(s: Array, b2: Array, t: Array) -> tuple[Array, Array, Array]:
    """(e^{-s t}, Cb(t), Sb(t)) for s >= 0, any real b^2 = w2 - s^2 and t >= 0, elementwise.

    t is halved k times (k the fewest that bring s t and |b^2| t^2 within 1/2, at most
    MAX_HALVINGS), the series are summed there, and the results doubled k times. (sim.vec's
    cos_sinc, for attitudes, takes a real angle only; here b^2 may be negative, an overdamped
    contact, and the decay e^{-s t} comes with it.)"""
    t = np.asarray(t, dtype=float)
    y = s * t
    z = -b2 * t * t
    k = np.zeros(y.shape, dtype=np.int64)
    for _ in range(MAX_HALVINGS):
        big = (y > _HALF_RANGE) | (np.abs(z) > _HALF_RANGE)
        if not big.any():
            break
        y = np.where(big, 0.5 * y, y)
        z = np.where(big, 0.25 * z, z)
        k += big
    e = _horner(_EXP, y)
    c = _horner(_COS, z)
    sinc = _horner(_SINC, z)
    # Sb(t_k) = t_k sinc, t_k = t / 2^k
    scale = np.ldexp(np.ones(y.shape), -k)
    sb = t * scale * sinc
    for i in range(int(k.max()) if k.size else 0):
        more = k > i
        e = np.where(more, e * e, e)
        sb = np.where(more, 2.0 * sb * c, sb)
        c = np.where(more, 2.0 * c * c - 1.0, c)
    return e, c, sb


@dataclass(frozen=True)
class Flow:
    """x'' + c1 x' + w2 x = b0 + b1 t from (x0, v0) at t = 0, per ship; w2 = 0 means ballistic
    (then c1 and b1 must be 0). Arrays of shape (N,)."""

    w2: Array  # 1/s^2
    c1: Array  # 1/s
    b0: Array  # m/s^2
    b1: Array  # m/s^3
    x0: Array  # m
    v0: Array  # m/s

    def at(self, t: Array | float) -> tuple[Array, Array, Array]:
        """(x, x', x'') at time t (a number or one per ship)."""
        t = np.broadcast_to(np.asarray(t, dtype=float), self.w2.shape)
        pressing = self.w2 > 0.0
        x = self.x0 + t * (self.v0 + 0.5 * self.b0 * t)
        v = self.v0 + self.b0 * t
        if pressing.any():
            w2 = np.where(pressing, self.w2, 1.0)
            p1 = self.b1 / w2
            p0 = (self.b0 - self.c1 * p1) / w2
            s = 0.5 * self.c1
            z0 = self.x0 - p0
            zd0 = self.v0 - p1
            e, c, sb = decay_cos_sinc(s, w2 - s * s, np.where(pressing, t, 0.0))
            z = e * (c * z0 + sb * (zd0 + s * z0))
            zd = e * (c * zd0 - sb * (w2 * z0 + s * zd0))
            x = np.where(pressing, p0 + p1 * t + z, x)
            v = np.where(pressing, p1 + zd, v)
        a = self.b0 + self.b1 * t - self.c1 * v - self.w2 * x
        return x, v, a

    def start(self) -> tuple[Array, Array, Array]:
        """(x, x', x'') at t = 0, without evaluating the solution."""
        return self.x0, self.v0, self.b0 - self.c1 * self.v0 - self.w2 * self.x0

    def take(self, idx: Array) -> "Flow":
        return Flow(*(getattr(self, f)[idx] for f in ("w2", "c1", "b0", "b1", "x0", "v0")))


@dataclass(frozen=True)
class Functional:
    """g(t) = cx x(t) + cv x'(t) + ca x''(t) + c0 + ct t along a flow: a force, a height or a
    speed whose zero is an event (separation, maximum compression). Coefficients are (N,) or
    numbers."""

    cx: Array | float = 0.0
    cv: Array | float = 0.0
    ca: Array | float = 0.0
    c0: Array | float = 0.0
    ct: Array | float = 0.0

    def value_and_rate(self, flow: Flow, t: Array,
                       xva: tuple[Array, Array, Array] | None = None) -> tuple[Array, Array]:
        """g(t) and g'(t); ``xva`` is (x, x', x'') at t when already known."""
        x, v, a = flow.at(t) if xva is None else xva
        jerk = flow.b1 - flow.c1 * a - flow.w2 * v  # d/dt of x''
        g = self.cx * x + self.cv * v + self.ca * a + self.c0 + self.ct * t
        dg = self.cx * v + self.cv * a + self.ca * jerk + self.ct
        return g, dg

    def take(self, idx: Array) -> "Functional":
        def pick(c):
            return c[idx] if np.ndim(c) else c
        return Functional(pick(self.cx), pick(self.cv), pick(self.ca), pick(self.c0), pick(self.ct))


#: most sub-intervals a step is scanned in for the first sign change of an event function
MAX_SCAN_POINTS = 16


def scan(flow: Flow, t_end: Array) -> tuple[Array, Array]:
    """(points, horizon): scan (0, horizon] in ``points`` equal sub-intervals for an event's first
    sign change. The first zero of a damped oscillation plus a constant comes within one period
    of the motion (2 pi / b underdamped; 2 pi / (w / 2) otherwise, the slowest an extremum can
    come), so the horizon is the step or that period, whichever is shorter, and each sub-interval
    a quarter period at most: 1 to MAX_SCAN_POINTS points. Ballistic ships (w2 = 0): one. A
    ship's scan depends on its own step and stiffness alone."""
    s = 0.5 * flow.c1
    w_scale2 = np.maximum(flow.w2 - s * s, 0.25 * flow.w2)
    oscillates = w_scale2 > 0.0
    period = 2.0 * np.pi / np.sqrt(np.where(oscillates, w_scale2, 1.0))
    horizon = np.where(oscillates & (period < t_end), period, t_end)
    n = np.where(oscillates, np.clip(np.ceil(4.0 * horizon / period), 1, MAX_SCAN_POINTS), 1)
    return n.astype(np.int64), horizon


def first_crossing(flow: Flow, g: Functional, t_end: Array, g_start: Array, g_end: Array
                   ) -> tuple[Array, Array, Array, Array, Array]:
    """The first scanned sub-interval (:func:`scan`) over which g changes sign:
    (crossed, t_lo, t_hi, g_lo, g_hi). ``g_start`` and ``g_end`` are g at 0 and at t_end; the scan
    evaluates only the points in between (none when one interval covers the step)."""
    points, horizon = scan(flow, t_end)
    n = g_start.shape[0]
    crossed = np.zeros(n, dtype=bool)
    t_lo, g_lo = np.zeros(n), g_start.copy()
    t_hi, g_hi = t_end.copy(), g_end.copy()
    prev_t, prev_g = np.zeros(n), g_start.copy()
    for j in range(1, int(points.max()) + 1 if n else 1):
        live = ~crossed & (j <= points)
        if not live.any():
            break
        idx = np.flatnonzero(live)
        at_end = (j == points[idx]) & (horizon[idx] == t_end[idx])
        t_j = np.where(at_end, t_end[idx], horizon[idx] * (j / points[idx]))
        g_j = np.where(at_end, g_end[idx], 0.0)
        inner = np.flatnonzero(~at_end)
        if inner.size:
            sub = idx[inner]
            g_j[inner], _ = g.take(sub).value_and_rate(flow.take(sub), t_j[inner])
        change = ((prev_g[idx] > 0.0) & (g_j < 0.0)) | ((prev_g[idx] < 0.0) & (g_j > 0.0))
        hit = idx[change]
        t_lo[hit], g_lo[hit] = prev_t[hit], prev_g[hit]
        t_hi[hit], g_hi[hit] = t_j[change], g_j[change]
        crossed[hit] = True
        prev_t[idx], prev_g[idx] = t_j, g_j
    return crossed, t_lo, t_hi, g_lo, g_hi


def bracketed_root(flow: Flow, g: Functional, t_lo: Array, t_hi: Array, g_lo: Array,
                   g_hi: Array) -> Array:
    """The root of g in (t_lo, t_hi) for ships whose g changes sign there (g_lo = g(t_lo), g_hi =
    g(t_hi) of opposite signs). Safeguarded Newton: a Newton step that leaves the bracket is
    replaced by bisection, the bracket shrinks every iteration, and a ship whose step has fallen
    to a few ulps is frozen, so its answer never depends on how long its neighbours take."""
    lo = t_lo.copy()
    hi = t_hi.copy()
    rising = g_hi > g_lo
    t = t_lo + (t_hi - t_lo) * (g_lo / (g_lo - g_hi))  # regula falsi start
    t = np.where((t > lo) & (t < hi), t, 0.5 * (lo + hi))
    done = np.zeros(t.shape, dtype=bool)
    eps = np.finfo(float).eps
    for _ in range(MAX_ROOT_ITERATIONS):
        val, rate = g.value_and_rate(flow, t)
        below = np.where(rising, val < 0.0, val > 0.0)  # the root lies after t
        lo = np.where(done, lo, np.where(below, t, lo))
        hi = np.where(done, hi, np.where(below, hi, t))
        safe_rate = np.where(rate != 0.0, rate, 1.0)
        newton = t - val / safe_rate
        inside = (rate != 0.0) & (newton > lo) & (newton < hi)
        t_new = np.where(inside, newton, 0.5 * (lo + hi))
        step_small = np.abs(t_new - t) <= 4.0 * eps * hi
        exact = val == 0.0
        t = np.where(done | exact, t, t_new)
        done = done | exact | step_small | (hi - lo <= 4.0 * eps * hi)
        if done.all():
            break
    return t
