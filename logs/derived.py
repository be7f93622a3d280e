"""What export derives from a logged state, in numpy: the tilt in degrees, the site frame's
position and velocity, and the mechanical energy, bit for bit the numbers the compiled functions
of :mod:`sim.measure` give (a test holds them to each other, number by number, over every log of
tests/data and over random states on spinning, sloped and bumpy ground).

Why a second spelling of three of the step's quantities: ``touchdown export`` reads a log's
numbers and writes them out, and the compiled functions cost it half a second before the first
number (numba's import, 0.2 s, and the loading of cached kernels, which refreshes numba's
registries and imports scipy, 0.3 s), two fifths of a Parquet export of 2 million rows. numpy
gives the same bits when it does the same IEEE-754 operations in the same order: each function
below is :mod:`sim.energy`, :mod:`sim.contact` and :mod:`sim.frames` written for columns,
operation by operation (``a + b + c`` is ``(a + b) + c`` in both; the kernels are compiled
without fastmath, so no multiply-add is fused: sim.compiled). Two steps are left out where their
result is known exactly, each said where it is. The one transcendental function, the tilt's
arccosine, is libm's in both (numpy's own vectorised one differs in the last bit for one value in
ten on AVX-512 machines; Arrow's ``acos`` calls libm's).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from touchdown.sim.params import Params

#: rows computed at a time: a block's intermediates stay in the CPU's cache
ROWS = 8192
_DEG = 180.0 / math.pi


def tilt_deg(cos_tilt: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """degrees(acos(c)), c clipped to [-1, 1]: ``math.degrees(math.acos(c))``, libm's acos."""
    import pyarrow as pa
    try:  # pyarrow.compute's own (importing pyarrow.compute itself costs 25 ms: it builds a
        from pyarrow._compute import call_function  # wrapper for each of its functions)
    except ImportError:  # pragma: no cover - a pyarrow that moved it
        from pyarrow.compute import call_function
    c = np.clip(np.ascontiguousarray(cos_tilt, float), -1.0, 1.0)
    acos = call_function("acos", [pa.array(c, pa.float64())])
    return np.multiply(acos.to_numpy(zero_copy_only=False), _DEG, out=out)


def body_angles(params: Params, t_s: np.ndarray) -> tuple[np.ndarray | float, np.ndarray | float]:
    """(cos, sin) of the body's angle at each row's time, as sim.measure.body_angles gives them
    (sim.frames.body_rotation: libm's cos and sin of Omega t, once per instant; (1, 0) at angle
    0). A body that does not turn: the two numbers for every row."""
    om = params.body.omega_radps
    t = np.asarray(t_s, float)
    if om == 0.0 and np.isfinite(t).all():  # (0 x an infinite time is NaN: done below)
        return 1.0, 0.0
    if not t.shape[0]:
        return np.zeros(0), np.zeros(0)
    starts = np.concatenate(([0], np.flatnonzero(t[1:] != t[:-1]) + 1))
    cs = np.array([(1.0, 0.0) if om * x == 0.0 else (math.cos(om * x), math.sin(om * x))
                   for x in t[starts].tolist()]).reshape(-1, 2)
    lengths = np.diff(np.append(starts, t.shape[0]))
    return np.repeat(cs[:, 0], lengths), np.repeat(cs[:, 1], lengths)


def _rows(c, lo: int, hi: int):
    return c if np.ndim(c) == 0 else c[lo:hi]


def site_frame(params: Params, p: np.ndarray, v: np.ndarray, cos_t, sin_t,
               out: tuple[np.ndarray, ...] | None = None) -> tuple[np.ndarray, ...]:
    """(east, north, up) of centres of mass (N,3), m, and their velocity relative to the surface
    in the same axes (v_east, v_north, v_up), m/s, each a column of its own
    (sim.measure.site_frame: sim.frames.rotate_z by the body's angle undone, site_axes, less
    the reference radius). ``out``: the six columns' arrays."""
    n = p.shape[0]
    radius, om = params.body.radius_m, params.body.omega_radps
    if out is None:
        out = tuple(np.empty(n) for _ in range(6))
    east, north, up, v_east, v_north, v_up = out
    for lo in range(0, n, ROWS):
        hi = min(lo + ROWS, n)
        c, ms = _rows(cos_t, lo, hi), -_rows(sin_t, lo, hi)
        p0, p1 = p[lo:hi, 0], p[lo:hi, 1]
        v0, v1 = v[lo:hi, 0], v[lo:hi, 1]
        if om != 0.0:  # sim.frames.surface_velocity; for Omega = 0 it is 0, and v - 0.0 is v
            v0, v1 = v0 - -om * p1, v1 - om * p0
        # rotate_z(x, c, -s) = (c x0 - (-s) x1, (-s) x0 + c x1, x2); site axes (y, z, x)
        for x0, x1, y, z in ((p0, p1, east, up), (v0, v1, v_east, v_up)):
            y, z = y[lo:hi], z[lo:hi]
            np.multiply(x1, c, out=y)
            y += ms * x0
            np.multiply(x0, c, out=z)
            z -= ms * x1
        up[lo:hi] -= radius
    north[:] = p[:, 2]
    if om == 0.0:
        v_north[:] = v[:, 2]
    else:
        np.subtract(v[:, 2], 0.0, out=v_north)
    return out


