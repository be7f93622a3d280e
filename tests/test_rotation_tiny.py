"""sim.rotation's tiny turns (tiny_turn, tiny_axis_flow) against the full flow they stand for,
bit for bit: signed zeros, denormals, tiny and ordinary spins, turns on both sides of the
threshold, three-moment and axisymmetric bodies. The full flow is free_rotation as it was
before them (quat_from_rotvec and axis_flow at every step), compiled with the same options."""
import numpy as np

from touchdown.sim.compiled import entry
from touchdown.sim.rotation import (FLOW_AXES, FLOW_FRACTIONS, axis_flow, free_rotation,
    median_moment, rotation_step)
from touchdown.sim.vec import (quat_from_rotvec, quat_mul, quat_normalize, quat_rotate_inv,
    quat_rotate_inv_of, scale)


@entry
def _full_rotations(qs, ls, inertias, hs, q_out, l_out):
    for n in range(qs.shape[0]):
        q = (qs[n, 0], qs[n, 1], qs[n, 2], qs[n, 3])
        l_b = (ls[n, 0], ls[n, 1], ls[n, 2])
        inertia = (inertias[n, 0], inertias[n, 1], inertias[n, 2])
        h = hs[n]
        i_ref = median_moment(inertia)
        coef = (1.0 / inertia[0] - 1.0 / i_ref, 1.0 / inertia[1] - 1.0 / i_ref,
                1.0 / inertia[2] - 1.0 / i_ref)
        q = quat_mul(q, quat_from_rotvec(scale(l_b, h / i_ref)))
        for k in range(len(FLOW_AXES)):
            axis = FLOW_AXES[k]
            if coef[axis] != 0.0:
                q, l_b = axis_flow(q, l_b, coef[axis], axis, FLOW_FRACTIONS[k] * h)
        q = quat_normalize(q)
        for j in range(4):
            q_out[n, j] = q[j]
        for j in range(3):
            l_out[n, j] = l_b[j]


@entry
def _rotations(qs, ls, inertias, hs, q_out, l_out):
    for n in range(qs.shape[0]):
        q, l_b = free_rotation((qs[n, 0], qs[n, 1], qs[n, 2], qs[n, 3]),
                               (ls[n, 0], ls[n, 1], ls[n, 2]),
                               (inertias[n, 0], inertias[n, 1], inertias[n, 2]), hs[n])
        for j in range(4):
            q_out[n, j] = q[j]
        for j in range(3):
            l_out[n, j] = l_b[j]


@entry
def _steps(qs, ls, inertias, hs, q_out, l_out):
    for n in range(qs.shape[0]):
        q, l_b = rotation_step((qs[n, 0], qs[n, 1], qs[n, 2], qs[n, 3]),
                               (ls[n, 0], ls[n, 1], ls[n, 2]),
                               (inertias[n, 0], inertias[n, 1], inertias[n, 2]), hs[n])
        for j in range(4):
            q_out[n, j] = q[j]
        for j in range(3):
            l_out[n, j] = l_b[j]


def _signed(rng, shape, scales):
    """Numbers of random sign whose sizes are drawn from ``scales`` (0.0: a zero of that sign)."""
    size = rng.choice(np.asarray(scales, float), size=shape)
    mant = rng.uniform(1.0, 2.0, size=shape)
    sign = rng.choice([-1.0, 1.0], size=shape)
    return np.where(size == 0.0, sign * 0.0, sign * mant * size)


def _inputs(n, seed):
    rng = np.random.default_rng(seed)
    qs = rng.normal(size=(n, 4))
    qs /= np.linalg.norm(qs, axis=1)[:, None]
    kind = rng.integers(0, 4, size=n)
    # upright ships: (+-1, +-0, +-0, +-0); one axis (a turn about z); some zeros; none
    zero = rng.random((n, 4)) < np.where(kind == 0, 0.75, np.where(kind == 1, 0.5, 0.25))[:, None]
    zero &= (kind != 3)[:, None]
    zero[np.all(zero, axis=1), 0] = False
    qs = np.where(zero, rng.choice([-1.0, 1.0], size=(n, 4)) * 0.0, qs)
    qs[kind == 0] = np.where(zero[kind == 0], qs[kind == 0], np.sign(qs[kind == 0]))
    qs /= np.linalg.norm(qs, axis=1)[:, None]  # (a zero divided stays a zero of its sign)
    scales = [0.0, 0.0, 5e-324, 1e-310, 1e-300, 1e-200, 1e-30, 1e-20, 1e-16, 1e-12, 1e-10, 1e-9,
              1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-2, 1.0, 1e2, 1e4, 1e6]
    ls = _signed(rng, (n, 3), scales)
    # a turn's half angle near the threshold (2^-27) for the default ship's moments
    near = rng.random(n) < 0.2
    ls[near] = _signed(rng, (int(near.sum()), 3), [0.0] + [2.0 ** e for e in range(-16, 0)])
    base = np.array([[30000.0, 45000.0, 20000.0], [40000.0, 40000.0, 25000.0],
                     [12000.0, 14500.0, 9000.0], [9000.0, 9000.0, 9000.0]])
    inertias = base[rng.integers(0, len(base), size=n)] * rng.choice(
        [1.0, 1.0, 0.5, 1.3], size=(n, 1))
    hs = rng.choice([0.05, 0.025, 0.05 / 8, 0.05 / 16, 0.5, 1e-4], size=n)
    return qs, ls, inertias, hs


