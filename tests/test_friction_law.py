"""sim/friction.py's Coulomb law on its own, against closed forms (tests/test_friction.py holds the
whole step to the same law: stopping distances, slopes, spins).

- One foot's disk problem, min x.B x / 2 + c.x over |x| <= r: for B = b I the impulse that stops
  the slip, -c / b, if it lies inside the cone (stick), else the cone's rim against the slip,
  -r c / |c| (slip); for any B, the rim point is the disk's minimiser (checked against the
  minimum over 20,000 points of the rim).
- Four feet of a point mass (the Delassus matrix I/m between every pair of feet): the feet stop
  the mass exactly when m |u0| <= sum mu J_i (the stick/slip boundary), and otherwise take
  sum mu J_i of momentum straight against the slip, whatever way the load is shared.
- The impulse spread over the step: a constant force's drift, h dv / 2, and no turn where
  friction made none (a held ship keeps its attitude's bits).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from touchdown.sim.friction import (CARRIED_RATE, _disk_step, _from_carried, _gauss_seidel,
                                     _slipping, _solve_feet, spread_over_step)


def disk(b, c, r):
    """_disk_step for a 2 x 2 symmetric B (as nested lists) and a 2-vector c."""
    return np.array(_disk_step(float(b[0][0]), float(b[0][1]), float(b[1][1]), float(c[0]),
                               float(c[1]), float(r)))


@pytest.mark.parametrize("b, c, r, sticks", [
    (2.0, (0.3, -0.4), 0.26, True),  # |c| / b = 0.25 inside the cone
    (2.0, (0.3, -0.4), 0.24, False),  # just outside: slips
    (1e-3, (5e-6, 0.0), 1e-2, True),
    (50.0, (-7.0, 3.0), 0.05, False),
])
def test_one_foot_sticks_inside_its_cone_and_slides_on_its_rim_against_the_slip(b, c, r, sticks):
    c = np.array(c)
    x = disk([[b, 0.0], [0.0, b]], c, r)
    stop = -c / b
    if sticks:
        assert x == pytest.approx(stop, rel=1e-14)
        assert np.linalg.norm(b * x + c) < 1e-15 * max(1.0, np.linalg.norm(c))  # no slip left
    else:
        assert x == pytest.approx(-r * c / np.linalg.norm(c), rel=1e-12)
        assert np.linalg.norm(x) == pytest.approx(r, rel=1e-14)


@pytest.mark.parametrize("b, c, r", [
    ([[3.0, 1.2], [1.2, 0.7]], (0.9, -1.7), 0.4),
    ([[1.0, -0.95], [-0.95, 1.0]], (0.2, 0.5), 0.1),
    ([[40.0, 3.0], [3.0, 0.2]], (-2.0, 0.1), 0.03),
])
def test_an_anisotropic_foot_on_its_rim_is_the_disks_minimiser(b, c, r):
    B, c = np.array(b), np.array(c)
    x = disk(b, c, r)
    assert np.linalg.norm(np.linalg.solve(B, -c)) > r  # the unconstrained minimum is outside
    assert np.linalg.norm(x) == pytest.approx(r, rel=1e-12)
    phi = np.linspace(0.0, 2.0 * math.pi, 20_000, endpoint=False)
    rim = r * np.stack([np.cos(phi), np.sin(phi)], 1)
    f = lambda y: 0.5 * np.einsum("...i,ij,...j", y, B, y) + y @ c  # noqa: E731
    assert f(x) <= f(rim).min() + 1e-12 * abs(f(rim).min())
    assert f(x) == pytest.approx(f(rim).min(), rel=1e-6)


def point_mass(mass_kg: float, slip_mps, radius_ns):
    """The feet of a point mass: each foot's slip moves by the sum of every impulse / m."""
    a = np.zeros((4, 2, 4, 2))
    for i in range(4):
        for j in range(4):
            a[i, :, j, :] = np.eye(2) / mass_kg
    slip = np.tile(np.asarray(slip_mps, float), (4, 1))
    radius = np.asarray(radius_ns, float)
    active = np.array([r > 0.0 for r in radius])
    lam = np.zeros((4, 2))
    _solve_feet(a, slip, radius, lam, active, True)  # try_pairs as the step passes it
    return a, slip, radius, lam, active


