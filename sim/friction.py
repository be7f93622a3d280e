"""Coulomb friction at the feet that press, applied as impulses after each (sub)step.

Touchdown's law (``friction_model = "coulomb"``, SEED-NOTES 4, MODEL-NOTES 23). Each foot that
pressed during the step has its own Coulomb cone: with J_i its normal impulse over the step (what
the integrator applied), its friction impulse lies in the ground's tangent plane there, bounded by
mu J_i. The feet are coupled through the rigid ship, and they are solved together as the
footprint's three tangential freedoms (its slip at the centre of pressure, and its spin about the
ground's normal; the contact patch of Howe & Cutkosky, Int. J. Robotics Research 15, 1996):

* stick: the impulse that stops the footprint (translation and spin) exactly, through the ship's
  3 x 3 effective-mass matrix there, if its share at every foot (the force in proportion to the
  foot's load, the moment in proportion to load times lever) fits that foot's disk mu_s J_i;
* slide: otherwise each foot carries mu_k J_i against its own slip: a slide decelerates at
  mu_k g, four feet damp a spin about the long axis at mu_k m g a / I_z, and a sliding, spinning
  footprint couples the two as four feet do;
* a sliding footprint whose stop impulse fits the mu_k disks stops (never overshooting zero);
  a sticking one that needs more than mu_s J breaks away.

Why not four rigid feet each held to zero slip: on a tilted ship that is eight conditions on six
velocities, two of them all but redundant (the fore and aft feet differ in height by a sin(tilt),
so only a pitch rate can make their slips differ: eigenvalues 1e-7 of the others, measured), and
stopping that differential slip takes internal impulses of 1e5 N s. The footprint's freedoms are
what friction can hold; the rest is compliance the rigid model does not have.

Everything is evaluated at the step's end state: the feet where they are, their slip relative to
the surface under them (Omega z x foot on a rotating body), in the tangent plane of the terrain
there (its slope on the ship's local vertical: the sphere's curvature across the footprint, a / R,
is left out of the friction planes). A ship held on a slope does not creep.

The impulse stands for a force that acted throughout the step, so the step's drift is corrected for
it (:func:`spread_over_step`): without that, the drift uses the speed from before the impulse, a
slide overshoots by mu_k g h T / 2 (first order in the step h) and a ship held on a slope creeps
by a h^2 / 2 a step.

The seed's law (``"seed"``): kinetic above 0.01 m/s with no stopping test, else reset the centre of
mass's tangential velocity, falling back to kinetic friction beyond mu_s N; it acts at the centre
of mass (no moment). Kept reachable for comparison; it 2-cycles and creeps as SEED-NOTES 4 shows.
"""
from __future__ import annotations

import numpy as np

from sim import vec
from sim.constants import STICK_SPEED_MPS
from sim.contact import Feet, Four, Ground

Array = np.ndarray

#: A footprint with less than this much of its load's lever (sum of J_i |rho_i|^2 over sum J_i, m^2)
#: is a point: it has no torsional friction (leg_radius = 0, or one foot pressing).
POINT_CONTACT_M2 = 1e-12


def spread_over_step(pos_m: Array, quat: Array, vel_before: Array, vel_after: Array,
                     omega_before: Array, omega_after: Array,
                     h: float | Array) -> tuple[Array, Array]:
    """Position and attitude as if the friction impulse had acted evenly over the step of length
    h: a velocity change dv spread over the step changes its drift by h dv / 2 (dv opposes the
    slip, so the ship ends short of where its speed before the impulse took it), and likewise
    for the turn. Exact for a constant friction force; a ship held at rest by static friction
    then stays exactly where it is."""
    h_col = h if np.ndim(h) == 0 else np.asarray(h)[:, None]
    pos = pos_m + 0.5 * h_col * (vel_after - vel_before)
    d_omega = omega_after - omega_before
    turned = (d_omega[:, 0] != 0.0) | (d_omega[:, 1] != 0.0) | (d_omega[:, 2] != 0.0)
    # a ship that friction did not turn keeps its attitude's bits (renormalising would not)
    quat = np.where(turned[:, None], vec.quat_integrate(quat, d_omega, 0.5 * np.asarray(h)), quat)
    return pos, quat


def _tangent_basis(n_hat: Array) -> tuple[Array, Array]:
    """Two unit vectors spanning the plane normal to n_hat (any orientation; chosen per ship from
    its own n_hat alone)."""
    ref = np.zeros_like(n_hat)
    use_z = np.abs(n_hat[:, 2]) < 0.9
    ref[:, 2] = np.where(use_z, 1.0, 0.0)
    ref[:, 0] = np.where(use_z, 0.0, 1.0)
    t1 = vec.unit(vec.cross(ref, n_hat))
    return t1, vec.cross(n_hat, t1)


