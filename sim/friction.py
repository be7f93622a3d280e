"""Coulomb friction at the feet that press, applied as impulses after each (sub)step.

Touchdown's law (``friction_model = "coulomb"``, SEED-NOTES 4, MODEL-NOTES 23 and 38). Each foot
that pressed during the step has its own Coulomb cone: with J_i its normal impulse over the step
(what the integrator applied), its friction impulse lambda_i lies in the ground's tangent plane
there, in the disk |lambda_i| <= mu J_i. The feet are coupled through the rigid ship: a foot's
slip after the impulses is  u_i = u0_i + sum_j A_ij lambda_j,  A the 8 x 8 Delassus matrix of the
four feet's tangent planes (translation and rotation through the ship's mass and inertia). The
impulses are those of maximum dissipation,

    minimise  lambda.A lambda / 2 + u0.lambda   over  |lambda_i| <= mu_i J_i,  i = 1..4,

whose optimality conditions are Coulomb's law at every foot at once: a foot inside its disk ends
with no slip (it sticks), a foot on its rim slides, its impulse against its own slip (Stewart,
"Rigid-body dynamics with friction and impact", SIAM Review 42, 2000; the per-contact cone of
MuJoCo and Bullet). mu_i is mu_s for a foot that held at the step's start, mu_k for one that slid;
a holding foot whose solution sits on its mu_s rim breaks away and the solve is repeated with it
kinetic (MAX_ROUNDS rounds). Solved by projected block Gauss-Seidel (each foot's 2 x 2 disk
problem exactly, :func:`_disk_step`), and where that crawls, on the near-redundant slips of three
or four feet, by a primal-dual interior-point method; both with fixed maximum counts.

Slow slips are a tolerance: a foot slipping slower than ``stick_speed_mps`` (the seed's 0.01 m/s
threshold, a scenario key) after the impulses keeps mu_s. The rigid model has no leg compliance, so
four feet a micrometre apart in height under a rocking ship must slip against each other by a
hair; the stick speed lets them, as the legs would.

Everything is evaluated at the step's end state: the feet where they are, their slip relative to
the surface under them (Omega z x foot on a rotating body), in the tangent plane of the terrain
there (its slope on the ship's local vertical: the sphere's curvature across the footprint, a / R,
is left out of the friction planes). A ship held on a slope does not creep.

The impulse stands for a force that acted throughout the step, so the step's drift is corrected for
it (:func:`spread_over_step`): without that, the drift uses the speed from before the impulse, a
slide overshoots by mu_k g h T / 2 (first order in the step h) and a ship held on a slope creeps
by a h^2 / 2 a step. Two refinements keep the impulse's errors out of the places they show:
a foot that was sliding at the step's start is dragged by mu_k N_i as a force inside the
integrator (sim.contact.evaluate), so a long slide's friction moment meets the feet's restoring
moment at the same instant; and a held footprint's static friction is carried into the next step
as a force (``hold_w``), so a ship held on a slope feels its hold while it integrates, not half a
step late.

The seed's law (``"seed"``): kinetic above 0.01 m/s with no stopping test, else reset the centre of
mass's tangential velocity, falling back to kinetic friction beyond mu_s N; it acts at the centre
of mass (no moment). Kept reachable for comparison; it 2-cycles and creeps as SEED-NOTES 4 shows.
One ship, compiled (sim.compiled).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from touchdown.sim.compiled import kernel, stack_zeros
from touchdown.sim.constants import SEED_STICK_SPEED_MPS
from touchdown.sim.contact import foot_velocity, surface_velocity
from touchdown.sim.settings import FrictionModel
from touchdown.sim.vec import add, cross, div, dot, fmax, fmin, norm, quat_integrate, quat_rotate, \
    quat_rotate_inv, scale, sub, unit


#: the seed's law (sim.settings.FrictionModel), as the scene record holds it
SEED_LAW = int(FrictionModel.SEED)


@kernel
def per_foot(cfg):
    """Which law runs, the one place the step reads the scene's ``contact.friction_model``:
    Coulomb's law at each foot (True: :func:`coulomb`, the holding feet's friction inside the
    step, stops and breakaways located, feet still at rest), or the seed's velocity reset at the
    centre of mass (False: :func:`seed`)."""
    return cfg.friction_model != SEED_LAW


@kernel
def law_of(cfg):
    """The scene's :class:`FrictionLaw`."""
    return FrictionLaw(cfg.friction_static, cfg.friction_kinetic, cfg.stick_speed_mps,
                       cfg.carried_try_pairs)


class FrictionLaw(NamedTuple):
    """Coulomb's law at the feet (the scene's ``contact.friction_static``, ``friction_kinetic`` and
    ``stick_speed``): a foot holds up to mu_s N and slides against mu_k N; one that slips slower
    than the stick speed keeps mu_s."""

    mu_s: float
    mu_k: float
    stick_speed_mps: float
    #: the solve's try from the carried impulses (:func:`_solve_feet`) for two or three feet, to
    #: its last iteration; False: for three or four, given up where its residual grows tenfold
    #: (sim.carried_try_pairs, MODEL-NOTES 64)
    try_pairs: bool


@kernel
def spread_over_step(pos_m, quat, vel_before, vel_after, omega_before, omega_after, h):
    """Position and attitude as if the friction impulse had acted evenly over the step of length
    h: a velocity change dv spread over the step changes its drift by h dv / 2 (dv opposes the
    slip, so the ship ends short of where its speed before the impulse took it), and likewise
    for the turn. Exact for a constant friction force; a ship held at rest by static friction
    then stays exactly where it is."""
    pos = add(pos_m, scale(sub(vel_after, vel_before), 0.5 * h))
    d_omega = sub(omega_after, omega_before)
    if d_omega[0] != 0.0 or d_omega[1] != 0.0 or d_omega[2] != 0.0:
        return pos, quat_integrate(quat, d_omega, 0.5 * h)
    return pos, quat  # a ship that friction did not turn keeps its attitude's bits


@kernel
def tangent_basis(n_hat):
    """Two unit vectors spanning the plane normal to n_hat (any orientation)."""
    use_z = abs(n_hat[2]) < 0.9
    ref = (0.0, 0.0, 1.0) if use_z else (1.0, 0.0, 0.0)
    t1 = unit(cross(ref, n_hat))
    return t1, cross(n_hat, t1)


class Rigid(NamedTuple):
    """The ship as friction's impulses move it: a rigid body of mass m and principal inertia I."""

    mass_kg: float
    inertia_kgm2: tuple  # principal moments, body frame


class FeetOn(NamedTuple):
    """The four feet at one instant (sim.contact.Feet) on the ground as it is then
    (sim.contact.Ground)."""

    ground: object
    feet: object


class Patch(NamedTuple):
    """The footprint as friction sees it."""

    normals: tuple  # each foot's friction plane normal
    n_bar: tuple  # the load-weighted normal
    centre: tuple  # the centre of pressure


@kernel
def patch(pos_m, ft, j_n):
    """Each foot's friction plane normal, and the footprint's: the load-weighted normal and the
    centre of pressure (weights: the feet's normal impulses). A foot's plane is the terrain's
    slope under it on the ship's local vertical: the sphere's own curvature across the footprint
    (a / R, 1e-6 rad) would make a straight descent slip every foot inwards."""
    up = unit(pos_m)
    j_sum = j_n[0] + j_n[1] + j_n[2] + j_n[3]
    n0 = unit(add(sub(ft.push_w[0], unit(ft.pos_w[0])), up))
    n1 = unit(add(sub(ft.push_w[1], unit(ft.pos_w[1])), up))
    n2 = unit(add(sub(ft.push_w[2], unit(ft.pos_w[2])), up))
    n3 = unit(add(sub(ft.push_w[3], unit(ft.pos_w[3])), up))
    if not j_sum > 0.0:
        return Patch((n0, n1, n2, n3), up, pos_m)
    n_bar = unit(add(add(add(scale(n0, j_n[0]), scale(n1, j_n[1])), scale(n2, j_n[2])),
                     scale(n3, j_n[3])))
    return Patch((n0, n1, n2, n3), n_bar, _centre_of_pressure(pos_m, ft.pos_w, j_n))


