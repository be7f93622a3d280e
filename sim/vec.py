"""Vector and quaternion arithmetic on batches, written component by component.

Every function takes arrays whose leading axis is the ship batch: vectors are ``(N, 3)``,
quaternions ``(N, 4)`` as ``(w, x, y, z)`` rotating body-frame vectors into the inertial frame.

Why not ``np.cross``/``np.linalg.norm``/``@``: those may reduce through BLAS or SIMD paths whose
summation order (and use of fused multiply-add) differs between machines and batch sizes. Here
each result element is a fixed sequence of IEEE-754 add, multiply, divide and sqrt on that
ship's own numbers, so a ship's result never depends on its neighbours or on the CPU's SIMD width.
"""
from __future__ import annotations

import numpy as np

Array = np.ndarray


def dot(a: Array, b: Array) -> Array:
    """a . b for (N,3) arrays -> (N,)."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def cross(a: Array, b: Array) -> Array:
    """a x b for (N,3) arrays -> (N,3)."""
    out = np.empty(a.shape if a.shape == b.shape else np.broadcast_shapes(a.shape, b.shape))
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def norm(a: Array) -> Array:
    """|a| for (N,3) -> (N,)."""
    return np.sqrt(dot(a, a))


def scale(a: Array, s: Array) -> Array:
    """a * s for (N,3) and (N,) -> (N,3)."""
    return a * s[:, None]


def unit(a: Array) -> Array:
    """a / |a|; zero vectors stay zero."""
    n = norm(a)
    safe = np.where(n > 0.0, n, 1.0)
    return a / safe[:, None]


def quat_rotate(q: Array, v: Array) -> Array:
    """Rotate body vectors v (N,3) into the inertial frame by unit quaternions q (N,4).

    v' = v + 2 w (u x v) + 2 u x (u x v), u = (x, y, z): the expanded form of q v q*.
    """
    u = q[:, 1:]
    t = cross(u, v)
    t = t + t
    return v + scale(t, q[:, 0]) + cross(u, t)


def quat_axis_z(q: Array) -> Array:
    """The body z axis (the long axis) in the inertial frame: q (0,0,1) q*."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    out = np.empty((q.shape[0], 3))
    out[:, 0] = 2.0 * (x * z + w * y)
    out[:, 1] = 2.0 * (y * z - w * x)
    out[:, 2] = 1.0 - 2.0 * (x * x + y * y)
    return out


def quat_rotate_inv(q: Array, v: Array) -> Array:
    """Rotate inertial vectors v into the body frame (by the conjugate of q)."""
    qc = q.copy()
    qc[:, 1:] = -qc[:, 1:]
    return quat_rotate(qc, v)


def quat_mul(a: Array, b: Array) -> Array:
    """Hamilton product a (x) b for (N,4) arrays."""
    aw, ax, ay, az = a[:, 0], a[:, 1], a[:, 2], a[:, 3]
    bw, bx, by, bz = b[:, 0], b[:, 1], b[:, 2], b[:, 3]
    out = np.empty(a.shape if a.shape == b.shape else np.broadcast_shapes(a.shape, b.shape))
    out[:, 0] = aw * bw - ax * bx - ay * by - az * bz
    out[:, 1] = aw * bx + ax * bw + ay * bz - az * by
    out[:, 2] = aw * by - ax * bz + ay * bw + az * bx
    out[:, 3] = aw * bz + ax * by - ay * bx + az * bw
    return out


def quat_normalize(q: Array) -> Array:
    n = np.sqrt(q[:, 0] * q[:, 0] + q[:, 1] * q[:, 1] + q[:, 2] * q[:, 2] + q[:, 3] * q[:, 3])
    return q / n[:, None]


def quat_derivative(q: Array, omega_body: Array) -> Array:
    """dq/dt = 1/2 q (x) (0, omega_body): attitude kinematics with body-frame angular velocity."""
    w = np.zeros((q.shape[0], 4))
    w[:, 1:] = omega_body
    return 0.5 * quat_mul(q, w)


