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
One ship, compiled (sim.compiled).
"""
from __future__ import annotations

from typing import NamedTuple

from sim.compiled import kernel, separate
from sim.constants import STICK_SPEED_MPS
from sim.contact import surface_velocity
from sim.vec import add, cross, div, dot, fmax, norm, quat_integrate, quat_rotate, \
    quat_rotate_inv, scale, sub, unit

#: A footprint with less than this much of its load's lever (sum of J_i |rho_i|^2 over sum J_i, m^2)
#: is a point: it has no torsional friction (leg_radius = 0, or one foot pressing).
POINT_CONTACT_M2 = 1e-12


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
    c = add(add(add(scale(ft.pos_w[0], j_n[0]), scale(ft.pos_w[1], j_n[1])),
                scale(ft.pos_w[2], j_n[2])), scale(ft.pos_w[3], j_n[3]))
    return Patch((n0, n1, n2, n3), n_bar, (c[0] / j_sum, c[1] / j_sum, c[2] / j_sum))


@kernel
def hold_footprint(pos_m, ft_start, ft_end, foot_impulse_ns, cos_turn, sin_turn):
    """The ship moved so that a footprint held by static friction through the whole step ends
    exactly where the ground has carried the point it stood on (the ground turning by the angle of
    (cos_turn, sin_turn) about z over the step): the position-level half of sticking. The
    velocity-level half (the stop impulse) and the spread of its drift over the step leave a
    residue when a held foot's slip does not grow evenly within the step (a held ship on a
    rotating body, whose ground curves away under its straight inertial step, crept 0.5 m an hour
    at 25 ms sub-steps without this); only the drift along the ground is undone."""
    j_n = (fmax(foot_impulse_ns[0], 0.0), fmax(foot_impulse_ns[1], 0.0),
           fmax(foot_impulse_ns[2], 0.0), fmax(foot_impulse_ns[3], 0.0))
    start = patch(pos_m, ft_start, j_n).centre
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


@kernel
def _share(force_stop, safe_sum, n_bar, lever_t, twist):
    """A foot's share of the stop impulse per unit of its load: the force in proportion to the
    load, the moment in proportion to load times lever."""
    return add((force_stop[0] / safe_sum, force_stop[1] / safe_sum, force_stop[2] / safe_sum),
               scale(cross(n_bar, lever_t), twist))


@separate
def coulomb(mu_s, mu_k, mass_kg, inertia_kgm2, pos_m, vel_mps, quat, omega_b, ft,
            foot_impulse_ns, sliding, ground):
    """Coulomb friction at the pressing feet (module docstring). ``ft``: the feet at the step's
    end state; ``sliding``: the feet's regime at the start."""
    j_n = (fmax(foot_impulse_ns[0], 0.0), fmax(foot_impulse_ns[1], 0.0),
           fmax(foot_impulse_ns[2], 0.0), fmax(foot_impulse_ns[3], 0.0))
    j_sum = j_n[0] + j_n[1] + j_n[2] + j_n[3]
    pressed = j_sum > 0.0
    safe_sum = j_sum if pressed else 1.0
    pt = patch(pos_m, ft, j_n)
    n_bar, centre = pt.n_bar, pt.centre
    t1, t2 = tangent_basis(n_bar)
    r = sub(centre, pos_m)
    lever_t = (_in_plane(sub(ft.pos_w[0], centre), n_bar), _in_plane(sub(ft.pos_w[1], centre), n_bar),
               _in_plane(sub(ft.pos_w[2], centre), n_bar), _in_plane(sub(ft.pos_w[3], centre), n_bar))
    s2 = (j_n[0] * dot(lever_t[0], lever_t[0]) + j_n[1] * dot(lever_t[1], lever_t[1])
          + j_n[2] * dot(lever_t[2], lever_t[2]) + j_n[3] * dot(lever_t[3], lever_t[3]))
    twists = s2 > POINT_CONTACT_M2 * safe_sum

    # the footprint's slip (at its centre, and its spin about n_bar) and effective mass
    omega_w = quat_rotate(quat, omega_b)
    spin_w = (0.0, 0.0, ground.spin_radps)
    slip_c = sub(add(vel_mps, cross(omega_w, r)), surface_velocity(ground, centre))
    sigma0, sigma1 = dot(slip_c, t1), dot(slip_c, t2)
    sigma2 = dot(sub(omega_w, spin_w), n_bar)
    a1 = quat_rotate_inv(quat, cross(r, t1))  # the body-frame turn per unit impulse, x I
    a2 = quat_rotate_inv(quat, cross(r, t2))
    a3 = quat_rotate_inv(quat, n_bar)
    inv_m = 1.0 / mass_kg
    k11 = inv_m + dot(a1, div(a1, inertia_kgm2))
    k22 = inv_m + dot(a2, div(a2, inertia_kgm2))
    k12 = dot(a1, div(a2, inertia_kgm2))
    k13 = dot(a1, div(a3, inertia_kgm2)) if twists else 0.0
    k23 = dot(a2, div(a3, inertia_kgm2)) if twists else 0.0
    k33 = dot(a3, div(a3, inertia_kgm2)) if twists else 1.0
    s3 = sigma2 if twists else 0.0
    # stop impulse (P1, P2, L) = -K^-1 sigma, by cofactors
    c11, c22, c33 = k22 * k33 - k23 * k23, k11 * k33 - k13 * k13, k11 * k22 - k12 * k12
    c12, c13, c23 = k13 * k23 - k12 * k33, k12 * k23 - k13 * k22, k12 * k13 - k11 * k23
    det = k11 * c11 + k12 * c12 + k13 * c13
    p1 = -(c11 * sigma0 + c12 * sigma1 + c13 * s3) / det
    p2 = -(c12 * sigma0 + c22 * sigma1 + c23 * s3) / det
    torque = -(c13 * sigma0 + c23 * sigma1 + c33 * s3) / det
    force_stop = add(scale(t1, p1), scale(t2, p2))

    # does the stop impulse's share fit every pressing foot's disk?
    was_sliding = ((sliding[0] and j_n[0] > 0.0) or (sliding[1] and j_n[1] > 0.0)
                   or (sliding[2] and j_n[2] > 0.0) or (sliding[3] and j_n[3] > 0.0))
    mu = mu_k if was_sliding else mu_s
    twist = torque / (s2 if twists else 1.0) if twists else 0.0
    fits = pressed
    for i in range(4):
        share = _share(force_stop, safe_sum, n_bar, lever_t[i], twist)
        fits = fits and (j_n[i] <= 0.0 or dot(share, share) <= mu * mu)

    # apply: the stop impulse at the centre, or each foot's kinetic impulse at the foot
    stop_ang = add(cross(r, force_stop), scale(n_bar, torque if twists else 0.0))
    d_vel = force_stop if fits else (0.0, 0.0, 0.0)
    d_ang = stop_ang if fits else (0.0, 0.0, 0.0)  # angular impulse about the centre, inertial
    total = 0.0
    kinetic = pressed and not fits
    for i in range(4):
        slip_i = sub(add(vel_mps, cross(omega_w, ft.offset_w[i])),
                     surface_velocity(ground, ft.pos_w[i]))
        normal = pt.normals[i]
        slip_i = sub(slip_i, scale(normal, dot(slip_i, normal)))
        speed = norm(slip_i)
        lam = scale(slip_i, -mu_k * j_n[i] / (speed if speed > 0.0 else 1.0))
        if not (kinetic and speed > 0.0):
            lam = (0.0, 0.0, 0.0)
        d_vel = add(d_vel, lam)
        d_ang = add(d_ang, cross(ft.offset_w[i], lam))
        if fits:
            total = total + j_n[i] * norm(_share(force_stop, safe_sum, n_bar, lever_t[i], twist))
        else:
            total = total + norm(lam)
    vel = add(vel_mps, (d_vel[0] / mass_kg, d_vel[1] / mass_kg, d_vel[2] / mass_kg))
    omega = add(omega_b, div(quat_rotate_inv(quat, d_ang), inertia_kgm2))
    now = (kinetic and j_n[0] > 0.0, kinetic and j_n[1] > 0.0, kinetic and j_n[2] > 0.0,
           kinetic and j_n[3] > 0.0)
    return Friction(vel, omega, now, total)


@kernel
def _in_plane(x, n_bar):
    """x without its component along n_bar."""
    return sub(x, scale(n_bar, dot(x, n_bar)))


@kernel
def seed(mu_s, mu_k, mass_kg, pos_m, vel_mps, omega_b, normal_impulse_ns, ground):
    """The seed's law at the centre of mass (module docstring)."""
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
    if s > STICK_SPEED_MPS:
        j = lim_k
    else:
        j = j_stop if j_stop <= lim_s else lim_k
    if not (moving and j_n > 0.0):
        j = 0.0
    vel = sub(vel_mps, scale(t_hat, j / mass_kg))
    still = s - j / mass_kg > STICK_SPEED_MPS and moving
    return Friction(vel, omega_b, (still, still, still, still), j)