def _run(fn, qs, ls, inertias, hs):
    q_out, l_out = np.empty_like(qs), np.empty_like(ls)
    fn(qs, ls, inertias, hs, q_out, l_out)
    return q_out, l_out


def test_tiny_turns_are_the_full_flow_bit_for_bit():
    qs, ls, inertias, hs = _inputs(400_000, 36)
    q_full, l_full = _run(_full_rotations, qs, ls, inertias, hs)
    for fn in (_rotations, _steps):  # free_rotation, and rotation_step's dispatch
        q_new, l_new = _run(fn, qs, ls, inertias, hs)
        assert np.array_equal(q_full.view(np.uint64), q_new.view(np.uint64))
        assert np.array_equal(l_full.view(np.uint64), l_new.view(np.uint64))
    # the inputs reach both sides: zero signs that the flows change, and ordinary turns
    assert np.any(np.signbit(q_full) != np.signbit(qs) & (q_full == 0.0))
    assert np.any(np.abs(l_full - ls) > 0.0)
    # and both of rotation_step's ways: tiny throughout, and not
    c = 1.0 / inertias - 1.0 / np.median(inertias, axis=1)[:, None]
    bound = np.abs(c).sum(axis=1) * np.abs(ls).sum(axis=1) * 1.7024143839193155 * hs
    tiny = (bound < 2.0 ** -27) & np.all(np.abs(ls * (hs / np.median(inertias, axis=1))[:, None])
                                         < 2.0 ** -28, axis=1)
    assert 0.2 < tiny.mean() < 0.8


def test_zero_spin_upright_every_sign():
    """An upright ship, q = (+-1, +-0, +-0, +-0), L = (+-0, +-0, +-0), every combination of
    signs, every moment set and step above."""
    rows = []
    for bits in range(1 << 7):
        sg = [-1.0 if bits >> j & 1 else 1.0 for j in range(7)]
        rows.append(([sg[0], sg[1] * 0.0, sg[2] * 0.0, sg[3] * 0.0],
                     [sg[4] * 0.0, sg[5] * 0.0, sg[6] * 0.0]))
    qs = np.array([r[0] for r in rows] * 8)
    ls = np.array([r[1] for r in rows] * 8)
    base = np.array([[30000.0, 45000.0, 20000.0], [40000.0, 40000.0, 25000.0],
                     [12000.0, 14500.0, 9000.0], [9000.0, 9000.0, 9000.0]])
    inertias = np.repeat(base, len(rows), axis=0).reshape(-1, 3)
    inertias = np.concatenate([inertias, inertias])
    hs = np.repeat([0.05, 0.05 / 16], 4 * len(rows))
    q_full, l_full = _run(_full_rotations, qs, ls, inertias, hs)
    for fn in (_rotations, _steps):
        q_new, l_new = _run(fn, qs, ls, inertias, hs)
        assert np.array_equal(q_full.view(np.uint64), q_new.view(np.uint64))
        assert np.array_equal(l_full.view(np.uint64), l_new.view(np.uint64))


@entry
def _rotated(qs, vs, out, out_of):
    for n in range(qs.shape[0]):
        q = (qs[n, 0], qs[n, 1], qs[n, 2], qs[n, 3])
        v = (vs[n, 0], vs[n, 1], vs[n, 2])
        a = quat_rotate_inv(q, v)
        b = quat_rotate_inv_of(q, v)
        for j in range(3):
            out[n, j] = a[j]
            out_of[n, j] = b[j]


def test_rotated_zero_vector():
    """sim.vec.quat_rotate_inv_of: quat_rotate_inv bit for bit for every finite attitude (+0 and
    -0 components, denormals, unnormalised), whatever the vector's zeros' signs; nan where it
    gives nan for a non-finite one."""
    rng = np.random.default_rng(7)
    n = 200_000
    qs = _signed(rng, (n, 4), [0.0, 0.0, 5e-324, 1e-300, 1e-10, 0.5, 1.0, 1e10, 1e300])
    bad = rng.random(n) < 0.05
    qs[bad, rng.integers(0, 4, size=int(bad.sum()))] = rng.choice([np.inf, -np.inf, np.nan],
                                                                   size=int(bad.sum()))
    vs = np.where(rng.random((n, 3)) < 0.5, 0.0, -0.0)
    vs[rng.random(n) < 0.3] = 0.0  # all +0: the way without products
    vs[rng.random(n) < 0.1] = _signed(rng, (1, 3), [1.0, 1e-300])
    out, out_of = np.empty_like(vs), np.empty_like(vs)
    _rotated(qs, vs, out, out_of)
    finite = np.all(np.isfinite(qs), axis=1)
    assert np.array_equal(out[finite].view(np.uint64), out_of[finite].view(np.uint64))
    assert np.array_equal(np.isnan(out), np.isnan(out_of))
    num = ~np.isnan(out)
    assert np.array_equal(out[num].view(np.uint64), out_of[num].view(np.uint64))
    allpos = np.all((vs == 0.0) & ~np.signbit(vs), axis=1)
    assert allpos.sum() > 0.25 * n and np.any(~finite & allpos)
