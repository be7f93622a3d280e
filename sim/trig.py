"""Trigonometry from IEEE-754 +, -, *, / and sqrt alone: the same bits on every machine.

libm's cos, sin, tan, acos and pow are not correctly rounded, and glibc picks among its own
implementations by CPU: with fused multiply-adds on AVX2 machines, without on older ones. Of
400,000 random arguments (glibc 2.36, this project's machines), cos differs between the two in 254,
sin in 279, acos in 101, pow(x, 2) in 299; another system's libm differs more. Whatever reaches a
run's bits comes from here instead: the body's turn at each tick (sim.frames.body_rotation), the
ground's slope, the ships' starting attitudes, the thresholds' cosines (sim.params,
sim.placement), an event's tilt (sim.vec.angle_between). A square is ``x * x``, never ``x ** 2``
(Python's power is libm's pow).

Plain Python on floats: each operation rounds once, as in the compiled kernels (compiled without
fastmath, so nothing is fused: sim.compiled), and sim.vec compiles these same functions
(:func:`cos_sinc`, :func:`angle`) for them. No numba here: ``export`` uses this module without
loading the compiler (logs.derived).
"""
from __future__ import annotations

import math

# Taylor coefficients of cos(x) and sin(x)/x in x^2 to degree 14 in x: the first term left out is
# 1e-15 at pi/4 and below 1e-29 at 0.1 rad, the step's angles (a sub-step's turn); argument
# halving extends the range. :func:`cos_sin` sums its own longer series.
_COS = (1.0, -1.0 / 2, 1.0 / 24, -1.0 / 720, 1.0 / 40320, -1.0 / 3628800, 1.0 / 479001600,
        -1.0 / 87178291200)
_SINC = (1.0, -1.0 / 6, 1.0 / 120, -1.0 / 5040, 1.0 / 362880, -1.0 / 39916800, 1.0 / 6227020800,
         -1.0 / 1307674368000)
#: fixed bound: 2^60 rad covers any finite rotation a tick can produce
MAX_HALVINGS = 60
#: rad, 2^-27: below it cos x and sin(x)/x are 1.0 to the last bit (x^2 / 2 < 2^-55), which
#: :func:`cos_sinc` returns without summing its series
TINY_ANGLE = 2.0 ** -27


def cos_sinc(x):
    """(cos x, sin(x)/x) from polynomials and double-angle steps: IEEE +, * only."""
    if x == 0.0:
        # what the series give there, exactly (each Horner step c y2 + k is k at y2 = 0, down to
        # the constant terms 1 and 1): the turn about a long axis a ship does not spin about
        # (sim.rotation.axis_flow at theta = 0, every step of a ship that only rocks or bounces)
        return 1.0, 1.0
    if abs(x) < TINY_ANGLE:
        # what the series give there too, exactly: in the last Horner step c1 y2 + 1 (c1 = -1/2
        # + y2 / 24 - ..., -1/6 + ... for sin(x)/x) the term c1 y2 is under 2^-55 and rounds away
        # (a rounding-level spin's turn, ~1e-10 rad a step: a bouncing upright ship's)
        return 1.0, 1.0
    x = abs(x)
    halvings = 0
    y = x
    for _ in range(MAX_HALVINGS):
        if not y > 0.785:
            break
        y = y * 0.5
        halvings += 1
    y2 = y * y
    c = _COS[7]
    s = _SINC[7]
    for k in range(6, -1, -1):
        c = c * y2 + _COS[k]
        s = s * y2 + _SINC[k]
    sin = s * y
    for _ in range(halvings):
        sin_new = 2.0 * sin * c
        c = c * c - sin * sin
        sin = sin_new
    if halvings > 0:
        return c, sin / (x if x > 0.0 else 1.0)
    return c, s


#: atan(z) = sum (-1)^k z^(2k+1) / (2k+1), for |z| <= tan(pi/32) ~ 0.0985 after three halvings:
#: the first term left out (z^19 / 19) is below 1e-20.
ATAN_TERMS = (1.0, -1.0 / 3, 1.0 / 5, -1.0 / 7, 1.0 / 9, -1.0 / 11, 1.0 / 13, -1.0 / 15, 1.0 / 17)
PI = 3.141592653589793


