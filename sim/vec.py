"""Vector and quaternion arithmetic for one ship, compiled (sim.compiled).

Vectors are tuples ``(x, y, z)``, quaternions ``(w, x, y, z)`` rotating body-frame vectors into
the inertial frame. Each function is a fixed sequence of IEEE-754 add, multiply, divide and sqrt,
written component by component, so a result is the same bits on every machine, whatever ship
sits beside it. Transcendental functions come from polynomials on a halved argument (``cos_sinc``,
``angle``), never from libm, whose implementations differ between machines.
"""
from __future__ import annotations

import math

from touchdown.sim import trig
from touchdown.sim.compiled import kernel
from touchdown.sim.trig import MAX_HALVINGS, TINY_ANGLE  # noqa: F401 (sim.rotation's)

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


cos_sinc = kernel(trig.cos_sinc)


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


angle = kernel(trig.angle)


@kernel
def angle_between(a, b):
    """The angle between a and b, in [0, pi]: atan2(|a x b|, a . b) by :func:`angle`, accurate
    at every angle (acos(a . b) loses half the digits near 0 and pi) and free of libm."""
    return angle(norm(cross(a, b)), dot(a, b))