def energy(params: Params, ship: np.ndarray, p: np.ndarray, v: np.ndarray, q: np.ndarray,
           w: np.ndarray, mass_kg: np.ndarray, cos_t, sin_t, out: np.ndarray | None = None
           ) -> np.ndarray:
    """sim.energy.mechanical's total (sim.measure.energy's ``total_j``) of each row: row i is
    ship ``ship[i]`` of ``params`` in state (p, v, q, w, mass) at body angle (cos_t, sin_t)."""
    sh, body, ter = params.ships, params.body, params.body.terrain
    n = p.shape[0]
    out = np.empty(n) if out is None else out
    scene = _Scene(float(body.gm_m3ps2), float(body.radius_m), float(body.omega_radps),
                   bool(ter.flat), float(ter.base_height_m), *map(float, ter.gradient),
                   np.array([ter.bump_east_m, ter.bump_north_m, ter.bump_radius_m,
                             ter.bump_height_m], float).reshape(4, -1).T.tolist())
    # each row's ship's numbers (a fleet of one class: the one number, no gather)
    inertia0, mass0, leg, com, kpm = (_per_row(a, ship) for a in (
        sh.inertia0_kgm2, sh.mass0_kg, sh.leg_radius_m, sh.com_height_m, sh.stiffness_per_kg))
    for lo in range(0, n, ROWS):
        hi = min(lo + ROWS, n)
        ships = (inertia0 if inertia0.ndim == 1 else inertia0[lo:hi],
                 *(_rows(a, lo, hi) for a in (mass0, leg, com, kpm)))
        out[lo:hi] = _energy(scene, ships, _rows(cos_t, lo, hi), _rows(sin_t, lo, hi),
                             p[lo:hi], v[lo:hi], q[lo:hi], w[lo:hi], mass_kg[lo:hi])
    return out


def _per_row(table: np.ndarray, ship: np.ndarray):
    """``table[ship]``: each row's ship's number (or row of numbers), or the one every ship
    has."""
    if table.shape[0] and (table == table[0]).all():
        return table[0] if table.ndim > 1 else float(table[0])
    return table[ship]


class _Scene(NamedTuple):
    gm: float
    radius: float
    spin: float
    flat: bool
    base: float
    slope_e: float
    slope_n: float
    bumps: list  # (east, north, radius, height) of each bump