@kernel
def _centre_of_pressure(pos_m, pos_w, j_n):
    """:func:`patch`'s centre of pressure of the feet at ``pos_w``: their positions weighted by
    their normal impulses j_n (``pos_m`` where none presses). Needs no ground: the positions
    alone."""
    j_sum = j_n[0] + j_n[1] + j_n[2] + j_n[3]
    if not j_sum > 0.0:
        return pos_m
    c = add(add(add(scale(pos_w[0], j_n[0]), scale(pos_w[1], j_n[1])),
                scale(pos_w[2], j_n[2])), scale(pos_w[3], j_n[3]))
    return (c[0] / j_sum, c[1] / j_sum, c[2] / j_sum)


@kernel
def _pressing_normals(pos_m, ft, j_n):
    """:func:`patch`'s normals of the feet that press (j_n > 0), the same bits; zero for the
    others, which nothing reads."""
    up = unit(pos_m)
    z = (0.0, 0.0, 0.0)
    n0 = unit(add(sub(ft.push_w[0], unit(ft.pos_w[0])), up)) if j_n[0] > 0.0 else z
    n1 = unit(add(sub(ft.push_w[1], unit(ft.pos_w[1])), up)) if j_n[1] > 0.0 else z
    n2 = unit(add(sub(ft.push_w[2], unit(ft.pos_w[2])), up)) if j_n[2] > 0.0 else z
    n3 = unit(add(sub(ft.push_w[3], unit(ft.pos_w[3])), up)) if j_n[3] > 0.0 else z
    return n0, n1, n2, n3


@kernel
def hold_footprint(pos_m, start_pos_w, ft_end, foot_impulse_ns, cos_turn, sin_turn):
    """The ship moved so that a footprint held by static friction through the whole step ends
    exactly where the ground has carried the point it stood on (the ground turning by the angle of
    (cos_turn, sin_turn) about z over the step): the position-level half of sticking. The
    velocity-level half (the stop impulse) and the spread of its drift over the step leave a
    residue when a held foot's slip does not grow evenly within the step (a held ship on a
    rotating body, whose ground curves away under its straight inertial step, crept 0.5 m an hour
    at 25 ms sub-steps without this); only the drift along the ground is undone. ``start_pos_w``:
    the feet's positions at the step's start (its centre of pressure needs no ground);
    ``ft_end``: the feet (sim.contact.Feet) at its end."""
    j_n = (fmax(foot_impulse_ns[0], 0.0), fmax(foot_impulse_ns[1], 0.0),
           fmax(foot_impulse_ns[2], 0.0), fmax(foot_impulse_ns[3], 0.0))
    start = _centre_of_pressure(pos_m, start_pos_w, j_n)
    end = patch(pos_m, ft_end, j_n)
    carried = (cos_turn * start[0] - sin_turn * start[1],
               sin_turn * start[0] + cos_turn * start[1], start[2])
    drift = sub(end.centre, carried)
    drift = sub(drift, scale(end.n_bar, dot(drift, end.n_bar)))
    return sub(pos_m, drift)


class Friction(NamedTuple):
    """What friction did over a step."""

    vel_mps: tuple
    omega_body_radps: tuple
    sliding: tuple  # each foot's regime (kinetic) after the step
    impulse_ns: float  # the sum of the feet's friction impulse magnitudes
    sweeps: int  # Gauss-Seidel sweeps the solve took (all of its rounds)
    held: bool  # no pressing foot slides and the footprint's centre ends at rest
    hold_w: tuple  # each holding foot's static friction over the step (carried into the next)


#: Most Gauss-Seidel sweeps of one solve of the feet's impulses, and the violation of its
#: optimality conditions (m/s of slip) below which it has converged. Most solves take a few
#: sweeps; the rest go to the interior-point method.
MAX_SWEEPS = 30
SLIP_TOL_MPS = 1e-11
#: Gauss-Seidel's crawl test (:func:`_gauss_seidel`): every CRAWL_SWEEPS sweeps, the residual's
#: rate over them, projected to MAX_SWEEPS, must reach CRAWL_MARGIN times the tolerance
CRAWL_SWEEPS = 3
CRAWL_MARGIN = 100.0
#: The interior-point method (:func:`_interior_point`): most Newton steps of one solve, the change
#: of the slips (m/s) in a step below which it stops, and the fraction of the way to the cones'
#: edges a step goes.
IPM_MAX_STEPS = 30
IPM_TOL_MPS = 1e-11
IPM_STEP = 0.99
#: The active-set finish of the interior-point method (:func:`_active_set`): the IPM's gap
#: (relative to its first) under which it is tried, a second time under the second; how clearly
#: every foot must already read as sticking or slipping (the ratio of its dual's and its primal's
#: distances, both ways); most Newton iterations a try; a reduced pivot under this fraction of its
#: diagonal entry drops its direction (several sticking feet hold the ship in many ways).
FINISH_GAPS = (1e-4, 1e-6)
FINISH_CLEAR = 10.0
FINISH_ITERATIONS = 3
FINISH_RATE = 0.1
FINISH_PIVOT = 1e-12
#: The active-set solve from the impulses carried in (:func:`_from_carried`): a carried impulse
#: at least this fraction of its radius reads as slipping; most Newton iterations; the residual
#: may not grow more than this factor in an iteration (only a diverging split is given up
#: early: from a guessed split the first iterations move feet between sticking and slipping).
CARRIED_RIM = 0.99
CARRIED_ITERATIONS = 6
CARRIED_RATE = 10.0
#: The fewest and most feet the try is for (sim.carried_try_pairs; MODEL-NOTES 64): two feet
#: that slip against each other by a hair, both on their rims, are its (Gauss-Seidel crawls
#: there, along the pair's null direction); four feet's carried split is wrong or its first
#: step throws the sticking feet out of their disks (3% settled: the try cost more than it saved)
PAIRS_FEET = (2, 3)
#: A slipping foot's impulse is set this fraction of its radius: on its rim (to _residual's
#: 1e-9), never outside it by a rounding.
RIM = 1.0 - 1e-15
#: Most Newton iterations of one foot's disk-constrained step, and its tolerance on the radius.
MAX_DISK_ITERATIONS = 30
#: Most rounds of a solve: each turns at least one sticking foot that breaks away to kinetic.
MAX_ROUNDS = 5


@kernel
def _disk_step(b11, b12, b22, c1, c2, radius):
    """argmin of x.B x / 2 + c.x over the disk |x| <= radius (B symmetric positive definite, 2 x 2):
    the unconstrained minimum -B^-1 c if it lies inside, else x(nu) = -(B + nu I)^-1 c with
    |x(nu)| = radius, nu > 0 found by Newton's method on 1/radius - 1/|x(nu)| (More & Sorensen
    1983), which rises monotonically to the root from nu = 0."""
    if not radius > 0.0:
        return 0.0, 0.0
    nu = 0.0
    x1 = x2 = 0.0
    for it in range(MAX_DISK_ITERATIONS):
        d11, d22 = b11 + nu, b22 + nu
        det = d11 * d22 - b12 * b12
        x1 = -(d22 * c1 - b12 * c2) / det
        x2 = -(d11 * c2 - b12 * c1) / det
        r2 = x1 * x1 + x2 * x2
        if it == 0 and r2 <= radius * radius:
            return x1, x2
        r = math.sqrt(r2)
        if abs(r - radius) <= 1e-15 * radius:
            break
        # y = (B + nu I)^-1 x, and x.y = -d|x|^2/dnu / 2
        y1 = (d22 * x1 - b12 * x2) / det
        y2 = (d11 * x2 - b12 * x1) / det
        nu = nu + (r - radius) / radius * r2 / (x1 * y1 + x2 * y2)
    r = math.sqrt(x1 * x1 + x2 * x2)
    return x1 * (radius / r), x2 * (radius / r)


@kernel
def _post_slips(a_mat, slip, lam, active, out):
    """Each foot's slip after the impulses ``lam`` of the ``active`` feet, into ``out``."""
    for i in range(4):
        u1, u2 = slip[i, 0], slip[i, 1]
        for j in range(4):
            if active[j]:
                u1 += a_mat[i, 0, j, 0] * lam[j, 0] + a_mat[i, 0, j, 1] * lam[j, 1]
                u2 += a_mat[i, 1, j, 0] * lam[j, 0] + a_mat[i, 1, j, 1] * lam[j, 1]
        out[i, 0], out[i, 1] = u1, u2