# Taylor coefficients of cos(x) and sin(x)/x in x^2, enough terms for |x| <= pi/4 to full double
# precision (the next term is below 1e-17 there). Argument halving extends the range.
_COS = (1.0, -1.0 / 2, 1.0 / 24, -1.0 / 720, 1.0 / 40320, -1.0 / 3628800, 1.0 / 479001600,
        -1.0 / 87178291200)
_SINC = (1.0, -1.0 / 6, 1.0 / 120, -1.0 / 5040, 1.0 / 362880, -1.0 / 39916800, 1.0 / 6227020800,
         -1.0 / 1307674368000)
_MAX_HALVINGS = 60  # fixed bound: 2^60 rad covers any finite rotation a tick can produce


def cos_sinc(x: Array) -> tuple[Array, Array]:
    """(cos x, sin(x)/x) from polynomials and double-angle steps: IEEE +,* only.

    numpy's vectorised sin/cos take different code paths on different SIMD widths; these do not,
    so an attitude update is bit-identical on every machine with IEEE doubles.
    """
    x = np.abs(x)
    halvings = np.zeros(x.shape, dtype=np.int64)
    y = x.copy()
    for _ in range(_MAX_HALVINGS):
        big = y > 0.785
        if not big.any():
            break
        y = np.where(big, y * 0.5, y)
        halvings += big
    y2 = y * y
    c = np.full(y.shape, _COS[-1])
    s = np.full(y.shape, _SINC[-1])
    for k in range(len(_COS) - 2, -1, -1):
        c = c * y2 + _COS[k]
        s = s * y2 + _SINC[k]
    sin = s * y
    for i in range(int(halvings.max()) if halvings.size else 0):
        more = halvings > i
        sin_new = 2.0 * sin * c
        c_new = c * c - sin * sin
        sin = np.where(more, sin_new, sin)
        c = np.where(more, c_new, c)
    safe_x = np.where(x > 0.0, x, 1.0)
    sinc = np.where(halvings > 0, sin / safe_x, s)
    return c, sinc


def quat_from_rotvec(phi: Array) -> Array:
    """Unit quaternion of the rotation vector phi (N,3): (cos |phi|/2, sin(|phi|/2) phi/|phi|)."""
    half = 0.5 * norm(phi)
    c, sinc = cos_sinc(half)
    q = np.empty((phi.shape[0], 4))
    q[:, 0] = c
    q[:, 1:] = phi * (0.5 * sinc)[:, None]
    return q


def quat_integrate(q: Array, omega_body: Array, dt: float | Array) -> Array:
    """q(t+dt) for constant body-frame angular velocity: q (x) exp(omega dt / 2)."""
    dt_arr = np.asarray(dt, dtype=float)
    phi = omega_body * (dt_arr[:, None] if dt_arr.ndim else dt)
    return quat_normalize(quat_mul(q, quat_from_rotvec(phi)))


#: atan(z) = sum (-1)^k z^(2k+1) / (2k+1), for |z| <= tan(pi/32) ~ 0.0985 after three halvings:
#: the first term left out (z^19 / 19) is below 1e-20.
_ATAN = tuple((-1.0) ** k / (2 * k + 1) for k in range(9))


def angle(y: Array, x: Array) -> Array:
    """atan2(y, x) for y >= 0, in [0, pi], from +,*,/ and sqrt only: the half-angle identity
    atan2(y, x) = 2 atan(y / (r + x)) (r = hypot(x, y); mirrored for x < 0), then
    atan(z) = 2 atan(z / (1 + sqrt(1 + z^2))) three times, then the series."""
    r = np.sqrt(x * x + y * y)
    back = x < 0.0
    denom = r + np.abs(x)
    z = np.where(denom > 0.0, y / np.where(denom > 0.0, denom, 1.0), 0.0)  # in [0, 1]
    for _ in range(3):
        z = z / (1.0 + np.sqrt(1.0 + z * z))
    z2 = z * z
    acc = np.full(z.shape, _ATAN[-1])
    for c in _ATAN[-2::-1]:
        acc = acc * z2 + c
    half_turn = 16.0 * z * acc  # 2 (half-angle) * 8 (three halvings) * atan(z)
    return np.where(back, np.pi - half_turn, half_turn)