def _patch(pos_m: Array, ft: Feet, j_n: list[Array]) -> tuple[list[Array], Array, Array]:
    """Each foot's friction plane normal, and the footprint's: the load-weighted normal and the
    centre of pressure (weights: the feet's normal impulses). A foot's plane is the terrain's
    slope under it on the ship's local vertical: the sphere's own curvature across the footprint
    (a / R, 1e-6 rad) would make a straight descent slip every foot inwards."""
    up = vec.unit(pos_m)
    j_sum = ((j_n[0] + j_n[1]) + j_n[2]) + j_n[3]
    pressed = j_sum > 0.0
    normals = [vec.unit(ft.push_w[i] - vec.unit(ft.pos_w[i]) + up) for i in range(4)]
    n_bar = vec.unit(sum((vec.scale(normals[i], j_n[i]) for i in range(1, 4)),
                         vec.scale(normals[0], j_n[0])))
    n_bar = np.where(pressed[:, None], n_bar, up)
    centre = sum((vec.scale(ft.pos_w[i], j_n[i]) for i in range(1, 4)),
                 vec.scale(ft.pos_w[0], j_n[0])) / np.where(pressed, j_sum, 1.0)[:, None]
    return normals, n_bar, np.where(pressed[:, None], centre, pos_m)


def hold_footprint(pos_m: Array, ft_start: Feet, ft_end: Feet, foot_impulse_ns: Four,
                   held: Array, cos_turn: float | Array, sin_turn: float | Array) -> Array:
    """The ship moved so that a footprint held by static friction through the whole step (``held``)
    ends exactly where the ground has carried the point it stood on (the ground turning by the
    angle of (cos_turn, sin_turn) about z over the step): the position-level half of sticking.
    The velocity-level half (the stop impulse) and the spread of its drift over the step leave a
    residue when a held foot's slip does not grow evenly within the step (a held ship on a
    rotating body, whose ground curves away under its straight inertial step, crept 0.5 m an hour
    at 25 ms sub-steps without this); only the drift along the ground is undone."""
    j_n = [np.maximum(j, 0.0) for j in foot_impulse_ns]
    _, _, start = _patch(pos_m, ft_start, j_n)
    _, n_bar, end = _patch(pos_m, ft_end, j_n)
    carried = start.copy()
    carried[:, 0] = cos_turn * start[:, 0] - sin_turn * start[:, 1]
    carried[:, 1] = sin_turn * start[:, 0] + cos_turn * start[:, 1]
    drift = end - carried
    drift = drift - vec.scale(n_bar, vec.dot(drift, n_bar))
    return pos_m - np.where(held[:, None], drift, 0.0)