@kernel
def _residual(a_mat, slip, lam, radius, active):
    """How far the impulses ``lam`` are from the solution, m/s: a foot inside its disk must not
    slip; one on its edge must slip straight against its impulse (maximum dissipation). The
    largest of the feet's violations."""
    worst = 0.0
    for i in range(4):
        if not active[i]:
            continue
        # foot i's slip after the impulses, as _post_slips sums it (no scratch array: this runs
        # at every sweep)
        u1, u2 = slip[i, 0], slip[i, 1]
        for j in range(4):
            if active[j]:
                u1 += a_mat[i, 0, j, 0] * lam[j, 0] + a_mat[i, 0, j, 1] * lam[j, 1]
                u2 += a_mat[i, 1, j, 0] * lam[j, 0] + a_mat[i, 1, j, 1] * lam[j, 1]
        l1, l2 = lam[i, 0], lam[i, 1]
        r = radius[i]
        l_norm2 = l1 * l1 + l2 * l2
        if not l_norm2 >= r * r * (1.0 - 1e-9) or not r > 0.0:
            worst = fmax(worst, math.sqrt(u1 * u1 + u2 * u2))  # inside: it must hold
        else:
            ln = math.sqrt(l_norm2)
            along = (u1 * l1 + u2 * l2) / ln  # must be <= 0: slipping against the impulse
            across = (u2 * l1 - u1 * l2) / ln
            worst = fmax(worst, fmax(abs(across), fmax(along, 0.0)))
    return worst


@kernel
def _gauss_seidel(a_mat, slip, radius, lam, active, early):
    """Projected block Gauss-Seidel on the feet's friction impulses: each sweep sets every active
    foot's impulse to its exact minimiser over its own disk with the others held, until the
    optimality conditions hold to SLIP_TOL_MPS (:func:`_residual`; the ship's motion is what is
    unique: several feet that hold together may share their load in many ways). Returns whether
    they did within MAX_SWEEPS.

    It gives up early where it would not get there: every CRAWL_SWEEPS sweeps, where the
    residual res_s, falling on at its rate since the last check, res_s (res_s / res_{s-c})^((
    MAX_SWEEPS - s) / c) (c = CRAWL_SWEEPS), would still be above CRAWL_MARGIN SLIP_TOL_MPS at
    MAX_SWEEPS (or has not fallen at all). The interior-point method then solves the problem
    from lam = 0, whatever the sweeps left. Of the solves that go to it (90 a touchdown in the
    envelope sweep), most give up after 6 sweeps (the first test that has a rate, c = 3; 10
    with c = 5 before, 30 before that): c = 3 rather than 5 sends 0.3 more solves a touchdown to
    the interior-point method (an interior-point solve costs about 40 sweeps) and spares 330 of
    a touchdown's 1,850 sweeps (issue 36, session 3's counts over 300 envelope touchdowns). A solve
    whose rate would have quickened enough to converge within MAX_SWEEPS is solved by the
    interior-point method instead, to its own accuracy (~1e-10 m/s) rather than to 1e-11: its
    bits change, its physics does not."""
    checkpoint = math.inf  # the residual CRAWL_SWEEPS sweeps ago
    last = math.inf  # the residual a sweep ago
    margin = CRAWL_MARGIN * SLIP_TOL_MPS
    n_active = 0
    for i in range(4):
        if active[i]:
            n_active += 1
    alone = n_active == 1
    for sweep in range(MAX_SWEEPS):
        for i in range(4):
            if not active[i]:
                continue
            c1, c2 = slip[i, 0], slip[i, 1]
            for j in range(4):
                if j != i and active[j]:
                    c1 += a_mat[i, 0, j, 0] * lam[j, 0] + a_mat[i, 0, j, 1] * lam[j, 1]
                    c2 += a_mat[i, 1, j, 0] * lam[j, 0] + a_mat[i, 1, j, 1] * lam[j, 1]
            x1, x2 = _disk_step(a_mat[i, 0, i, 0], a_mat[i, 0, i, 1], a_mat[i, 1, i, 1], c1, c2,
                                radius[i])
            lam[i, 0], lam[i, 1] = x1, x2
        res = _residual(a_mat, slip, lam, radius, active)
        if res <= SLIP_TOL_MPS:
            return True
        if alone:  # one foot's sweep is exact: the next ones repeat it, and the crawl test then
            return False  # gives up (no fall in the residual), as it would after 3-6 of them
        if early and sweep == 1:  # three or four feet: the rate over the second sweep
            if not res < last or res * (res / last) ** (MAX_SWEEPS - 2) > margin:
                return False
        last = res
        if (sweep + 1) % CRAWL_SWEEPS == 0:
            left = (MAX_SWEEPS - 1 - sweep) / CRAWL_SWEEPS
            if not res < checkpoint or res * (res / checkpoint) ** left > CRAWL_MARGIN * SLIP_TOL_MPS:
                return False
            checkpoint = res
    return False


@kernel
def _cholesky_factor(h_mat, n, l_mat, semidefinite):
    """The Cholesky factor L (H = L L^T) of the symmetric leading n x n block of ``h_mat``, into
    the scratch ``l_mat`` (8 x 8; every entry read is written first) with 1 / L_ii on its diagonal
    (the substitutions multiply: a division is ten multiplications' time). The pivot rule:
    positive definite (``semidefinite`` False), False returned where a pivot is not positive; or
    positive semidefinite (True), a pivot under FINISH_PIVOT times its diagonal entry (a
    direction the matrix does not see, to rounding) gets 1 / L_ii = 0, so
    :func:`_cholesky_substitute` leaves that direction's component at 0 (and its column's
    entries are 0), False returned where a pivot is negative beyond that. (A constant at each
    call: the rule's branch folds away where LLVM inlines it.)"""
    for i in range(n):
        for j in range(i + 1):
            acc = h_mat[i, j]
            for k in range(j):
                acc -= l_mat[i, k] * l_mat[j, k]
            if i != j:
                l_mat[i, j] = acc * l_mat[j, j]
            elif not semidefinite:
                if not acc > 0.0:
                    return False
                l_mat[i, i] = 1.0 / math.sqrt(acc)
            else:
                tol = FINISH_PIVOT * abs(h_mat[i, i])
                if acc > tol:
                    l_mat[i, i] = 1.0 / math.sqrt(acc)
                elif acc >= -1e3 * tol:
                    l_mat[i, i] = 0.0
                else:
                    return False
    return True


@kernel
def _cholesky_substitute(l_mat, rhs, n, out, y):
    """out = (L L^T)^-1 rhs for the factor of :func:`_cholesky_factor` (``y``: scratch, 8)."""
    for i in range(n):
        acc = rhs[i]
        for k in range(i):
            acc -= l_mat[i, k] * y[k]
        y[i] = acc * l_mat[i, i]
    for i in range(n - 1, -1, -1):
        acc = y[i]
        for k in range(i + 1, n):
            acc -= l_mat[k, i] * out[k]
        out[i] = acc * l_mat[i, i]


@kernel
def _active_set(a_loc, u0, rho, x, z, n_feet, out):
    """The interior-point method's finish (:func:`_interior_point`): from its iterate (x, z),
    guess which feet stick (their dual z_k near its apex) and which slip (lam_k near its rim),
    then Newton's method on the optimality conditions of that split, the slipping feet's
    impulses on their rims: with nu_k = -v_k.lam_k / rho_k^2 (foot k slips at
    v_k = -nu_k lam_k), the step dlam = Z y minimises the quadratic model
    (A + diag_slipping nu_k I) along Z, the sticking feet's two directions and each slipping
    foot's tangent to its rim (a sequential quadratic step with the multipliers estimated; one
    reduced Cholesky factorisation, semidefinite: several sticking feet share the ship's load in
    many ways). After each step the slipping feet go back onto their rims, a sticking foot
    pushed out of its disk slips, a slipping foot whose slip turned along its impulse sticks.
    Accepted where the optimality conditions hold to IPM_TOL_MPS (the measure of
    :func:`_residual`: a foot inside its disk holds, one on its rim slips straight against its
    impulse) within FINISH_ITERATIONS iterations: impulses into ``out``, returns 2 (else 1).
    Tried only where every foot reads clearly (by FINISH_CLEAR) as one or the other: else 0."""
    n = 2 * n_feet
    slips = stack_zeros(4, np.bool_)
    scale_s = 0.0  # (the largest slip before the impulses, as the method's start has it)
    for k in range(n_feet):
        scale_s = fmax(scale_s, math.sqrt(u0[2 * k] * u0[2 * k] + u0[2 * k + 1] * u0[2 * k + 1]))
    for k in range(n_feet):
        ln = math.sqrt(x[2 * k] * x[2 * k] + x[2 * k + 1] * x[2 * k + 1])
        far = (rho[k] - ln) / rho[k] * scale_s  # (primal distance to the rim, as a speed)
        tau = z[k, 0]
        if not (far > FINISH_CLEAR * tau or tau > FINISH_CLEAR * far):
            return 0
        slips[k] = tau > far
        if slips[k]:
            if not ln > 0.0:
                return 1
            out[2 * k], out[2 * k + 1] = x[2 * k] * (rho[k] * RIM / ln), x[2 * k + 1] * (rho[k] * RIM / ln)
        else:
            out[2 * k], out[2 * k + 1] = x[2 * k], x[2 * k + 1]
    return _active_newton(a_loc, u0, rho, slips, n_feet, out, (FINISH_ITERATIONS, FINISH_RATE))