@pytest.mark.parametrize("mass_kg, slip, loads, sticks", [
    (1000.0, (0.3, 0.4), (150.0, 150.0, 100.0, 100.0), True),  # m|u0| = 500 = sum mu J
    (1000.0, (0.3, 0.4), (150.0, 150.0, 100.0, 99.0), False),  # 1 N s short of stopping it
    (1e4, (-2.0, 0.0), (2000.0, 0.0, 3000.0, 0.0), False),  # two feet pressing
    (1e4, (0.0, 0.001), (10.0, 0.0, 0.0, 0.0), True),  # one foot holds a slow slip
])
def test_a_point_mass_stops_exactly_when_its_momentum_fits_in_the_feet_cones(mass_kg, slip, loads,
                                                                             sticks):
    a, slip0, radius, lam, active = point_mass(mass_kg, slip, loads)
    total = lam.sum(axis=0)
    u0 = np.asarray(slip, float)
    assert np.all(np.linalg.norm(lam, axis=1) <= radius * (1.0 + 1e-12))  # each in its cone
    assert np.all(lam[~active] == 0.0)
    if sticks:
        assert total == pytest.approx(-mass_kg * u0, rel=1e-9, abs=1e-12 * mass_kg)
        after = u0 + total / mass_kg
        assert np.linalg.norm(after) < 1e-9
        assert not any(_slipping(a, slip0, lam, active, 1e-9))
    else:
        capacity = radius.sum()
        assert mass_kg * np.linalg.norm(u0) > capacity
        # all the feet's friction, straight against the slip (maximum dissipation)
        assert total == pytest.approx(-capacity * u0 / np.linalg.norm(u0), rel=1e-9)
        after = u0 + total / mass_kg
        assert np.linalg.norm(after) == pytest.approx(np.linalg.norm(u0) - capacity / mass_kg,
                                                      rel=1e-9)
        assert all(_slipping(a, slip0, lam, active, 0.0)[i] == active[i] for i in range(4))


def test_the_impulse_spread_over_the_step_is_a_constant_forces_drift():
    pos = (1.0e6, 2.0, -3.0)
    quat = tuple(np.array([0.9, 0.1, -0.3, 0.2]) / math.sqrt(0.95))
    v0, v1 = (1.0, 2.0, 0.5), (0.2, 1.5, 0.5)
    h = 0.05
    p, q = spread_over_step(pos, quat, v0, v1, (0.0, 0.1, 0.0), (0.0, 0.1, 0.0), h)
    # x(h) under a constant force is x0 + v0 h + dv h / 2: the step drifted v1 h, so + (v1 - v0) h/2
    assert p == pytest.approx(tuple(x + (b - a) * h / 2 for x, a, b in zip(pos, v0, v1)),
                              rel=1e-15)
    assert q == quat  # friction made no turn: the attitude's bits are kept
    # a change of spin d_omega spread over the step turns the ship by |d_omega| h / 2 more
    _, q2 = spread_over_step(pos, quat, v0, v0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.2), h)
    turn_rad = 2.0 * math.acos(min(1.0, abs(float(np.dot(q2, quat)))))
    assert turn_rad == pytest.approx(0.2 * h / 2, rel=1e-6)
    assert math.isclose(float(np.dot(q2, q2)), 1.0, rel_tol=1e-12)