def coulomb(mu_s: float, mu_k: float, mass_kg: Array, inertia_kgm2: Array, pos_m: Array,
            vel_mps: Array, quat: Array, omega_b: Array, ft: Feet, foot_impulse_ns: Four,
            sliding: Array, ground: Ground) -> tuple[Array, Array, Array, Array]:
    """Coulomb friction at the pressing feet (module docstring). ``ft``: the feet at the step's
    end state; ``sliding`` (N, 4): the feet's regime at the start. Returns (vel, omega_b,
    sliding (N, 4), the sum of the feet's friction impulse magnitudes, N s)."""
    j_n = [np.maximum(j, 0.0) for j in foot_impulse_ns]
    j_sum = ((j_n[0] + j_n[1]) + j_n[2]) + j_n[3]
    pressed = j_sum > 0.0
    safe_sum = np.where(pressed, j_sum, 1.0)
    normals, n_bar, centre = _patch(pos_m, ft, j_n)
    t1, t2 = _tangent_basis(n_bar)
    r = centre - pos_m
    lever = [ft.pos_w[i] - centre for i in range(4)]
    lever_t = [x - vec.scale(n_bar, vec.dot(x, n_bar)) for x in lever]
    s2 = sum((j_n[i] * vec.dot(lever_t[i], lever_t[i]) for i in range(1, 4)),
             j_n[0] * vec.dot(lever_t[0], lever_t[0]))
    twists = s2 > POINT_CONTACT_M2 * safe_sum

    # the footprint's slip (at its centre, and its spin about n_bar) and effective mass
    omega_w = vec.quat_rotate(quat, omega_b)
    spin_w = np.zeros_like(omega_w)
    spin_w[:, 2] = ground.spin_radps
    slip_c = vel_mps + vec.cross(omega_w, r) - ground.surface_velocity(centre)
    sigma = (vec.dot(slip_c, t1), vec.dot(slip_c, t2), vec.dot(omega_w - spin_w, n_bar))
    a1 = vec.quat_rotate_inv(quat, vec.cross(r, t1))  # the body-frame turn per unit impulse, x I
    a2 = vec.quat_rotate_inv(quat, vec.cross(r, t2))
    a3 = vec.quat_rotate_inv(quat, n_bar)
    inv_m = 1.0 / mass_kg
    k11 = inv_m + vec.dot(a1, a1 / inertia_kgm2)
    k22 = inv_m + vec.dot(a2, a2 / inertia_kgm2)
    k12 = vec.dot(a1, a2 / inertia_kgm2)
    k13 = np.where(twists, vec.dot(a1, a3 / inertia_kgm2), 0.0)
    k23 = np.where(twists, vec.dot(a2, a3 / inertia_kgm2), 0.0)
    k33 = np.where(twists, vec.dot(a3, a3 / inertia_kgm2), 1.0)
    s3 = np.where(twists, sigma[2], 0.0)
    # stop impulse (P1, P2, L) = -K^-1 sigma, by cofactors
    c11, c22, c33 = k22 * k33 - k23 * k23, k11 * k33 - k13 * k13, k11 * k22 - k12 * k12
    c12, c13, c23 = k13 * k23 - k12 * k33, k12 * k23 - k13 * k22, k12 * k13 - k11 * k23
    det = k11 * c11 + k12 * c12 + k13 * c13
    p1 = -(c11 * sigma[0] + c12 * sigma[1] + c13 * s3) / det
    p2 = -(c12 * sigma[0] + c22 * sigma[1] + c23 * s3) / det
    torque = -(c13 * sigma[0] + c23 * sigma[1] + c33 * s3) / det
    force_stop = vec.scale(t1, p1) + vec.scale(t2, p2)

    # does the stop impulse's share fit every pressing foot's disk?
    was_sliding = (sliding & np.stack([j > 0.0 for j in j_n], axis=1)).any(axis=1)
    mu = np.where(was_sliding, mu_k, mu_s)
    twist_per_s2 = torque / np.where(twists, s2, 1.0)
    fits = pressed.copy()
    for i in range(4):
        share = force_stop / safe_sum[:, None] + vec.scale(vec.cross(n_bar, lever_t[i]),
                                                           np.where(twists, twist_per_s2, 0.0))
        fits &= (j_n[i] <= 0.0) | (vec.dot(share, share) <= mu * mu)

    # apply: the stop impulse at the centre, or each foot's kinetic impulse at the foot
    d_vel = np.zeros_like(vel_mps)
    d_ang = np.zeros_like(vel_mps)  # angular impulse about the centre of mass, inertial
    stop_ang = vec.cross(r, force_stop) + vec.scale(n_bar, np.where(twists, torque, 0.0))
    d_vel = np.where(fits[:, None], force_stop, d_vel)
    d_ang = np.where(fits[:, None], stop_ang, d_ang)
    total = np.zeros_like(j_sum)
    kinetic = pressed & ~fits
    for i in range(4):
        slip_i = (vel_mps + vec.cross(omega_w, ft.offset_w[i]) - ground.surface_velocity(ft.pos_w[i]))
        slip_i = slip_i - vec.scale(normals[i], vec.dot(slip_i, normals[i]))
        speed = vec.norm(slip_i)
        lam = vec.scale(slip_i, -mu_k * j_n[i] / np.where(speed > 0.0, speed, 1.0))
        lam = np.where((kinetic & (speed > 0.0))[:, None], lam, 0.0)
        d_vel = d_vel + lam
        d_ang = d_ang + vec.cross(ft.offset_w[i], lam)
        share = force_stop / safe_sum[:, None] + vec.scale(vec.cross(n_bar, lever_t[i]),
                                                           np.where(twists, twist_per_s2, 0.0))
        total = total + np.where(fits, j_n[i] * vec.norm(share), vec.norm(lam))
    vel = vel_mps + d_vel / mass_kg[:, None]
    omega = omega_b + vec.quat_rotate_inv(quat, d_ang) / inertia_kgm2
    now_sliding = np.stack([kinetic & (j > 0.0) for j in j_n], axis=1)
    return vel, omega, now_sliding, total


def seed(mu_s: float, mu_k: float, mass_kg: Array, pos_m: Array, vel_mps: Array,
         normal_impulse_ns: Array, sliding: Array, ground: Ground
         ) -> tuple[Array, Array, Array]:
    """The seed's law at the centre of mass (module docstring). Returns (vel, sliding (N, 4),
    friction impulse N s)."""
    n_hat = vec.unit(pos_m)
    v_rel = vel_mps - ground.surface_velocity(pos_m)
    v_t = v_rel - vec.scale(n_hat, vec.dot(v_rel, n_hat))
    s = vec.norm(v_t)
    moving = s > 0.0
    t_hat = v_t / np.where(moving, s, 1.0)[:, None]
    j_n = np.maximum(normal_impulse_ns, 0.0)
    lim_s, lim_k = mu_s * j_n, mu_k * j_n
    j_stop = mass_kg * s
    j = np.where(s > STICK_SPEED_MPS, lim_k, np.where(j_stop <= lim_s, j_stop, lim_k))
    j = np.where(moving & (j_n > 0.0), j, 0.0)
    vel = vel_mps - vec.scale(t_hat, j / mass_kg)
    still = (s - j / mass_kg > STICK_SPEED_MPS) & moving
    return vel, np.repeat(still[:, None], 4, axis=1), j