@kernel
def _active_newton(a_loc, u0, rho, slips, n_feet, out, limits):
    """:func:`_active_set`'s Newton iterations from the impulses ``out`` (each slipping foot's on
    its rim) and the split ``slips`` (updated as it goes): the impulses into ``out``, returns 2
    where the optimality conditions hold to IPM_TOL_MPS within ``limits`` (most iterations, the
    fall of the residual an iteration must reach), else 1."""
    iterations, rate = limits
    n = 2 * n_feet
    vecs = stack_zeros((5, 8), np.float64)
    v, g, rg, y, dy = vecs[0], vecs[1], vecs[2], vecs[3], vecs[4]
    cols = stack_zeros((2, 8), np.float64)  # each reduced direction's two coefficients
    col_foot = stack_zeros(8, np.int64)
    mats = stack_zeros((2, 8, 8), np.float64)
    red, l_mat = mats[0], mats[1]
    nu = stack_zeros(4, np.float64)
    prev = math.inf
    for it in range(iterations + 1):
        # the slips at these impulses, and how far they are from the optimality conditions
        worst = 0.0
        for k in range(n_feet):
            i1, i2 = 2 * k, 2 * k + 1
            u1, u2 = u0[i1], u0[i2]
            for b in range(n):
                u1 += a_loc[i1, b] * out[b]
                u2 += a_loc[i2, b] * out[b]
            v[i1], v[i2] = u1, u2
            l1, l2 = out[i1], out[i2]
            r = rho[k]
            l_norm2 = l1 * l1 + l2 * l2
            if not l_norm2 >= r * r * (1.0 - 1e-9):
                worst = fmax(worst, math.sqrt(u1 * u1 + u2 * u2))
            else:
                ln = math.sqrt(l_norm2)
                along = (u1 * l1 + u2 * l2) / ln
                across = (u2 * l1 - u1 * l2) / ln
                worst = fmax(worst, fmax(abs(across), fmax(along, 0.0)))
        if worst <= IPM_TOL_MPS:
            return 2
        if it == iterations or not worst <= rate * prev:
            return 1  # (the last, or Newton's method is not converging fast: the IPM goes on)
        prev = worst
        turned = False
        for k in range(n_feet):
            i1, i2 = 2 * k, 2 * k + 1
            if slips[k] and v[i1] * out[i1] + v[i2] * out[i2] > 0.0:
                slips[k] = False  # its slip turned along its impulse: it sticks
                out[i1], out[i2] = out[i1] * (1.0 - 1e-6), out[i2] * (1.0 - 1e-6)
                turned = True
        if turned:
            for a in range(n):
                acc = u0[a]
                for b in range(n):
                    acc += a_loc[a, b] * out[b]
                v[a] = acc
        m = 0
        for k in range(n_feet):
            i1, i2 = 2 * k, 2 * k + 1
            if slips[k]:
                n1, n2 = out[i1] / rho[k], out[i2] / rho[k]
                nu[k] = -(v[i1] * n1 + v[i2] * n2) / rho[k]
                g[i1], g[i2] = v[i1] + nu[k] * out[i1], v[i2] + nu[k] * out[i2]
                cols[0, m], cols[1, m] = -n2, n1
                col_foot[m] = k
                m += 1
            else:
                nu[k] = 0.0
                g[i1], g[i2] = v[i1], v[i2]
                cols[0, m], cols[1, m] = 1.0, 0.0
                cols[0, m + 1], cols[1, m + 1] = 0.0, 1.0
                col_foot[m] = col_foot[m + 1] = k
                m += 2
        for c in range(m):
            fc = col_foot[c]
            p, q = cols[0, c], cols[1, c]
            rg[c] = -(p * g[2 * fc] + q * g[2 * fc + 1])
            for d in range(c + 1):
                fd = col_foot[d]
                pd, qd = cols[0, d], cols[1, d]
                h11 = a_loc[2 * fc, 2 * fd]
                h12 = a_loc[2 * fc, 2 * fd + 1]
                h21 = a_loc[2 * fc + 1, 2 * fd]
                h22 = a_loc[2 * fc + 1, 2 * fd + 1]
                if fc == fd:
                    h11 += nu[fc]
                    h22 += nu[fc]
                red[c, d] = p * (h11 * pd + h12 * qd) + q * (h21 * pd + h22 * qd)
        if not _cholesky_factor(red, m, l_mat, True):
            return 1
        _cholesky_substitute(l_mat, rg, m, dy, y)
        for c in range(m):
            fc = col_foot[c]
            out[2 * fc] += dy[c] * cols[0, c]
            out[2 * fc + 1] += dy[c] * cols[1, c]
        for k in range(n_feet):
            ln = math.sqrt(out[2 * k] * out[2 * k] + out[2 * k + 1] * out[2 * k + 1])
            if not ln < math.inf:
                return 1
            if slips[k] or ln > rho[k]:
                slips[k] = True
                if not ln > 0.0:
                    return 1
                out[2 * k], out[2 * k + 1] = out[2 * k] * (rho[k] * RIM / ln), out[2 * k + 1] * (rho[k] * RIM / ln)
    return 1


@kernel
def _cone_step(c, x0, x1, x2, d0, d1, d2):
    """The largest t with x + t d in the second-order cone x0 >= |(x1, x2)|, x strictly inside
    it with c = x0^2 - |(x1, x2)|^2 > 0 (given: the caller has it in a factored, accurate form):
    the first positive root of a t^2 + b t + c, the cone's edge along the line; inf if none. One
    root of the numerically stable pair c / q, q / a."""
    a = d0 * d0 - d1 * d1 - d2 * d2
    b = 2.0 * (x0 * d0 - x1 * d1 - x2 * d2)
    disc = b * b - 4.0 * a * c
    if a >= 0.0 and (b >= 0.0 or disc < 0.0):
        return math.inf  # (a convex quadratic, positive at 0: no positive root)
    sq = math.sqrt(fmax(disc, 0.0))
    if b < 0.0:
        return 2.0 * c / (sq - b)  # the smaller positive root (the only one if a < 0)
    return -0.5 * (b + sq) / a  # a < 0 <= b: the positive root


@kernel
def _scaled(eta, w, v0, v1, v2):
    """W v for the Nesterov-Todd scaling W = eta (2 w w^T - J) of a foot's cone pair (w^T J w = 1,
    J = diag(1, -1, -1); ``w`` = (w0, w1, w2, 1 / (1 + w0))):
    eta (w0 v0 - wb.vb, vb + (wb.vb / (1 + w0) - v0) wb)."""
    t = w[1] * v1 + w[2] * v2
    c = t * w[3] - v0
    return eta * (w[0] * v0 - t), eta * (v1 + c * w[1]), eta * (v2 + c * w[2])