def angle(y, x):
    """atan2(y, x) for y >= 0, in [0, pi], from +,*,/ and sqrt only: the half-angle identity
    atan2(y, x) = 2 atan(y / (r + x)) (r = hypot(x, y); mirrored for x < 0), then
    atan(z) = 2 atan(z / (1 + sqrt(1 + z^2))) three times, then the series."""
    r = math.sqrt(x * x + y * y)
    denom = r + abs(x)
    z = y / denom if denom > 0.0 else 0.0
    for _ in range(3):
        z = z / (1.0 + math.sqrt(1.0 + z * z))
    z2 = z * z
    acc = ATAN_TERMS[8]
    for k in range(7, -1, -1):
        acc = acc * z2 + ATAN_TERMS[k]
    half_turn = 16.0 * z * acc  # 2 (half-angle) * 8 (three halvings) * atan(z)
    return PI - half_turn if x < 0.0 else half_turn


# pi/2 in four parts (fdlibm's pio2_1, pio2_2, pio2_3 of 33 bits each and the rest, pio2_3t), so
# that k times each of the first three is exact for |k| < 2^20 (|x| < 1.6e6 rad) and x - k pi/2
# is found to ~1e-47 rad, far below an ulp of the rest even beside a multiple of pi/2 (Cody and
# Waite's reduction)
_PIO2_1 = 1.57079632673412561417e+00
_PIO2_2 = 6.07710050630396597660e-11
_PIO2_3 = 2.02226624871116645580e-21
_PIO2_3T = 8.47842766036889956997e-32
_TWO_OVER_PI = 6.36619772367581382433e-01
#: cos r and sin(r)/r in r^2 to degree 20 in r, whose first term left out is below 3e-21 at
#: pi/4: the whole range after the reduction, to the last bit but rounding (cos_sinc's series,
#: for the step's small angles, stops at degree 14, 1e-15 at pi/4)
_COS_R = tuple((-1.0) ** k / math.factorial(2 * k) for k in range(11))
_SINC_R = tuple((-1.0) ** k / math.factorial(2 * k + 1) for k in range(11))


def cos_sin(x: float) -> tuple[float, float]:
    """(cos x, sin x): x less its nearest multiple of pi/2, k pi/2 (exactly as above for
    |x| < 1.6e6 rad; beyond, the same bits on every machine but less accurate), then the
    series of the rest (|r| <= pi/4) and the quadrant k mod 4. Within 3 ulp of libm's to 1e6 rad
    (tests/test_portable.py)."""
    if x == 0.0:
        return 1.0, x  # sin(-0) = -0
    if not math.isfinite(x):
        return math.nan, math.nan
    k = math.floor(x * _TWO_OVER_PI + 0.5)
    r = (((x - k * _PIO2_1) - k * _PIO2_2) - k * _PIO2_3) - k * _PIO2_3T
    r2 = r * r
    c, sinc = _COS_R[10], _SINC_R[10]
    for j in range(9, -1, -1):
        c = c * r2 + _COS_R[j]
        sinc = sinc * r2 + _SINC_R[j]
    s = r * sinc
    quadrant = k % 4
    if quadrant == 0:
        return c, s
    if quadrant == 1:
        return -s, c
    if quadrant == 2:
        return -c, -s
    return s, -c


def acos(c: float) -> float:
    """acos c, c clipped to [-1, 1] (NaN stays NaN): :func:`angle` of (sqrt((1 - c)(1 + c)), c).
    1 - c is exact near 1 (Sterbenz), so the angle keeps its digits there, within 2e-14 deg of
    libm's everywhere (tests/test_export_numpy.py). logs.derived.tilt_deg spells it for
    columns."""
    if c != c:
        return c
    c = min(1.0, max(-1.0, c))
    return angle(math.sqrt((1.0 - c) * (1.0 + c)), c)


def cos(x: float) -> float:
    return cos_sin(x)[0]


def sin(x: float) -> float:
    return cos_sin(x)[1]


def tan(x: float) -> float:
    c, s = cos_sin(x)
    return s / c