def tilted_lander(rng):
    """The friction problem of a 15 t lander's pressing feet (foot offsets 2.5 m out, 1.6 m down,
    the ship tilted up to 0.3 rad; principal inertia 6e4, 6e4, 4e4 kg m^2), as coulomb builds it:
    A = J M^-1 J^T (rank 6 at most: four feet have 8 slips, the ship 6 freedoms), a slip from a
    random motion, each disk mu J_i. The problems Gauss-Seidel crawls on."""
    mass, inertia = 15000.0, np.array([6e4, 6e4, 4e4])
    tilt, az = rng.uniform(0.0, 0.3), rng.uniform(0.0, 2.0 * math.pi)
    axis = np.array([math.cos(az), math.sin(az), 0.0])
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    rot = np.eye(3) + math.sin(tilt) * k + (1.0 - math.cos(tilt)) * k @ k
    feet = np.array([[2.5, 0.0, -1.6], [0.0, 2.5, -1.6], [-2.5, 0.0, -1.6], [0.0, -2.5, -1.6]])
    offsets = feet @ rot.T
    t1, t2 = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    pressing = rng.permutation(4)[:rng.integers(2, 5)]
    jac = np.array([np.concatenate([t / math.sqrt(mass),
                                    np.cross(offsets[i], t) / np.sqrt(inertia)])
                    for i in pressing for t in (t1, t2)])
    motion = rng.normal(0.0, 1.0, 6) * rng.choice([1e-2, 1e-1, 1.0])
    mu_j = rng.choice([0.4, 0.6, 1.0]) * rng.uniform(100.0, 5000.0, len(pressing))
    return jac @ jac.T, jac @ motion, mu_j


def barrier_reference(a, s, r, weights=18, steps=10):
    """The feet's problem by a long primal barrier method (numpy): Newton's method on
    lam.A lam / 2 + s.lam - mu sum log(r_i^2 - |lam_i|^2), ``steps`` steps at each of ``weights``
    values of mu, each a tenth of the last (sim.friction's method before issue 36's third part,
    run four times as long: its slips agree with 20,000 Gauss-Seidel sweeps where those
    converge)."""
    lam = last = np.zeros(len(s))
    mu = np.abs(s).max() * r.max()
    for _ in range(weights):
        for _ in range(steps):
            l2 = lam.reshape(-1, 2)
            norm = np.linalg.norm(l2, axis=1)
            d = (r - norm) * (r + norm)
            if not np.all(d > 0.0):
                return last  # rounding reached a disk's edge: the last point inside
            last = lam
            grad = a @ lam + s + (2.0 * mu * l2 / d[:, None]).reshape(-1)
            hess = a.copy()
            for k in range(len(r)):
                hess[2 * k:2 * k + 2, 2 * k:2 * k + 2] += (2.0 * mu / d[k] * np.eye(2)
                                                           + 4.0 * mu / d[k] ** 2
                                                           * np.outer(l2[k], l2[k]))
            try:
                dx = np.linalg.solve(hess, -grad)
            except np.linalg.LinAlgError:
                return lam  # numerically singular: this point
            t = 1.0
            for k in range(len(r)):
                dk = dx[2 * k:2 * k + 2]
                qa, qb = dk @ dk, 2.0 * l2[k] @ dk
                if qa > 0.0:
                    t = min(t, 0.99 * (-qb + math.sqrt(max(qb * qb + 4.0 * qa * d[k], 0.0)))
                            / (2.0 * qa))
            lam = lam + t * dx
        mu *= 0.1
    return lam


def test_the_feet_gauss_seidel_crawls_on_end_at_the_exact_slips():
    """Tilted landers' mixed stick/slide footprints (their matrices singular or nearly so): the
    solve (Gauss-Seidel, then sim.friction's interior-point method where it crawls) leaves every
    foot's slip within 1e-9 m/s of a long barrier solve's (a different method: the exact slips
    to ~1e-12), each impulse inside its disk."""
    rng = np.random.default_rng(36)
    methods = []
    for _ in range(40):
        a2, s2, r = tilted_lander(rng)
        nf = len(r)
        a = np.zeros((4, 2, 4, 2))
        a[:nf, :, :nf, :] = a2.reshape(nf, 2, nf, 2)
        slip = np.zeros((4, 2))
        slip[:nf] = s2.reshape(nf, 2)
        radius = np.zeros(4)
        radius[:nf] = r
        active = radius > 0.0
        lam = np.zeros((4, 2))
        methods.append(_solve_feet(a, slip, radius, lam, active, True))
        ref = barrier_reference(a2, s2, r)
        after, after_ref = a2 @ lam[:nf].reshape(-1) + s2, a2 @ ref + s2
        assert np.abs(after - after_ref).max() < 1e-9, np.abs(after - after_ref).max()
        assert np.all(np.linalg.norm(lam[:nf], axis=1) <= r)
    assert methods.count(2) >= 30  # most of them crawl in Gauss-Seidel: the interior-point method