@kernel
def _interior_point(a_mat, slip, radius, lam, active):
    """The same problem by a primal-dual interior-point method, for the footprints Gauss-Seidel
    crawls on: feet at different heights holding a rocking ship make the problem's matrix nearly
    singular (eigenvalues 1e-3 of the others, or 0: four feet have 8 slips, the ship 6 freedoms),
    and Gauss-Seidel then needs thousands of sweeps. Returns its Newton steps.

    As a cone program: each foot's s_k = (rho_k, lam_k) lies in the second-order cone
    Q = {(t, y): t >= |y|} (rho_k its disk's radius), its dual z_k = (tau_k, v_k) in Q too, and
    the optimality conditions are

        A lam + slip - v = 0,   s_k o z_k = (rho_k tau_k + lam_k.v_k, rho_k v_k + tau_k lam_k) = 0

    (v_k: foot k's slip after the impulses; o: Q's Jordan product): a foot inside its disk has no
    slip, a foot on its rim slips at tau_k straight against its impulse. Newton's method on them
    with s_k o z_k = sigma mu e in place of 0 (mu = sum_k s_k.z_k / feet), in the Nesterov-Todd
    scaling W_k = eta_k (2 w_k w_k^T - J) of each pair (W_k s_k = W_k^-1 z_k = l_k): each step

        (A + diag_k eta_k^2 (I + 2 wb_k wb_k^T)) dlam = -(A lam + slip - v) + [W_k xi_k]_(1,2),
        xi_k = l_k \\ c_k (the Jordan quotient),  dz_k = W_k (xi_k - W_k ds_k),  ds_k = (0, dlam_k),

    with Mehrotra's predictor-corrector: the affine step (c_k = -l_k o l_k) sets the centring
    sigma = (mu_aff / mu)^3 and the second-order term of the combined step (c_k = sigma mu e -
    l_k o l_k - (W_k ds_k) o (W_k^-1 dz_k)), both solved with one Cholesky factorisation; steps
    IPM_STEP of the way to the cones' edges. Vandenberghe, "The CVXOPT linear and quadratic cone
    program solvers" (2010: coneqp; here s_k's first entry is rho_k, so the primal iterates are
    feasible throughout); Mehrotra, SIAM J. Optim. 2 (1992). From lam = 0 and
    z_k = (|slip_k| + max_j |slip_j|, slip_k) (feasible, inside both cones), until a step moved
    no slip by more than IPM_TOL_MPS (with A lam + slip - v under it too), IPM_MAX_STEPS at most:
    8.7 steps a solve on the lander-like problems of docs/issue36/tools/pdipm_offline.py (the
    primal barrier method this replaced took 42), its slips within 1e-9 m/s of the exact
    solution's in all of them and 1e-10 in 99% (the barrier method's: 4e-9, 3e-9); checked on
    tilted landers' footprints against a long barrier solve in tests/test_friction_law.py."""
    idx = stack_zeros(4, np.int64)
    n_feet = 0
    scale_s = 0.0
    for i in range(4):
        if active[i] and radius[i] > 0.0:
            idx[n_feet] = i
            n_feet += 1
            scale_s = fmax(scale_s, math.sqrt(slip[i, 0] * slip[i, 0] + slip[i, 1] * slip[i, 1]))
        lam[i, 0] = lam[i, 1] = 0.0
    n = 2 * n_feet
    if n == 0 or not scale_s > 0.0:
        return 0
    if n_feet == 4:  # (the loops of four feet's known lengths: LLVM unrolls them; the same
        return _ipm_steps(a_mat, slip, radius, lam, idx, 4, scale_s)  # arithmetic, same bits)
    return _ipm_steps(a_mat, slip, radius, lam, idx, n_feet, scale_s)