def _energy(scene: _Scene, ships, cos_t, sin_t, p, v, q, w, m) -> np.ndarray:
    """sim.energy.mechanical (``may_touch``) and sim.energy.total, for rows. The products keep
    the kernels' grouping; ``x += y`` for ``y + x`` (IEEE addition and multiplication commute:
    the same bits)."""
    gm, radius, spin = scene.gm, scene.radius, scene.spin
    inertia0, mass0, leg, com, kpm = ships
    # the ship's numbers of each row, as sim.measure.energy takes them
    f = m / mass0
    i0, i1, i2 = (inertia0[..., j] * f for j in range(3))
    p0, p1, p2 = p[:, 0], p[:, 1], p[:, 2]
    v0, v1, v2 = v[:, 0], v[:, 1], v[:, 2]
    qw, qx, qy, qz = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    w0, w1, w2 = w[:, 0], w[:, 1], w[:, 2]
    if spin != 0.0:
        # spin_b = quat_rotate_inv(q, (0, 0, spin)): quat_rotate((w, -x, -y, -z), v)
        ux, uy, uz = -qx, -qy, -qz
        t0 = uy * spin - uz * 0.0
        t1 = uz * 0.0 - ux * spin
        t2 = ux * 0.0 - uy * 0.0
        t0, t1, t2 = t0 + t0, t1 + t1, t2 + t2
        c0, c1, c2 = uy * t2 - uz * t1, uz * t0 - ux * t2, ux * t1 - uy * t0
        b0, b1, b2 = (0.0 + t0 * qw) + c0, (0.0 + t1 * qw) + c1, (spin + t2 * qw) + c2
        # v - sim.contact.surface_velocity(ground, p)
        v0, v1, v2 = v0 - -spin * p1, v1 - spin * p0, v2 - 0.0
        w0, w1, w2 = w0 - b0, w1 - b1, w2 - b2
    # (Omega = 0: the surface's velocity is 0, and v - 0.0 is v to the bit; the body's spin in
    # the ship's frame is 0 or -0 for a finite q, whose sign the squares below drop, and NaN
    # for any other q, which makes the energy NaN: set below)
    trans = v0 * v0
    trans += v1 * v1
    trans += v2 * v2
    trans *= 0.5 * m
    rot = w0 * (i0 * w0)
    rot += w1 * (i1 * w1)
    rot += w2 * (i2 * w2)
    rot *= 0.5
    r = p0 * p0
    r += p1 * p1
    r += p2 * p2
    np.sqrt(r, out=r)
    grav = r - radius
    grav /= radius * r
    grav *= m * gm
    total = trans
    total += grav
    if spin != 0.0:
        rho = p0 * p0
        rho += p1 * p1
        rho -= radius * radius
        rho *= -0.5 * m * spin * spin
        total += rho  # the centre of mass's centrifugal part
        cs = b0 * (i0 * b0)
        cs += b1 * (i1 * b1)
        cs += b2 * (i2 * b2)
        cs *= -0.5
        rot += cs  # the rotation's
    else:
        total += 0.0
        rot += 0.0
    total += rot
    total += _spring(scene, cos_t, sin_t, p0, p1, p2, qw, qx, qy, qz, leg, com,
                     0.25 * (kpm * m))
    if spin == 0.0:
        odd = qw + qx
        odd += qy
        odd += qz
        odd = ~np.isfinite(odd)  # (a sum of finite numbers may overflow: each is looked at)
        if odd.any():
            odd[odd] = ~np.isfinite(q[odd]).all(axis=1)
            total[odd] = np.nan
    return total


def _spring(scene: _Scene, cos_t, sin_t, p0, p1, p2, qw, qx, qy, qz, leg, com, k_leg):
    """What the four feet's springs store (sim.contact.feet: foot_offsets_w, under)."""
    # body_axes(q): the rotation matrix's columns (each product taken once: it is the same
    # operation on the same numbers wherever the kernel takes it)
    xx, yy, zz = qx * qx, qy * qy, qz * qz
    xy, wz, xz, wy, yz, wx = qx * qy, qw * qz, qx * qz, qw * qy, qy * qz, qw * qx
    ex = (1.0 - 2.0 * (yy + zz), 2.0 * (xy + wz), 2.0 * (xz - wy))
    ey = (2.0 * (xy - wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz + wx))
    h = -com
    down = (2.0 * (xz + wy) * h, 2.0 * (yz - wx) * h,
            (1.0 - 2.0 * (xx + yy)) * h)  # scale(ez, -com_height)
    spring = np.zeros_like(p0)
    ground = scene.radius + scene.base
    half_k = 0.5 * k_leg
    along = ([ex[j] * leg for j in range(3)], [ey[j] * leg for j in range(3)])
    # the feet in sim.contact's order, +x, +y, -x, -y: p + (down + axis a), p + (down + axis
    # (-a)), where axis (-a) is -(axis a) to the bit, and down + -(x) is down - x
    for k in range(4):
        foot = []
        for j, pj in enumerate((p0, p1, p2)):
            fj = down[j] + along[k % 2][j] if k < 2 else down[j] - along[k % 2][j]
            fj += pj
            foot.append(fj)
        r = foot[0] * foot[0]
        r += foot[1] * foot[1]
        r += foot[2] * foot[2]
        np.sqrt(r, out=r)
        if scene.flat:
            x = np.subtract(ground, r, out=r)
        else:  # sim.contact.site_coords, height_and_slope
            east, north = -sin_t * foot[0] + cos_t * foot[1], foot[2]
            hgt = scene.base + scene.slope_e * east + scene.slope_n * north
            for be, bn, brad, bh in scene.bumps:
                de, dn = east - be, north - bn
                s = (de * de + dn * dn) * (1.0 / (brad * brad))
                w = 1.0 - s
                hgt = hgt + np.where(s < 1.0, bh * w * w, 0.0)
            x = (scene.radius + hgt) - r
        e = half_k * x
        e *= x
        spring += np.where(x > 0.0, e, 0.0)  # (spring + 0.0 for a foot off the ground)
    return spring


__all__ = ["tilt_deg", "body_angles", "site_frame", "energy", "ROWS"]