def two_feet_on_their_rims():
    """Feet 1 and 3 of an envelope touchdown's striking tick (case 45, the step to tick 178):
    their Delassus block is singular to rounding (they slip against each other by a hair, foot 1
    ends on its rim), and the impulses carried in are ~0.05 of their disks (MODEL-NOTES 64)."""
    block = np.array([
        [5.1041807688850316e-04, 1.1271476842879717e-06, 1.1042622420090814e-04,
         1.1273455163023973e-06],
        [1.1271476842879717e-06, 3.1043188930845653e-04, -1.1271391820597576e-06,
         3.1043279010227367e-04],
        [1.1042622420090814e-04, -1.1271391820597576e-06, 5.1041807462176147e-04,
         -1.1273370131684900e-06],
        [1.1273455163023973e-06, 3.1043279010227367e-04, -1.1273370131684900e-06,
         3.1043369090013304e-04]])
    a = np.zeros((4, 2, 4, 2))
    slip, lam, radius = np.zeros((4, 2)), np.zeros((4, 2)), np.zeros(4)
    feet = (1, 3)
    for p, i in enumerate(feet):
        for q, j in enumerate(feet):
            a[i, :, j, :] = block[2 * p:2 * p + 2, 2 * q:2 * q + 2]
    slip[1] = (-2.8997577484884935e-04, -1.8460055860288935e-06)
    slip[3] = (-2.8916779763265389e-04, -1.8452405671371844e-06)
    radius[1], radius[3] = 8.92341832314799, 8.929704251730845
    lam[1] = (0.46737357248745914, 0.0029675141547827423)
    lam[3] = (0.4654583114432366, 0.0029696057136297813)
    active = np.array([False, True, False, True])
    return a, slip, radius, lam, active


def test_two_feet_slipping_by_a_hair_settle_by_the_carried_try_to_the_interior_point_slips():
    """Gauss-Seidel gives up on the pair; the try from the carried impulses settles it once
    it may run its iterations whatever the residual does on the way (the tenfold rule of
    MODEL-NOTES 62 gave it up); sim.carried_try_pairs' solve and note 62's (the interior-point
    method here) leave the same slips, to the methods' ~1e-10 m/s, each impulse in its disk."""
    a, slip, radius, lam0, active = two_feet_on_their_rims()
    assert not _gauss_seidel(a, slip, radius, lam0.copy(), active, False)
    assert _from_carried(a, slip, radius, lam0.copy(), active, math.inf)
    assert not _from_carried(a, slip, radius, lam0.copy(), active, CARRIED_RATE)
    after, lams = {}, {}
    for pairs in (True, False):
        lam = lams[pairs] = lam0.copy()
        _solve_feet(a, slip, radius, lam, active, pairs)
        assert np.all(np.linalg.norm(lam, axis=1) <= radius * (1.0 + 1e-12))
        after[pairs] = slip + np.einsum("iajb,jb->ia", a, lam)
    assert np.abs(after[True] - after[False]).max() < 1e-10
    # foot 1 ends on its rim, slipping by a hair (~8e-10 m/s) that no impulse in the disks takes out
    assert np.linalg.norm(lams[True][1]) >= radius[1] * (1.0 - 1e-9)
    assert 0.0 < np.linalg.norm(after[True][1]) < 1e-8