@kernel
def _ipm_steps(a_mat, slip, radius, lam, idx, n_feet, scale_s):
    """:func:`_interior_point`'s steps for its ``n_feet`` feet ``idx`` (``scale_s``: the largest
    slip before the impulses; ``lam`` zeroed): its impulses into ``lam``, returns its steps."""
    n = 2 * n_feet
    # one scratch allocation each for the vectors, the matrices and the feet's cones (each a
    # malloc of its own costs as much as a Newton step's arithmetic)
    vecs = stack_zeros((7, 8), np.float64)
    x, u0, res, rhs, dx, y, rho = vecs[0], vecs[1], vecs[2], vecs[3], vecs[4], vecs[5], vecs[6]
    mats = stack_zeros((3, 8, 8), np.float64)
    a_loc, hess, l_mat = mats[0], mats[1], mats[2]
    cones = stack_zeros((8, 4, 4), np.float64)
    # z_k; w_k with 1 / (1 + w0); l_k = W_k s_k; xi_k; W_k ds_k and W_k^-1 dz_k of the predictor;
    # dz_k; (eta_k, 1 / det l_k, det s_k, det z_k)
    z, w, lsc, xi, wds, wdz, dz, scal = (cones[0], cones[1], cones[2], cones[3], cones[4],
                                         cones[5], cones[6], cones[7])
    for a in range(n):
        fa, ca = idx[a // 2], a % 2
        u0[a] = slip[fa, ca]
        for b in range(n):
            a_loc[a, b] = hess[a, b] = a_mat[fa, ca, idx[b // 2], b % 2]
    for k in range(n_feet):
        rho[k] = radius[idx[k]]
        z[k, 0] = math.sqrt(u0[2 * k] * u0[2 * k] + u0[2 * k + 1] * u0[2 * k + 1]) + scale_s
        z[k, 1], z[k, 2] = u0[2 * k], u0[2 * k + 1]
    steps = 0
    moved = math.inf
    gap_0 = 0.0
    tries = 0
    for _ in range(IPM_MAX_STEPS):
        gap = 0.0
        for k in range(n_feet):
            gap += rho[k] * z[k, 0] + x[2 * k] * z[k, 1] + x[2 * k + 1] * z[k, 2]
        mu = gap / n_feet
        if steps == 0:
            gap_0 = gap
        elif tries < 2 and gap < FINISH_GAPS[tries] * gap_0:
            tried = _active_set(a_loc, u0, rho, x, z, n_feet, dx)
            if tried == 2:
                for a in range(n):
                    x[a] = dx[a]
                break
            tries += tried
        worst = 0.0
        for a in range(n):
            acc = u0[a] - z[a // 2, 1 + a % 2]
            for b in range(n):
                acc += a_loc[a, b] * x[b]
            res[a] = -acc
            worst = fmax(worst, abs(acc))
        if worst <= IPM_TOL_MPS and moved <= IPM_TOL_MPS:
            break
        inside = True
        for k in range(n_feet):  # the Nesterov-Todd scaling of foot k's pair
            s0, s1, s2 = rho[k], x[2 * k], x[2 * k + 1]
            z0, z1, z2 = z[k, 0], z[k, 1], z[k, 2]
            s_n, z_n = math.sqrt(s1 * s1 + s2 * s2), math.sqrt(z1 * z1 + z2 * z2)
            s_det, z_det = (s0 - s_n) * (s0 + s_n), (z0 - z_n) * (z0 + z_n)
            if not (s_det > 0.0 and z_det > 0.0):
                inside = False  # rounding has reached a cone's edge: keep this point
                break
            s_i, z_i = 1.0 / math.sqrt(s_det), 1.0 / math.sqrt(z_det)
            s0, s1, s2 = s0 * s_i, s1 * s_i, s2 * s_i
            z0, z1, z2 = z0 * z_i, z1 * z_i, z2 * z_i
            g_i = 1.0 / math.sqrt(2.0 * (1.0 + s0 * z0 + s1 * z1 + s2 * z2))
            w0, w1, w2 = (s0 + z0) * g_i, (s1 - z1) * g_i, (s2 - z2) * g_i
            wk = (w0, w1, w2, 1.0 / (1.0 + w0))
            w[k, 0], w[k, 1], w[k, 2], w[k, 3] = wk
            e2 = s_i / z_i  # eta_k^2 = sqrt(det z_k / det s_k)
            eta = math.sqrt(e2)
            scal[k, 0], scal[k, 1], scal[k, 2], scal[k, 3] = eta, s_i * z_i, s_det, z_det
            # (hess is a_loc off its feet's 2 x 2 diagonal blocks: those are set at every step)
            hess[2 * k, 2 * k] = a_loc[2 * k, 2 * k] + e2 * (1.0 + 2.0 * w1 * w1)
            hess[2 * k + 1, 2 * k + 1] = a_loc[2 * k + 1, 2 * k + 1] + e2 * (1.0 + 2.0 * w2 * w2)
            hess[2 * k + 1, 2 * k] = a_loc[2 * k + 1, 2 * k] + e2 * 2.0 * w1 * w2
            l0, l1, l2 = _scaled(eta, wk, rho[k], x[2 * k], x[2 * k + 1])
            lsc[k, 0], lsc[k, 1], lsc[k, 2], lsc[k, 3] = l0, l1, l2, 1.0 / l0
        if not inside or not _cholesky_factor(hess, n, l_mat, False):
            break  # numerically singular: keep the last point (inside every cone)
        sigma = 0.0
        step = 0.0
        for phase in range(2):  # Mehrotra's predictor (affine), then the combined step
            for a in range(n):
                rhs[a] = res[a]
            for k in range(n_feet):
                l0, l1, l2 = lsc[k, 0], lsc[k, 1], lsc[k, 2]
                c0 = -(l0 * l0 + l1 * l1 + l2 * l2)
                c1, c2 = -2.0 * l0 * l1, -2.0 * l0 * l2
                if phase == 1:
                    a0, a1, a2 = wds[k, 0], wds[k, 1], wds[k, 2]
                    b0, b1, b2 = wdz[k, 0], wdz[k, 1], wdz[k, 2]
                    c0 += sigma * mu - (a0 * b0 + a1 * b1 + a2 * b2)
                    c1 -= a0 * b1 + b0 * a1
                    c2 -= a0 * b2 + b0 * a2
                q0 = (l0 * c0 - l1 * c1 - l2 * c2) * scal[k, 1]  # xi_k = l_k \ c_k
                q1, q2 = (c1 - q0 * l1) * lsc[k, 3], (c2 - q0 * l2) * lsc[k, 3]
                xi[k, 0], xi[k, 1], xi[k, 2] = q0, q1, q2
                wk = (w[k, 0], w[k, 1], w[k, 2], w[k, 3])
                _, r1, r2 = _scaled(scal[k, 0], wk, q0, q1, q2)
                rhs[2 * k] += r1
                rhs[2 * k + 1] += r2
            _cholesky_substitute(l_mat, rhs, n, dx, y)
            alpha = 1.0
            for k in range(n_feet):
                eta, wk = scal[k, 0], (w[k, 0], w[k, 1], w[k, 2], w[k, 3])
                d1, d2 = dx[2 * k], dx[2 * k + 1]
                a0, a1, a2 = _scaled(eta, wk, 0.0, d1, d2)  # W_k ds_k
                b0, b1, b2 = xi[k, 0] - a0, xi[k, 1] - a1, xi[k, 2] - a2  # W_k^-1 dz_k
                e0, e1, e2 = _scaled(eta, wk, b0, b1, b2)
                if phase == 0:
                    wds[k, 0], wds[k, 1], wds[k, 2] = a0, a1, a2
                    wdz[k, 0], wdz[k, 1], wdz[k, 2] = b0, b1, b2
                dz[k, 0], dz[k, 1], dz[k, 2] = e0, e1, e2
                alpha = fmin(alpha, _cone_step(scal[k, 2], rho[k], x[2 * k], x[2 * k + 1], 0.0,
                                               d1, d2))
                alpha = fmin(alpha, _cone_step(scal[k, 3], z[k, 0], z[k, 1], z[k, 2], e0, e1,
                                               e2))
            if phase == 0:  # the centring: how far the affine step would take the gap
                gap_aff = 0.0
                for k in range(n_feet):
                    gap_aff += (rho[k] * (z[k, 0] + alpha * dz[k, 0])
                                + (x[2 * k] + alpha * dx[2 * k]) * (z[k, 1] + alpha * dz[k, 1])
                                + (x[2 * k + 1] + alpha * dx[2 * k + 1])
                                * (z[k, 2] + alpha * dz[k, 2]))
                ratio = fmax(0.0, fmin(1.0, gap_aff / gap))
                sigma = ratio * ratio * ratio
            else:
                step = fmin(1.0, IPM_STEP * alpha)
        if not step > 0.0:
            break
        moved = 0.0
        for k in range(n_feet):
            moved = fmax(moved, step * fmax(abs(dz[k, 1]), abs(dz[k, 2])))
        if not moved < math.inf:
            break  # (not finite: keep the last point)
        for a in range(n):
            x[a] += step * dx[a]
        for k in range(n_feet):
            z[k, 0] += step * dz[k, 0]
            z[k, 1] += step * dz[k, 1]
            z[k, 2] += step * dz[k, 2]
        steps += 1
    for k in range(n_feet):
        lam[idx[k], 0], lam[idx[k], 1] = x[2 * k], x[2 * k + 1]
    return steps


@kernel
def _from_carried(a_mat, slip, radius, lam, active, rate):
    """The feet's impulses by the active-set Newton iterations alone (:func:`_active_newton`,
    the interior-point method's finish), from the impulses ``lam`` the solve starts with (the
    holding feet's friction carried in from the last step): a foot whose carried impulse is on
    its rim (to CARRIED_RIM) or none slips, the others stick; a slipping foot that carried none
    starts on its rim against its slip at the others' impulses. Accepted only where the
    optimality conditions then hold to IPM_TOL_MPS within CARRIED_ITERATIONS (the interior-point
    method's own acceptance, the measure of :func:`_residual`: the slips after are the
    solution's, which are unique; how several sticking feet share the load, which is not, may
    differ): the impulses into ``lam``, returns True; else False, ``lam`` untouched. Given up
    early where the residual grows ``rate`` times in an iteration (math.inf: never)."""
    idx = stack_zeros(4, np.int64)
    n_feet = 0
    for i in range(4):
        if active[i] and radius[i] > 0.0:
            idx[n_feet] = i
            n_feet += 1
    n = 2 * n_feet
    if n_feet == 0:
        return False
    vecs = stack_zeros((3, 8), np.float64)
    u0, rho, out = vecs[0], vecs[1], vecs[2]
    a_loc = stack_zeros((8, 8), np.float64)
    slips = stack_zeros(4, np.bool_)
    for a in range(n):
        fa, ca = idx[a // 2], a % 2
        u0[a] = slip[fa, ca]
        for b in range(n):
            a_loc[a, b] = a_mat[fa, ca, idx[b // 2], b % 2]
    for k in range(n_feet):
        r = radius[idx[k]]
        rho[k] = r
        l1, l2 = lam[idx[k], 0], lam[idx[k], 1]
        l_norm2 = l1 * l1 + l2 * l2
        slips[k] = l_norm2 >= (CARRIED_RIM * r) ** 2 or l_norm2 == 0.0
        if slips[k] and l_norm2 > 0.0:
            ln = math.sqrt(l_norm2)
            out[2 * k], out[2 * k + 1] = l1 * (r * RIM / ln), l2 * (r * RIM / ln)
        else:
            out[2 * k], out[2 * k + 1] = l1, l2
    for k in range(n_feet):
        if slips[k] and out[2 * k] == 0.0 and out[2 * k + 1] == 0.0:
            u1, u2 = u0[2 * k], u0[2 * k + 1]
            for b in range(n):
                u1 += a_loc[2 * k, b] * out[b]
                u2 += a_loc[2 * k + 1, b] * out[b]
            un = math.sqrt(u1 * u1 + u2 * u2)
            if not un > 0.0:
                return False
            out[2 * k], out[2 * k + 1] = -u1 * (rho[k] * RIM / un), -u2 * (rho[k] * RIM / un)
    if _active_newton(a_loc, u0, rho, slips, n_feet, out, (CARRIED_ITERATIONS, rate)) != 2:
        return False
    for i in range(4):
        lam[i, 0] = lam[i, 1] = 0.0
    for k in range(n_feet):
        lam[idx[k], 0], lam[idx[k], 1] = out[2 * k], out[2 * k + 1]
    return True


@kernel
def _solve_feet(a_mat, slip, radius, lam, active, try_pairs=True):
    """The feet's friction impulses that take the most kinetic energy out of the ship, each in its
    own disk (maximum dissipation, with the normal impulses given): Gauss-Seidel, and where it
    does not converge within MAX_SWEEPS (or crawls: :func:`_gauss_seidel`), the interior-point
    method. Three or four feet that Gauss-Seidel gives up on (97% of them in the envelope sweep:
    they slip against one another by a hair) try the active-set solve from the impulses carried
    in before the interior-point method (:func:`_from_carried`: 60% of them settled there; issue
    36, session 10). After Gauss-Seidel, not before: where it converges (a ship upright on level
    ground, its feet sticking alike) its sweeps cost a fraction of the try. ``try_pairs``
    (sim.carried_try_pairs, MODEL-NOTES 64): the try is for two or three feet instead, to its
    last iteration (two feet slipping against each other by a hair, on their rims, are where
    Gauss-Seidel gives up on two; four feet's try settled 3%). Returns 1 (Gauss-Seidel) or 2
    (the others)."""
    n_active = 0
    for i in range(4):
        if active[i]:
            n_active += 1
    carried = stack_zeros((4, 2), np.float64)
    for i in range(4):
        carried[i, 0], carried[i, 1] = lam[i, 0], lam[i, 1]
    if _gauss_seidel(a_mat, slip, radius, lam, active, n_active >= 3):
        return 1
    if try_pairs:
        tried = PAIRS_FEET[0] <= n_active <= PAIRS_FEET[1]
        rate = math.inf  # a guessed split's first iterations may move its residual up first
    else:
        tried = n_active >= 3
        rate = CARRIED_RATE
    if tried:
        # the try starts from the carried impulses, not from what the sweeps left
        for i in range(4):
            lam[i, 0], lam[i, 1] = carried[i, 0], carried[i, 1]
        if _from_carried(a_mat, slip, radius, lam, active, rate):
            return 2
    _interior_point(a_mat, slip, radius, lam, active)
    return 2


#: A footprint whose centre (its feet's load-weighted mean) slips slower than this after the
#: impulses is at rest (m/s), and held in place (step.substep, :func:`hold_footprint`). Not zero:
#: its feet may slip against each other by a hair, as four rigid feet
#: a micrometre apart in height under a ship that rocks at 1e-4 rad/s must slip against each other
#: by ~1e-7 m/s, which only impulses far beyond their cones could stop; the legs' compliance, which
#: the rigid model leaves out, takes that in a real lander (MODEL-NOTES 23).
AT_REST_MPS = 1e-5


@kernel
def _slipping(a_mat, slip, lam, active, stick_speed_mps):
    """Which pressing feet still slip faster than ``stick_speed_mps`` after the impulses ``lam``."""
    out = (False, False, False, False)
    tol2 = stick_speed_mps * stick_speed_mps
    for i in range(4):
        if not active[i]:
            continue
        u1, u2 = slip[i, 0], slip[i, 1]
        for j in range(4):
            if active[j]:
                u1 += a_mat[i, 0, j, 0] * lam[j, 0] + a_mat[i, 0, j, 1] * lam[j, 1]
                u2 += a_mat[i, 1, j, 0] * lam[j, 0] + a_mat[i, 1, j, 1] * lam[j, 1]
        moves = u1 * u1 + u2 * u2 > tol2
        out = (out[0] or (i == 0 and moves), out[1] or (i == 1 and moves),
               out[2] or (i == 2 and moves), out[3] or (i == 3 and moves))
    return out


@kernel
def _moving(after, pressing, stick_speed_mps):
    """Which pressing feet slip faster than ``stick_speed_mps`` (their slips ``after``, as
    :func:`_post_slips` leaves them)."""
    tol2 = stick_speed_mps * stick_speed_mps
    return (pressing[0] and after[0, 0] * after[0, 0] + after[0, 1] * after[0, 1] > tol2,
            pressing[1] and after[1, 0] * after[1, 0] + after[1, 1] * after[1, 1] > tol2,
            pressing[2] and after[2, 0] * after[2, 0] + after[2, 1] * after[2, 1] > tol2,
            pressing[3] and after[3, 0] * after[3, 0] + after[3, 1] * after[3, 1] > tol2)


@kernel
def _dragged_only(law, rigid, stepped, end, j_n, normals, sliding):
    """:func:`coulomb` where no pressing foot takes an impulse (each is dragged by its friction as
    a force, or none presses): the same numbers, without the solve's arrays. The slips after are
    the slips before (the solve adds no impulse to them), each foot kinetic while it slips faster
    than the stick speed; one sweep, as the solve counts a solve with nothing to do."""
    mu_k, vel_mps, omega_b = law.mu_k, stepped.v, stepped.w
    ground, ft = end
    omega_w = quat_rotate(stepped.q, omega_b)
    inv_m = 1.0 / rigid.mass_kg
    tol2 = law.stick_speed_mps * law.stick_speed_mps
    drag = 0.0
    mean = (0.0, 0.0, 0.0)
    j_sum = 0.0
    kin = (False, False, False, False)
    for i in range(4):
        if not j_n[i] > 0.0:
            continue  # (not pressing: not kinetic, not in the mean)
        drag = drag + mu_k * j_n[i]
        t1, t2 = tangent_basis(normals[i])
        u = foot_velocity(ground, vel_mps, omega_w, ft.offset_w[i], ft.pos_w[i])
        u1, u2 = dot(u, t1), dot(u, t2)
        moves = u1 * u1 + u2 * u2 > tol2
        mean = add(mean, scale(add(scale(t1, u1), scale(t2, u2)), j_n[i]))
        j_sum = j_sum + j_n[i]
        kin = (kin[0] or (i == 0 and moves), kin[1] or (i == 1 and moves),
               kin[2] or (i == 2 and moves), kin[3] or (i == 3 and moves))
    held = j_sum > 0.0 and norm(mean) <= AT_REST_MPS * j_sum
    for i in range(4):
        held = held and not (j_n[i] > 0.0 and (sliding[i] or kin[i]))
    z = (0.0, 0.0, 0.0)
    return Friction(add(vel_mps, scale(z, inv_m)), add(omega_b, z), kin, drag, 1, held,
                    (z, z, z, z))


# (inlined into its one caller, sim.flight.substep: no call passing the step and the feet by
# value; session15-glue)
@kernel
def coulomb(law, rigid, stepped, end, sliding, friction_force, h):
    """Coulomb friction at each pressing foot (module docstring) of a ship of mass m and principal
    inertia I (``rigid``, a :class:`Rigid`), after a step of length h (``stepped``: its end state and each foot's normal impulse
    J_i, sim.integrators.Stepped). ``friction_force``: the friction that acted as a force during
    the step (sim.contact.FrictionForce): the feet of its ``kinetic`` were dragged by mu_k N_i
    (sim.contact.evaluate) and take no impulse; its ``hold_w`` carried the holding feet's static
    friction in. Each other foot's impulse lies in its disk: mu_k J_i if it slides (``sliding``,
    its regime at the step's start), mu_s J_i if it holds (mu_k J_i if it breaks away). ``end``
    (a :class:`FeetOn`): the feet at the step's end state, on the ground as it is then."""
    mu_s, mu_k, stick_speed_mps = law.mu_s, law.mu_k, law.stick_speed_mps
    mass_kg, inertia_kgm2 = rigid
    ground, ft = end
    pos_m, vel_mps, quat, omega_b = stepped.p, stepped.v, stepped.q, stepped.w
    foot_impulse_ns = stepped.foot_impulse_ns
    dragged, hold_w = friction_force.kinetic, friction_force.hold_w
    j_n = (fmax(foot_impulse_ns[0], 0.0), fmax(foot_impulse_ns[1], 0.0),
           fmax(foot_impulse_ns[2], 0.0), fmax(foot_impulse_ns[3], 0.0))
    normals = _pressing_normals(pos_m, ft, j_n)
    omega_w = quat_rotate(quat, omega_b)
    inv_m = 1.0 / mass_kg
    if not ((j_n[0] > 0.0 and not dragged[0]) or (j_n[1] > 0.0 and not dragged[1])
            or (j_n[2] > 0.0 and not dragged[2]) or (j_n[3] > 0.0 and not dragged[3])):
        return _dragged_only(law, rigid, stepped, end, j_n, normals, sliding)
    # the solve's arrays as views of five scratch allocations (thirteen mallocs were a fifth of
    # the solve's cost where no foot's impulse is solved for; a view by its first index is
    # pointer arithmetic, a reshape a call)
    bases = stack_zeros((3, 4, 2, 3), np.float64)
    tang = bases[0]  # each foot's tangent basis
    turn = bases[1]  # I^-1 R^T (r_i x t): the body-frame turn per unit impulse
    lever = bases[2]  # R^T (r_i x t)
    per_foot = stack_zeros((4, 4, 2), np.float64)
    slip = per_foot[0]
    lam = per_foot[1]
    carried = per_foot[2]  # h F_i on each holding foot's basis
    after = per_foot[3]
    radius = stack_zeros(4, np.float64)
    a_mat = stack_zeros((4, 2, 4, 2), np.float64)
    flags = stack_zeros((3, 4), np.bool_)
    pressing = flags[0]
    active = flags[1]  # the feet whose impulses are solved for
    kinetic = flags[2]  # their disks: mu_k (sliding, or broke away) or mu_s
    drag = 0.0  # what the dragged feet's force took over the step, ~ mu_k J_i
    for i in range(4):
        pressing[i] = j_n[i] > 0.0
        active[i] = pressing[i] and not dragged[i]
        kinetic[i] = active[i] and sliding[i]
        if pressing[i] and dragged[i]:
            drag = drag + mu_k * j_n[i]
        if not pressing[i]:
            continue  # (nothing reads a foot's basis, slip or rows where it does not press)
        t1, t2 = tangent_basis(normals[i])
        u = foot_velocity(ground, vel_mps, omega_w, ft.offset_w[i], ft.pos_w[i])
        slip[i, 0], slip[i, 1] = dot(u, t1), dot(u, t2)
        g1 = quat_rotate_inv(quat, cross(ft.offset_w[i], t1))
        g2 = quat_rotate_inv(quat, cross(ft.offset_w[i], t2))
        w1, w2 = div(g1, inertia_kgm2), div(g2, inertia_kgm2)
        for k in range(3):
            tang[i, 0, k], tang[i, 1, k] = t1[k], t2[k]
            lever[i, 0, k], lever[i, 1, k] = g1[k], g2[k]
            turn[i, 0, k], turn[i, 1, k] = w1[k], w2[k]
    for i in range(4):
        if active[i]:
            for a in range(2):
                carried[i, a] = h * (hold_w[i][0] * tang[i, a, 0] + hold_w[i][1] * tang[i, a, 1]
                                     + hold_w[i][2] * tang[i, a, 2])
    # the Delassus matrix: the change of foot i's slip along t_ia per unit impulse along t_jb;
    # only its columns of active feet are ever read with an impulse that is not zero (where no
    # foot is active, the slips after are the slips before: the zeros leave them as they are).
    # Its block of active feet is symmetric (G M^-1 G^T): computed on and above the diagonal
    # and mirrored (36 entries of four feet's 64; the solvers assume the symmetry)
    for i in range(4):
        if not pressing[i]:
            continue
        for a in range(2):
            for j in range(4):
                if not active[j] or (active[i] and j < i):
                    continue
                for b in range(2):
                    if active[i] and j == i and b < a:
                        continue
                    a_mat[i, a, j, b] = (inv_m * (tang[i, a, 0] * tang[j, b, 0]
                                                  + tang[i, a, 1] * tang[j, b, 1]
                                                  + tang[i, a, 2] * tang[j, b, 2])
                                         + lever[i, a, 0] * turn[j, b, 0]
                                         + lever[i, a, 1] * turn[j, b, 1]
                                         + lever[i, a, 2] * turn[j, b, 2])
                    if active[i]:
                        a_mat[j, b, i, a] = a_mat[i, a, j, b]
    # the slips less the carried forces' share; solve for the whole impulses
    for i in range(4):
        for a in range(2):
            for j in range(4):
                if active[j] and pressing[i]:
                    slip[i, a] -= (a_mat[i, a, j, 0] * carried[j, 0]
                                   + a_mat[i, a, j, 1] * carried[j, 1])
            lam[i, a] = carried[i, a] if active[i] else 0.0
    sweeps = 0
    for _ in range(MAX_ROUNDS):
        for i in range(4):
            radius[i] = (mu_k if kinetic[i] else mu_s) * j_n[i] if active[i] else 0.0
        sweeps += _solve_feet(a_mat, slip, radius, lam, active, law.try_pairs)
        # A held foot that the solve leaves slipping faster than the stick speed breaks away:
        # kinetic for the whole step. A full disk alone is not slipping: which of several
        # holding feet takes how much is not unique, and Gauss-Seidel fills the first ones first.
        _post_slips(a_mat, slip, lam, pressing, after)
        moving = _moving(after, pressing, stick_speed_mps)
        broke = False
        for i in range(4):
            if active[i] and moving[i] and not kinetic[i]:
                kinetic[i] = True
                broke = True
        if not broke:
            break
    # (moving and after: the last round's, at the impulses the loop ends with; MAX_ROUNDS >= 1)
    # held: no foot slides, and the footprint as a whole (its load-weighted mean slip) is at rest.
    # Feet of one footprint may still slip against each other by a hair: the rigid model's
    # redundancy (see AT_REST_MPS), which only the footprint's centre would carry it away with.
    mean = (0.0, 0.0, 0.0)
    j_sum = 0.0
    for i in range(4):
        if pressing[i]:
            u_w = add(scale((tang[i, 0, 0], tang[i, 0, 1], tang[i, 0, 2]), after[i, 0]),
                      scale((tang[i, 1, 0], tang[i, 1, 1], tang[i, 1, 2]), after[i, 1]))
            mean = add(mean, scale(u_w, j_n[i]))
            j_sum = j_sum + j_n[i]
    held = j_sum > 0.0 and norm(mean) <= AT_REST_MPS * j_sum
    d_vel = (0.0, 0.0, 0.0)
    d_omega = (0.0, 0.0, 0.0)
    z = (0.0, 0.0, 0.0)
    new_hold = (z, z, z, z)
    total = drag
    for i in range(4):
        # each pressing foot's regime for the next step: kinetic while it slips faster than the
        # stick speed (a sliding foot that slowed under it holds from now on)
        kinetic[i] = pressing[i] and moving[i]
        held = held and not (pressing[i] and (sliding[i] or moving[i]))
        if not active[i]:
            continue
        whole = add(scale((tang[i, 0, 0], tang[i, 0, 1], tang[i, 0, 2]), lam[i, 0]),
                    scale((tang[i, 1, 0], tang[i, 1, 1], tang[i, 1, 2]), lam[i, 1]))
        if not kinetic[i]:  # it holds: its friction is carried into the next step
            hold = (whole[0] / h, whole[1] / h, whole[2] / h)
            new_hold = (hold if i == 0 else new_hold[0], hold if i == 1 else new_hold[1],
                        hold if i == 2 else new_hold[2], hold if i == 3 else new_hold[3])
        f_i = add(scale((tang[i, 0, 0], tang[i, 0, 1], tang[i, 0, 2]), lam[i, 0] - carried[i, 0]),
                  scale((tang[i, 1, 0], tang[i, 1, 1], tang[i, 1, 2]), lam[i, 1] - carried[i, 1]))
        d_vel = add(d_vel, f_i)
        c0, c1 = lam[i, 0] - carried[i, 0], lam[i, 1] - carried[i, 1]
        d_omega = add(d_omega, add(scale((turn[i, 0, 0], turn[i, 0, 1], turn[i, 0, 2]), c0),
                                   scale((turn[i, 1, 0], turn[i, 1, 1], turn[i, 1, 2]), c1)))
        total = total + math.sqrt(lam[i, 0] * lam[i, 0] + lam[i, 1] * lam[i, 1])
    vel = add(vel_mps, scale(d_vel, inv_m))
    omega = add(omega_b, d_omega)
    return Friction(vel, omega, (kinetic[0], kinetic[1], kinetic[2], kinetic[3]), total, sweeps,
                    held, new_hold)


@kernel
def seed(law, mass_kg, pos_m, vel_mps, omega_b, normal_impulse_ns, ground):
    """The seed's law at the centre of mass (module docstring)."""
    mu_s, mu_k = law.mu_s, law.mu_k
    stick_speed_mps = SEED_STICK_SPEED_MPS  # the seed's own 0.01 m/s, whatever contact.stick_speed
    n_hat = unit(pos_m)
    v_rel = sub(vel_mps, surface_velocity(ground, pos_m))
    v_t = sub(v_rel, scale(n_hat, dot(v_rel, n_hat)))
    s = norm(v_t)
    moving = s > 0.0
    sf = s if moving else 1.0
    t_hat = (v_t[0] / sf, v_t[1] / sf, v_t[2] / sf)
    j_n = fmax(normal_impulse_ns, 0.0)
    lim_s, lim_k = mu_s * j_n, mu_k * j_n
    j_stop = mass_kg * s
    if s > stick_speed_mps:
        j = lim_k
    else:
        j = j_stop if j_stop <= lim_s else lim_k
    if not (moving and j_n > 0.0):
        j = 0.0
    vel = sub(vel_mps, scale(t_hat, j / mass_kg))
    still = s - j / mass_kg > stick_speed_mps and moving
    z = (0.0, 0.0, 0.0)
    return Friction(vel, omega_b, (still, still, still, still), j, 0, False, (z, z, z, z))
