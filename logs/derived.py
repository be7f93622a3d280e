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
result is known exactly, each said where it is. The tilt's arccosine is sim.trig's (IEEE +, *, /
and sqrt only), spelled for columns here: libm's differs between machines, numpy's own
vectorised one differs from libm's in the last bit for one value in ten on AVX-512 machines.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from touchdown.sim import trig
from touchdown.sim.params import Params

#: rows computed at a time: a block's intermediates stay in the CPU's cache
ROWS = 8192
_DEG = 180.0 / math.pi


def tilt_deg(cos_tilt: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """degrees(sim.trig.acos(c)) for a column: c clipped to [-1, 1], then sim.trig.angle's
    operations elementwise (the half-angle, three halvings and the series), NaN kept. The same
    bits as the scalar function, value by value (tests/test_export_numpy.py)."""
    c = np.clip(np.ascontiguousarray(cos_tilt, float), -1.0, 1.0)
    with np.errstate(invalid="ignore"):
        y = np.sqrt((1.0 - c) * (1.0 + c))
        r = np.sqrt(c * c + y * y)
        denom = r + np.abs(c)
        positive = denom > 0.0
        z = np.where(positive, y / np.where(positive, denom, 1.0), 0.0)
        for _ in range(3):
            z = z / (1.0 + np.sqrt(1.0 + z * z))
        z2 = z * z
        acc = np.full_like(z, trig.ATAN_TERMS[8])
        for k in range(7, -1, -1):
            acc = acc * z2 + trig.ATAN_TERMS[k]
        half_turn = 16.0 * z * acc
        a = np.where(c < 0.0, trig.PI - half_turn, half_turn)
    a = np.where(np.isnan(c), c, a)
    return np.multiply(a, _DEG, out=out)


def body_angles(params: Params, t_s: np.ndarray) -> tuple[np.ndarray | float, np.ndarray | float]:
    """(cos, sin) of the body's angle at each row's time, as sim.measure.body_angles gives them
    (sim.frames.body_rotation: sim.trig's cos and sin of Omega t, once per instant; (1, 0) at angle
    0). A body that does not turn: the two numbers for every row."""
    om = params.body.omega_radps
    t = np.asarray(t_s, float)
    if om == 0.0 and np.isfinite(t).all():  # (0 x an infinite time is NaN: done below)
        return 1.0, 0.0
    if not t.shape[0]:
        return np.zeros(0), np.zeros(0)
    starts = np.concatenate(([0], np.flatnonzero(t[1:] != t[:-1]) + 1))
    cs = np.array([(1.0, 0.0) if om * x == 0.0 else trig.cos_sin(om * x)
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
    work = _Work(min(n, ROWS))
    for lo in range(0, n, ROWS):
        hi = min(lo + ROWS, n)
        ships = (inertia0 if inertia0.ndim == 1 else inertia0[lo:hi],
                 *(_rows(a, lo, hi) for a in (mass0, leg, com, kpm)))
        work.rows = hi - lo
        _energy(scene, ships, _rows(cos_t, lo, hi), _rows(sin_t, lo, hi), p[lo:hi], v[lo:hi],
                q[lo:hi], w[lo:hi], mass_kg[lo:hi], work, out[lo:hi])
    return out


class _Work:
    """Scratch arrays for a stretch of rows, each handed out once per stretch (``__call__``)
    and all taken back for the next (``rows =``): the intermediates of every stretch lie in
    the same memory. (numpy's own temporaries, freed at the end of each stretch and taken again
    for the next, cost glibc's trimming of its heap and a page fault per 4 kB: 120,000 faults,
    a fifth of the export's time, measured.)"""

    def __init__(self, n: int):
        self._n, self._arrays, self._bools, self._i, self._j = n, [], [], 0, 0
        self._rows = n

    @property
    def rows(self) -> int:
        return self._rows

    @rows.setter
    def rows(self, n: int) -> None:
        self._rows, self._i, self._j = n, 0, 0

    def __call__(self) -> np.ndarray:
        if self._i == len(self._arrays):
            self._arrays.append(np.empty(self._n))
        self._i += 1
        return self._arrays[self._i - 1][:self._rows]

    def mask(self) -> np.ndarray:
        if self._j == len(self._bools):
            self._bools.append(np.empty(self._n, bool))
        self._j += 1
        return self._bools[self._j - 1][:self._rows]


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


def _energy(scene: _Scene, ships, cos_t, sin_t, p, v, q, w, m, work: _Work, out: np.ndarray
            ) -> None:
    """sim.energy.mechanical (``may_touch``) and sim.energy.total, for rows, into ``out``.
    Each product and sum is the kernel's, in its grouping: ``add(x, y)`` for ``x + y`` or
    ``y + x``, ``multiply(x, y)`` for ``x y`` or ``y x`` (IEEE addition and multiplication
    commute: the same bits); the intermediates in ``work``."""
    add, sub, mul, div = np.add, np.subtract, np.multiply, np.divide
    gm, radius, spin = scene.gm, scene.radius, scene.spin
    inertia0, mass0, leg, com, kpm = ships
    W = work
    # the ship's numbers of each row, as sim.measure.energy takes them
    f = div(m, mass0, out=W())
    i0, i1, i2 = (mul(inertia0[..., j], f, out=W()) for j in range(3))
    p0, p1, p2 = p[:, 0], p[:, 1], p[:, 2]
    v0, v1, v2 = v[:, 0], v[:, 1], v[:, 2]
    qw, qx, qy, qz = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    w0, w1, w2 = w[:, 0], w[:, 1], w[:, 2]
    a, b = W(), W()
    if spin != 0.0:
        # spin_b = quat_rotate_inv(q, (0, 0, spin)): quat_rotate((w, -x, -y, -z), (0, 0, spin))
        ux, uy, uz = (np.negative(c, out=W()) for c in (qx, qy, qz))
        t0 = sub(mul(uy, spin, out=a), mul(uz, 0.0, out=b), out=W())
        t1 = sub(mul(uz, 0.0, out=a), mul(ux, spin, out=b), out=W())
        t2 = sub(mul(ux, 0.0, out=a), mul(uy, 0.0, out=b), out=W())
        for t in (t0, t1, t2):
            add(t, t, out=t)
        c0 = sub(mul(uy, t2, out=a), mul(uz, t1, out=b), out=W())
        c1 = sub(mul(uz, t0, out=a), mul(ux, t2, out=b), out=W())
        c2 = sub(mul(ux, t1, out=a), mul(uy, t0, out=b), out=W())
        spin_b = []
        for t, c, s0 in ((t0, c0, 0.0), (t1, c1, 0.0), (t2, c2, spin)):  # (s0 + t w) + c
            bj = add(mul(t, qw, out=W()), s0, out=a)
            spin_b.append(add(bj, c, out=c))
        b0, b1, b2 = spin_b
        # v - sim.contact.surface_velocity(ground, p) = v - (-spin p1, spin p0, 0.0)
        v0 = sub(v0, mul(p1, -spin, out=a), out=W())
        v1 = sub(v1, mul(p0, spin, out=a), out=W())
        v2 = sub(v2, 0.0, out=W())
        w0, w1, w2 = (sub(wj, bj, out=W()) for wj, bj in ((w0, b0), (w1, b1), (w2, b2)))
    # (Omega = 0: the surface's velocity is 0, and v - 0.0 is v to the bit; the body's spin in
    # the ship's frame is 0 or -0 for a finite q, whose sign the squares below drop, and NaN
    # for any other q, which makes the energy NaN: set below)
    trans = mul(v0, v0, out=W())  # 0.5 m (v.v)
    add(trans, mul(v1, v1, out=a), out=trans)
    add(trans, mul(v2, v2, out=a), out=trans)
    mul(trans, mul(m, 0.5, out=a), out=trans)
    rot = mul(w0, mul(i0, w0, out=a), out=W())  # 0.5 (w . I w)
    add(rot, mul(w1, mul(i1, w1, out=a), out=a), out=rot)
    add(rot, mul(w2, mul(i2, w2, out=a), out=a), out=rot)
    mul(rot, 0.5, out=rot)
    r = mul(p0, p0, out=W())  # |p|
    add(r, mul(p1, p1, out=a), out=r)
    add(r, mul(p2, p2, out=a), out=r)
    np.sqrt(r, out=r)
    grav = sub(r, radius, out=W())  # m GM ((r - R) / (R r))
    div(grav, mul(r, radius, out=a), out=grav)
    mul(grav, mul(m, gm, out=a), out=grav)
    total = add(trans, grav, out=out)
    if spin != 0.0:
        rho = mul(p0, p0, out=W())  # -0.5 m spin spin (p0 p0 + p1 p1 - R R)
        add(rho, mul(p1, p1, out=a), out=rho)
        sub(rho, radius * radius, out=rho)
        k = mul(m, -0.5, out=a)
        mul(k, spin, out=k)
        mul(k, spin, out=k)
        add(total, mul(rho, k, out=rho), out=total)
        cs = mul(b0, mul(i0, b0, out=a), out=W())  # -0.5 (spin_b . I spin_b)
        add(cs, mul(b1, mul(i1, b1, out=a), out=a), out=cs)
        add(cs, mul(b2, mul(i2, b2, out=a), out=a), out=cs)
        add(rot, mul(cs, -0.5, out=cs), out=rot)
    else:
        add(total, 0.0, out=total)
        add(rot, 0.0, out=rot)
    add(total, rot, out=total)
    k_leg = mul(mul(kpm, m, out=W()), 0.25, out=f)  # (f is done with)
    add(total, _spring(scene, cos_t, sin_t, p0, p1, p2, qw, qx, qy, qz, leg, com, k_leg, W),
        out=total)
    if spin == 0.0:
        odd = add(add(add(qw, qx, out=a), qy, out=a), qz, out=a)
        odd = np.isfinite(odd, out=W.mask())
        if not odd.all():  # (a sum of finite numbers may overflow: each is looked at)
            rows = np.flatnonzero(~odd)
            total[rows[~np.isfinite(q[rows]).all(axis=1)]] = np.nan


def _spring(scene: _Scene, cos_t, sin_t, p0, p1, p2, qw, qx, qy, qz, leg, com, k_leg, W):
    """What the four feet's springs store (sim.contact.feet: foot_offsets_w, under)."""
    add, sub, mul = np.add, np.subtract, np.multiply
    a = W()
    # body_axes(q): the rotation matrix's columns (each product taken once: it is the same
    # operation on the same numbers wherever the kernel takes it)
    xx, yy, zz = (mul(c, c, out=W()) for c in (qx, qy, qz))
    xy, wz, xz, wy, yz, wx = (mul(c, d, out=W()) for c, d in (
        (qx, qy), (qw, qz), (qx, qz), (qw, qy), (qy, qz), (qw, qx)))

    def twice(op, x, y):  # 2 (x op y)
        o = op(x, y, out=W())
        return mul(o, 2.0, out=o)

    ex = (sub(1.0, mul(add(yy, zz, out=a), 2.0, out=a), out=W()), twice(add, xy, wz),
          twice(sub, xz, wy))
    ey = (twice(sub, xy, wz), sub(1.0, mul(add(xx, zz, out=a), 2.0, out=a), out=W()),
          twice(add, yz, wx))
    ez = (twice(add, xz, wy), twice(sub, yz, wx),
          sub(1.0, mul(add(xx, yy, out=a), 2.0, out=a), out=W()))
    h = np.negative(com)
    down = [mul(e, h, out=e) for e in ez]  # scale(ez, -com_height)
    # axis a, for each axis (ex and ey are done with)
    along = ([mul(e, leg, out=e) for e in ex], [mul(e, leg, out=e) for e in ey])
    spring = W()
    spring[:] = 0.0
    ground = scene.radius + scene.base
    half_k = mul(k_leg, 0.5, out=k_leg)
    foot = [W(), W(), W()]
    r, e, off = W(), W(), W.mask()
    if not scene.flat:
        ms = np.negative(sin_t)
        hgt, t1, de, dn, bump = W(), W(), W(), W(), W()
    # the feet in sim.contact's order, +x, +y, -x, -y: p + (down + axis a), p + (down + axis
    # (-a)), where axis (-a) is -(axis a) to the bit, and down + -(x) is down - x
    for k in range(4):
        for j, pj in enumerate((p0, p1, p2)):
            (add if k < 2 else sub)(down[j], along[k % 2][j], out=foot[j])
            add(foot[j], pj, out=foot[j])
        mul(foot[0], foot[0], out=r)
        add(r, mul(foot[1], foot[1], out=a), out=r)
        add(r, mul(foot[2], foot[2], out=a), out=r)
        np.sqrt(r, out=r)
        if scene.flat:
            x = sub(ground, r, out=r)
        else:  # sim.contact.site_coords, height_and_slope
            east = add(mul(foot[0], ms, out=t1), mul(foot[1], cos_t, out=a), out=e)
            north = foot[2]
            add(mul(east, scene.slope_e, out=hgt), scene.base, out=hgt)
            add(hgt, mul(north, scene.slope_n, out=a), out=hgt)
            for be, bn, brad, bh in scene.bumps:
                sub(east, be, out=de)
                sub(north, bn, out=dn)
                s = add(mul(de, de, out=de), mul(dn, dn, out=dn), out=de)
                mul(s, 1.0 / (brad * brad), out=s)
                w = sub(1.0, s, out=dn)
                mul(mul(w, bh, out=bump), w, out=bump)
                np.copyto(bump, 0.0, where=np.logical_not(np.less(s, 1.0, out=off), out=off))
                add(hgt, bump, out=hgt)
            x = sub(add(hgt, scene.radius, out=hgt), r, out=r)
        mul(half_k, x, out=e)
        mul(e, x, out=e)
        np.copyto(e, 0.0, where=np.logical_not(np.greater(x, 0.0, out=off), out=off))
        add(spring, e, out=spring)  # (spring + 0.0 for a foot off the ground)
    return spring


__all__ = ["tilt_deg", "body_angles", "site_frame", "energy", "ROWS"]
