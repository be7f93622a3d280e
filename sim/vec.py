"""Vector and quaternion arithmetic for one ship, compiled (sim.compiled).

Vectors are tuples ``(x, y, z)``, quaternions ``(w, x, y, z)`` rotating body-frame vectors into
the inertial frame. Each function is a fixed sequence of IEEE-754 add, multiply, divide and sqrt,
written component by component, so a result is the same bits on every machine, whatever ship
sits beside it. Transcendental functions come from polynomials on a halved argument (``cos_sinc``,
``angle``), never from libm, whose implementations differ between machines.
"""
from __future__ import annotations

import math

from touchdown.sim.compiled import kernel

Vec = tuple[float, float, float]
Quat = tuple[float, float, float, float]

@kernel
def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@kernel
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@kernel
def scale(a, s):
    """a * s for a vector and a number."""
    return (a[0] * s, a[1] * s, a[2] * s)


@kernel
def mul(a, b):
    """Elementwise a * b (a principal inertia times a body-frame rate)."""
    return (a[0] * b[0], a[1] * b[1], a[2] * b[2])


@kernel
def div(a, b):
    """Elementwise a / b."""
    return (a[0] / b[0], a[1] / b[1], a[2] / b[2])


@kernel
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@kernel
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@kernel
def norm(a):
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@kernel
def unit(a):
    """a / |a|; a zero vector stays zero."""
    n = norm(a)
    safe = n if n > 0.0 else 1.0
    return (a[0] / safe, a[1] / safe, a[2] / safe)


@kernel
def fmax(a, b):
    """numpy's maximum: a unless b is larger (a NaN in a is kept)."""
    return a if (a >= b or a != a) else b


@kernel
def fmin(a, b):
    """numpy's minimum."""
    return a if (a <= b or a != a) else b


# -- quaternions ---------------------------------------------------------------------------------
@kernel
def quat_rotate(q, v):
    """Rotate a body vector v into the inertial frame: v + 2 w (u x v) + 2 u x (u x v),
    u = (x, y, z), the expanded form of q v q*."""
    u = (q[1], q[2], q[3])
    t = cross(u, v)
    t = (t[0] + t[0], t[1] + t[1], t[2] + t[2])
    c = cross(u, t)
    return (v[0] + t[0] * q[0] + c[0], v[1] + t[1] * q[0] + c[1], v[2] + t[2] * q[0] + c[2])


@kernel
def quat_rotate_inv(q, v):
    """Rotate an inertial vector into the body frame (by the conjugate of q)."""
    return quat_rotate((q[0], -q[1], -q[2], -q[3]), v)


@kernel
def positive_zero(x):
    """x is +0.0 (not -0.0)."""
    return x == 0.0 and math.copysign(1.0, x) > 0.0


@kernel
def quat_rotate_inv_of(q, v):
    """:func:`quat_rotate_inv`, for v = (+0.0, +0.0, +0.0) (a ship clear of the ground's contact
    torque, a body that does not spin) without its products: each component it gives is then
    (+0 + t q_w) + c with t and c sums of signed zeros for a finite q, and +0 + (+-0) is +0 under
    round to nearest, so it gives (+0, +0, +0); for a q with an infinite or nan component, nan
    in every component (inf * 0), as (q - q) sums it here (tests/test_rotation_tiny.py)."""
    if positive_zero(v[0]) and positive_zero(v[1]) and positive_zero(v[2]):
        z = ((q[0] - q[0]) + (q[1] - q[1])) + ((q[2] - q[2]) + (q[3] - q[3]))
        return (z, z, z)
    return quat_rotate_inv(q, v)


@kernel
def quat_axis_z(q):
    """The body z axis (the long axis) in the inertial frame: q (0,0,1) q*."""
    w, x, y, z = q
    return (2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y))


@kernel
def body_axes(q):
    """The body x, y, z axes in the inertial frame: the columns of the rotation matrix of q."""
    w, x, y, z = q
    ex = (1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y))
    ey = (2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x))
    ez = (2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y))
    return ex, ey, ez


@kernel
def quat_mul(a, b):
    """Hamilton product a (x) b."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


@kernel
def quat_normalize(q):
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


@kernel
def quat_derivative(q, omega_body):
    """dq/dt = 1/2 q (x) (0, omega_body): attitude kinematics with body-frame angular velocity."""
    d = quat_mul(q, (0.0, omega_body[0], omega_body[1], omega_body[2]))
    return (0.5 * d[0], 0.5 * d[1], 0.5 * d[2], 0.5 * d[3])


@kernel
def quat_add_scaled(q, d, h):
    """q + h d, component by component."""
    return (q[0] + h * d[0], q[1] + h * d[1], q[2] + h * d[2], q[3] + h * d[3])


# Taylor coefficients of cos(x) and sin(x)/x in x^2, enough terms for |x| <= pi/4 to full double
# precision (the next term is below 1e-17 there). Argument halving extends the range.
_COS = (1.0, -1.0 / 2, 1.0 / 24, -1.0 / 720, 1.0 / 40320, -1.0 / 3628800, 1.0 / 479001600,
        -1.0 / 87178291200)
_SINC = (1.0, -1.0 / 6, 1.0 / 120, -1.0 / 5040, 1.0 / 362880, -1.0 / 39916800, 1.0 / 6227020800,
         -1.0 / 1307674368000)
#: fixed bound: 2^60 rad covers any finite rotation a tick can produce
MAX_HALVINGS = 60
#: rad, 2^-27: below it cos x and sin(x)/x are 1.0 to the last bit (x^2 / 2 < 2^-55), which
#: :func:`cos_sinc` returns without summing its series
TINY_ANGLE = 2.0 ** -27


@kernel
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


@kernel
def quat_from_rotvec(phi):
    """Unit quaternion of the rotation vector phi: (cos |phi|/2, sin(|phi|/2) phi/|phi|)."""
    half = 0.5 * norm(phi)
    c, sinc = cos_sinc(half)
    k = 0.5 * sinc
    return (c, phi[0] * k, phi[1] * k, phi[2] * k)


@kernel
def quat_integrate(q, omega_body, dt):
    """q(t+dt) for constant body-frame angular velocity: q (x) exp(omega dt / 2)."""
    return quat_normalize(quat_mul(q, quat_from_rotvec(scale(omega_body, dt))))


#: atan(z) = sum (-1)^k z^(2k+1) / (2k+1), for |z| <= tan(pi/32) ~ 0.0985 after three halvings:
#: the first term left out (z^19 / 19) is below 1e-20.
_ATAN = (1.0, -1.0 / 3, 1.0 / 5, -1.0 / 7, 1.0 / 9, -1.0 / 11, 1.0 / 13, -1.0 / 15, 1.0 / 17)
PI = 3.141592653589793


@kernel
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
    acc = _ATAN[8]
    for k in range(7, -1, -1):
        acc = acc * z2 + _ATAN[k]
    half_turn = 16.0 * z * acc  # 2 (half-angle) * 8 (three halvings) * atan(z)
    return PI - half_turn if x < 0.0 else half_turn
