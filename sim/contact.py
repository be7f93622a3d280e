"""Ground contact of the landing legs: the seed's penalty spring-damper, applied at each foot.

Each of the four feet sits at ``leg_radius`` from the long axis, ``com_height`` below the centre of
mass (body frame: (a dx, a dy, -h)). A foot's penetration is measured along the local radial, as the
seed measures it, ``x = R + h(east, north) - |foot|`` (R the body's radius, h the terrain's height
under the foot), and the ground pushes it out by

    F_i = max(0, k_i x_i + c_i x_i') g_i,   g_i = -grad x_i,   k_i = k / 4,  c_i = c / 4,

with k = 100 m and c = 2 zeta sqrt(k m) (seed, "Ground Reaction Forces" and "Bounce"). On level
ground g_i is the radial unit vector and an upright ship on four feet feels exactly the seed's
single spring k and damper c. On a slope g_i is the terrain's normal (``contact.surface_normal =
"terrain"``, the default; the seed deferred terrain normals, SEED-NOTES and MODEL-NOTES 22), of
length sec(slope): the force is minus the gradient of the potential k_i x_i^2 / 2, so the spring
stores exactly what it takes (a frictionless ship climbing a hill slows as energy says), and the
damper's power is -c_i x_i'^2. ``"radial"`` keeps the seed's radial push on any slope.

Tilted, only the low feet touch, so the ground's push acts at the rim of the footprint: that gives
the restoring moment below the critical tilt and the toppling one above it (SEED-NOTES 5), without
a special case. The critical tilt is atan(a / h) toward a foot (37 degrees for the default lander)
and atan(a / (sqrt(2) h)) toward the edge between two feet (28 degrees).

An impact slower than ``bounce_speed`` is absorbed (SEED-NOTES 1): its contact uses the absorber's
damping ratio and is bilateral while a foot is compressed (no clamp at zero), so it cannot throw the
ship back off the ground.

Velocities are taken relative to the body's surface (``Omega z x p`` subtracted), and the ground is
evaluated at the instant of each evaluation: on a rotating body the terrain moves under the ship.
Everything here is one ship's, compiled (sim.compiled).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from touchdown.sim.compiled import kernel
from touchdown.sim.constants import MAX_BUMPS
from touchdown.sim.vec import add, body_axes, cross, dot, fmax, norm, quat_rotate, scale, sub, \
    unit

#: Columns of the terrain's bump table (one row per bump).
BUMP_EAST, BUMP_NORTH, BUMP_RADIUS, BUMP_HEIGHT = 0, 1, 2, 3

#: The terrain as the kernels read it: one record (a pointer inside the kernels: no reference
#: counting wherever a Ground goes).
TERRAIN_DTYPE = np.dtype([
    ("base_height_m", "f8"),
    # a uniform slope through the site: the height's gradient dh/d(east), dh/d(north) (SPEC.md 6)
    ("slope_east", "f8"),
    ("slope_north", "f8"),
    ("level", "?"),  # no bumps and no slope: the ground is the sphere R + base_height
    ("n_bumps", "i8"),
    ("bumps", "f8", (MAX_BUMPS, 4)),  # rows: east, north, radius, height (m); the first n_bumps
], align=True)


class Ground(NamedTuple):
    """The body's surface at one instant, as one ship sees it.

    The terrain is a deterministic height field over the landing site, m:
    h(e, n) = base_height + s_e e + s_n n + sum_j height_j (1 - d_j^2 / radius_j^2)^2 for
    d_j < radius_j, d_j the distance from bump j's centre (east_j, north_j) in the site's tangent
    plane, (s_e, s_n) a uniform slope's gradient. The biweight bump is smooth (C1) and needs only
    +, *. The site is the body-fixed +x axis; east is body-fixed +y,
    north +z; the body has turned by theta = Omega t about the inertial +z axis."""

    radius_m: float
    terrain: np.record  # a TERRAIN_DTYPE record
    cos_theta: float
    sin_theta: float
    spin_radps: float  # Omega, about the inertial +z axis
    radial: bool  # the seed's normal: radial whatever the terrain's slope


@kernel
def height_and_slope(ground, east_m, north_m):
    """(h, dh/de, dh/dn): the terrain's height and its gradient, analytically: the slope's
    (s_e, s_n), and dh/de = -4 height (1 - s) de / radius^2 inside each bump (likewise north)."""
    ter = ground.terrain
    h = ter.base_height_m + ter.slope_east * east_m + ter.slope_north * north_m
    dh_de = ter.slope_east
    dh_dn = ter.slope_north
    for j in range(ter.n_bumps):
        hgt = ter.bumps[j, BUMP_HEIGHT]
        rad = ter.bumps[j, BUMP_RADIUS]
        de = east_m - ter.bumps[j, BUMP_EAST]
        dn = north_m - ter.bumps[j, BUMP_NORTH]
        inv_r2 = 1.0 / (rad * rad)
        s = (de * de + dn * dn) * inv_r2
        w = 1.0 - s
        inside = s < 1.0
        h = h + (hgt * w * w if inside else 0.0)
        slope = -4.0 * hgt * w * inv_r2 if inside else 0.0
        dh_de = dh_de + slope * de
        dh_dn = dh_dn + slope * dn
    return h, dh_de, dh_dn


@kernel
def site_coords(ground, point):
    """(east, north) of an inertial point: its body-fixed (y, z)."""
    return -ground.sin_theta * point[0] + ground.cos_theta * point[1], point[2]


@kernel
def under(ground, point):
    """(x, g): the penetration x = R + h - |p| of a point and g = -grad x, the direction the ground
    pushes it (unit radial on level ground or with ``radial``)."""
    r = norm(point)
    r_hat = (point[0] / r, point[1] / r, point[2] / r)
    if ground.terrain.level:
        return ground.radius_m + ground.terrain.base_height_m - r, r_hat
    east, north = site_coords(ground, point)
    h, dh_de, dh_dn = height_and_slope(ground, east, north)
    pen = ground.radius_m + h - r
    if ground.radial:
        return pen, r_hat
    # grad east = body-fixed y axis in the inertial frame, (-sin, cos, 0); grad north = z
    return pen, (r_hat[0] + dh_de * ground.sin_theta, r_hat[1] - dh_de * ground.cos_theta,
                 r_hat[2] - dh_dn)


@kernel
def under_up(ground, point):
    """:func:`under`, and the point's own radial unit vector (its ``unit``: the same bits)."""
    r = norm(point)
    r_hat = (point[0] / r, point[1] / r, point[2] / r)
    if ground.terrain.level:
        return ground.radius_m + ground.terrain.base_height_m - r, r_hat, r_hat
    east, north = site_coords(ground, point)
    h, dh_de, dh_dn = height_and_slope(ground, east, north)
    pen = ground.radius_m + h - r
    if ground.radial:
        return pen, r_hat, r_hat
    return pen, (r_hat[0] + dh_de * ground.sin_theta, r_hat[1] - dh_de * ground.cos_theta,
                 r_hat[2] - dh_dn), r_hat


@kernel
def rise_rate(ground, point, v_mps, r_hat):
    """How fast a point moving at ``v_mps`` (inertial) rises from the ground under it: -x' =
    g . (v - Omega z x p), g = -grad x (sec(slope) long): the gap the feet see, whatever
    ``radial``. On level ground the speed along ``r_hat``, the point's local up (the surface's
    own velocity is across it); with ``radial`` (the seed's normal) too, as the docs say."""
    if ground.terrain.level or ground.radial:
        return dot(v_mps, r_hat)
    east, north = site_coords(ground, point)
    _h, dh_de, dh_dn = height_and_slope(ground, east, north)
    g = (r_hat[0] + dh_de * ground.sin_theta, r_hat[1] - dh_de * ground.cos_theta,
         r_hat[2] - dh_dn)
    return dot(g, sub(v_mps, surface_velocity(ground, point)))


@kernel
def surface_velocity(ground, point):
    """Omega z x p: the velocity of the body's surface (a body-fixed point) at p."""
    om = ground.spin_radps
    if om == 0.0:
        return (0.0, 0.0, 0.0)
    return (-om * point[1], om * point[0], 0.0)


class Feet(NamedTuple):
    """The four feet at one instant (each field: four of them)."""

    offset_w: tuple  # from the centre of mass, inertial
    pos_w: tuple
    pen_m: tuple  # penetration (negative: height above the ground)
    push_w: tuple  # g = -grad x, the direction the ground pushes


_Z3 = (0.0, 0.0, 0.0)
#: a Feet that holds nothing (:class:`KnownFeet`'s when not known)
NO_FEET = Feet((_Z3, _Z3, _Z3, _Z3), (_Z3, _Z3, _Z3, _Z3), (0.0, 0.0, 0.0, 0.0),
               (_Z3, _Z3, _Z3, _Z3))


class KnownFeet(NamedTuple):
    """The feet at a state where a caller has them already (a geometry's at the same pose and
    ground: :func:`feet_of`), or not (``known`` False: look them up)."""

    known: bool
    feet: Feet


#: feet not known: looked up where asked
FEET_UNKNOWN = KnownFeet(False, NO_FEET)


class Legs(NamedTuple):
    """A ship's four landing legs as the ground meets them: each foot ``leg_radius_m`` from the
    long axis and ``com_height_m`` below the centre of mass (:func:`foot_offsets_w`), on a spring
    of k / 4, so that the four pressed together are the seed's one spring k = stiffness_per_kg m."""

    leg_radius_m: float
    com_height_m: float
    k_npm: float  # the whole ship's k (each foot's: k / 4)


@kernel
def foot_offsets_w(q, leg_radius_m, com_height_m):
    """Each foot's position relative to the centre of mass, inertial: body (+-a, 0, -h) and
    (0, +-a, -h) (sim.constants.LEG_DIRECTIONS_BODY)."""
    ex, ey, ez = body_axes(q)
    down = scale(ez, -com_height_m)
    a = leg_radius_m
    return (add(down, scale(ex, a)), add(down, scale(ey, a)), add(down, scale(ex, -a)),
            add(down, scale(ey, -a)))


@kernel
def foot_positions_w(pos_m, offset_w):
    """Each foot's position, inertial: the centre of mass's plus its offset
    (:func:`foot_offsets_w`)."""
    return (add(pos_m, offset_w[0]), add(pos_m, offset_w[1]), add(pos_m, offset_w[2]),
            add(pos_m, offset_w[3]))


# (inlined where it is called, not a call of its own: its FeetOn passed back through memory cost
# more than its 4.6 kB of code at each of its eleven sites; session15-glue)
@kernel
def feet(ground, pos_m, quat, leg_radius_m, com_height_m):
    """Where the feet are, how deep, and which way the ground would push them."""
    off = foot_offsets_w(quat, leg_radius_m, com_height_m)
    p0, p1, p2, p3 = foot_positions_w(pos_m, off)
    x0, g0 = under(ground, p0)
    x1, g1 = under(ground, p1)
    x2, g2 = under(ground, p2)
    x3, g3 = under(ground, p3)
    return Feet(off, (p0, p1, p2, p3), (x0, x1, x2, x3), (g0, g1, g2, g3))


@kernel
def depth(ground, point):
    """:func:`under`'s penetration x = R + h - |p| alone (the same bits; the push's direction,
    three divisions, not formed)."""
    r = norm(point)
    if ground.terrain.level:
        return ground.radius_m + ground.terrain.base_height_m - r
    east, north = site_coords(ground, point)
    h = height_and_slope(ground, east, north)[0]
    return ground.radius_m + h - r


@kernel
def lowest_foot_penetration(ground, pos_m, quat, leg_radius_m, com_height_m):
    """Penetration of the deepest foot (negative: height of the lowest foot above its ground); the
    same number as :func:`evaluate`'s ``max_penetration_m``, without the forces (:func:`feet`'s
    positions and penetrations, without the directions it returns too)."""
    p0, p1, p2, p3 = foot_positions_w(pos_m, foot_offsets_w(quat, leg_radius_m, com_height_m))
    return fmax(fmax(fmax(depth(ground, p0), depth(ground, p1)), depth(ground, p2)),
                depth(ground, p3))


@kernel
def lowest_foot(ground, pos_m, quat, leg_radius_m, com_height_m):
    """(penetration, position) of the deepest foot; the first of equals."""
    ft = feet(ground, pos_m, quat, leg_radius_m, com_height_m)
    best = 0
    for i in range(1, 4):
        if ft.pen_m[i] > ft.pen_m[best]:
            best = i
    return ft.pen_m[best], ft.pos_w[best]


class ContactGeometry(NamedTuple):
    """The feet at one pose: the geometry phase of a contact evaluation, everything in it that
    depends on the ship's position p and attitude q (and on its legs and the ground at that
    instant) but on no velocity and on no foot's role (the style of MJX's and brax's pipelines:
    kinematics, then the forces from them). Two evaluations at one pose and instant differ only
    in their forces phase (:func:`forces`): the two of the exponential step's closing kick
    (sim.integrators.closing_kick) share one geometry, the same bits by construction (each number
    is formed by the same operations on the same operands). It is not kept in the ContactEval:
    55 numbers more in every evaluation passed to or returned from a compiled call cost about as
    many instructions as looking the feet up again (callgrind, session 14)."""

    offset_w: tuple  # r_i: each foot from the centre of mass, inertial
    pos_w: tuple  # p + r_i
    pen_m: tuple  # x_i = R + h - |p + r_i| (negative: height above the ground)
    push_w: tuple  # g_i = -grad x_i, the direction the ground pushes foot i
    push_norm: tuple  # |g_i|: sec(slope), 1 on level ground
    normal_w: tuple  # n_i, each foot's friction plane normal (:func:`friction_normal`)
    up_w: tuple  # unit(p): the centre of mass's local vertical


class ContactEval(NamedTuple):
    """The ground's action on a ship at one instant."""

    touching: bool  # False: a ship known to be clear of the ground (no contact work done)
    pen_m: tuple  # each foot's penetration (negative: its height above the ground)
    pen_rate_mps: tuple  # x' of each foot (+ = going into the ground)
    foot_force_n: tuple  # k x + c x' of each foot (clamped at 0 unless absorbing)
    push_norm: tuple  # |g_i| of each foot: sec(slope), 1 on level ground
    force_w: tuple  # total force, inertial: the feet's push, and the sliding feet's friction
    torque_w: tuple  # its moment about the centre of mass, inertial (with kinetic friction's)
    normal_n: float  # sum of the feet's force magnitudes (< 0 only while absorbing)
    slip_w: tuple  # each foot's velocity over the ground, in its friction plane
    friction_n: float  # the kinetic friction of the feet that slide, sum of magnitudes
    max_penetration_m: float  # deepest foot (negative: lowest foot's height above the ground)
    lowest_foot_w: tuple  # the deepest (or lowest) foot
    # The pressing feet (those whose force is not clamped away) as one linear spring-damper along
    # the axis n (sim.integrators.exponential; :func:`spring_axis`): with gamma_i = g_i . n, the
    # sums of k_i gamma_i^2, c_i gamma_i^2, k_i gamma_i x_i and k_i gamma_i x_i' (zeros unless
    # asked for: evaluate's linear_model), and gamma of the deepest foot.
    axis: tuple
    stiffness_npm: float
    damping_nspm: float
    spring_load_n: float
    spring_load_rate_nps: float
    lowest_gamma: float
    #: each foot's friction plane normal (:func:`friction_normal`), for the held feet's friction
    #: (sim.dynamics.held_friction) at the same state
    normal_w: tuple


class FrictionForce(NamedTuple):
    """The feet's friction that acts as a force inside a step, integrated with the springs
    (:func:`evaluate`): each foot of ``kinetic`` that presses is dragged by mu_k N_i against its
    slip, each other foot that presses is held by ``hold_w``, its static friction over the last
    step. The rest of friction comes after the step, as impulses (sim.friction.coulomb)."""

    mu_k: float  # 0 under the seed's law, which acts after the step
    kinetic: tuple  # each foot: dragged by its kinetic friction
    hold_w: tuple  # each foot's static friction carried in, inertial, N
    #: each dragged foot's drag against this direction, where it is not zero (a foot whose stop is
    #: being located: sim.flight.step_piece), else against its slip
    drag_dir: tuple


class Spring(NamedTuple):
    """One foot's spring-damper: F = k x + c x' (k / 4 and c / 4 of the ship's), clamped at zero
    unless ``bilateral`` (an absorbed contact, SEED-NOTES 1, pulls as well as pushes)."""

    k_npm: float
    c_nspm: float
    bilateral: bool


class Dampers(NamedTuple):
    """The legs' dampers over a step: the whole ship's c = 2 zeta sqrt(k m), the absorbers' while
    ``absorbing`` (SEED-NOTES 1: then bilateral, no clamp at zero)."""

    c_nspm: float
    absorbing: bool


class FootForce(NamedTuple):
    """One foot's share of a contact evaluation."""

    force_n: float  # k x + c x', clamped as the contact requires
    pen_rate_mps: float  # x'
    # its terms of the pressing feet's linear model (zeros when not pressing or not asked for)
    stiffness_npm: float
    damping_nspm: float
    spring_load_n: float
    spring_load_rate_nps: float


@kernel
def foot_velocity(ground, vel_mps, omega_w, offset, foot):
    """A foot's velocity over the ground under it: v + w x r_i - Omega z x foot (r_i its offset
    from the centre of mass, w the ship's angular velocity, inertial)."""
    return sub(add(vel_mps, cross(omega_w, offset)), surface_velocity(ground, foot))


@kernel
def foot_force(spring, v_foot, pen, push, engage_m, n_hat, linear_model):
    # engage_m: this foot presses from penetration > -engage_m
    """One foot's ``spring`` (a :class:`Spring`) force k x + c x', its rate x' = -g . v_foot
    (``v_foot``: its velocity over the ground, :func:`foot_velocity`), and (``linear_model``) its
    terms of the pressing feet's linear model along n_hat."""
    k_leg, c_leg, absorbing = spring
    pen_rate = -dot(push, v_foot)
    f = k_leg * pen + c_leg * pen_rate
    stiff = damp = load = load_rate = 0.0
    if linear_model:
        pressing = pen > -engage_m and (absorbing or f > 0.0)
        gamma = dot(push, n_hat)
        k_g = k_leg * gamma if pressing else 0.0
        stiff = k_g * gamma
        damp = c_leg * gamma * gamma if pressing else 0.0
        load = k_g * pen
        load_rate = k_g * pen_rate
    if not absorbing:
        f = fmax(f, 0.0)
    if not pen > -engage_m:
        f = 0.0
    return FootForce(f, pen_rate, stiff, damp, load, load_rate)


@kernel
def spring_axis(ground, up, ft, engage_m):
    """The direction along which the feet that touch push: the centre of mass's radial on level
    ground (or with the seed's radial normal), else the mean of their pushes g_i (on a uniform
    slope, the slope's normal exactly). The exact method solves the springs along it, so a force
    that acts along it is integrated by one rule whole, not by one rule along the radial and
    another across it (which gave a spring on a 39 degree slope a 0.6% pull along the slope).
    ``up``: the centre of mass's local vertical, unit(p); ``ft``: the feet (their pen_m, push_w)."""
    if ground.terrain.level or ground.radial:
        return up
    s = (0.0, 0.0, 0.0)
    for i in range(4):
        if ft.pen_m[i] > -engage_m[i]:
            s = add(s, ft.push_w[i])
    if not dot(s, s) > 0.0:
        return up
    return unit(s)


@kernel
def friction_normal(pos_m, foot_pos_w, push_w):
    """The normal of a foot's friction plane: the terrain's slope under it on the ship's local
    vertical, unit(g_i - r_hat_i + up). The sphere's own curvature across the footprint (a / R,
    1e-6 rad) is left out: it would make a straight descent slip every foot inwards."""
    return unit(add(sub(push_w, unit(foot_pos_w)), unit(pos_m)))


@kernel
def foot_slip(pos_m, v_foot, foot, push):
    """A foot's velocity over the ground under it (``v_foot``, :func:`foot_velocity`), in its
    friction plane."""
    return in_plane(v_foot, friction_normal(pos_m, foot, push))


@kernel
def in_plane(v, n):
    """v less its part along the unit normal n."""
    return sub(v, scale(n, dot(v, n)))


@kernel
def geometry(ground, pos_m, quat, legs):
    """The :class:`ContactGeometry` of a ship at ``pos_m``, turned by ``quat``, on its ``legs``:
    the feet (:func:`feet`'s numbers), each foot's friction plane normal
    n_i = unit(g_i - r_hat_i + up) (:func:`friction_normal`, its radial r_hat_i from
    :func:`under_up` without normalising the foot's position again; on level ground, or with the
    seed's radial normal, g_i is r_hat_i and every n_i is unit(up)), and |g_i|."""
    off = foot_offsets_w(quat, legs.leg_radius_m, legs.com_height_m)
    f0, f1, f2, f3 = (add(pos_m, off[0]), add(pos_m, off[1]), add(pos_m, off[2]),
                      add(pos_m, off[3]))
    x0, g0, u0 = under_up(ground, f0)
    x1, g1, u1 = under_up(ground, f1)
    x2, g2, u2 = under_up(ground, f2)
    x3, g3, u3 = under_up(ground, f3)
    up = unit(pos_m)
    n0 = unit(add(sub(g0, u0), up))
    if ground.terrain.level or ground.radial:  # g_i is u_i: every foot's normal is unit(up)'s
        normals = (n0, n0, n0, n0)
    else:
        normals = (n0, unit(add(sub(g1, u1), up)), unit(add(sub(g2, u2), up)),
                   unit(add(sub(g3, u3), up)))
    return ContactGeometry(off, (f0, f1, f2, f3), (x0, x1, x2, x3), (g0, g1, g2, g3),
                           (norm(g0), norm(g1), norm(g2), norm(g3)), normals, up)


@kernel
def feet_of(geo):
    """:func:`feet`'s numbers from a :class:`ContactGeometry` at the same pose and ground (its
    offsets, positions, penetrations and pushes are formed by the same operations: the same
    bits)."""
    return Feet(geo.offset_w, geo.pos_w, geo.pen_m, geo.push_w)


@kernel
def evaluate(ground, motion, legs, dampers, engage_m, linear_model, friction_force):
    """Normal force, its moment, and penetration (see the module docstring) of a ship in
    ``motion`` (p, v, q, w_b: sim.dynamics.Motion) on its ``legs``, their ``dampers`` (a
    :class:`Dampers`: the absorbers' while absorbing): the feet at its pose (:func:`geometry`),
    then the ground's action on them at its velocities (:func:`forces`).

    ``engage_m``: foot i counts as touching from ``x_i > -engage_m[i]`` (0 as a rule; a foot that
    has just reached the ground gets a micrometre, so that rounding cannot leave out the damper's
    jump at its first stage; -inf keeps a foot from pressing while a step is stepped up to the
    instant it reaches the ground, sim.step). ``linear_model``: also sum the pressing feet's
    stiffness, damping, load and load rate along the spring axis (zeros otherwise).
    ``friction_force`` (:class:`FrictionForce`): its ``kinetic`` feet, whose friction is kinetic
    (sliding faster than the stick speed, sim.friction): each of them that pushes is dragged by
    mu_k N_i against its slip, a force the method integrates as it does the spring's (the feet
    that hold get theirs as an impulse after the step, sim.friction.coulomb); its ``hold_w``: the
    holding feet's static friction over the last step, carried into this one as a force (each
    pressing foot that is not kinetic; in its friction plane), so that a ship held on its feet
    feels its friction throughout the step: the impulse after it only corrects it
    (sim.friction.coulomb)."""
    c_nspm, absorbing = dampers
    return forces(ground, geometry(ground, motion.p, motion.q, legs), motion,
                  Spring(0.25 * legs.k_npm, 0.25 * c_nspm, absorbing), engage_m, linear_model,
                  friction_force)


# (a kernel, inlined into its caller, sim.dynamics.contact_forces, inlined into contact_inline,
# themselves inlined into the integrators' stages and into sim.dynamics.contact_at: its
# ContactEval is then built where it is used, not copied there from a call's; 4.2% of a
# touchdown's instructions, session 4)
@kernel
def forces(ground, geo, motion, spring, engage_m, linear_model, friction_force):
    """The forces phase of an evaluation (:func:`evaluate`): the ground's action on feet at
    ``geo`` (a :class:`ContactGeometry`, at ``motion``'s pose and instant) moving at ``motion``'s
    velocities: each foot's rate x_i' = -g_i . u_i (u_i = v + w x r_i - Omega z x foot, its
    velocity over the ground), its ``spring``'s force F_i = k_i x_i + c_i x_i' (clamped at 0
    unless bilateral), the sliding feet's kinetic friction and the holding feet's carried static
    friction (``friction_force``), their sum and moment about the centre of mass."""
    vel_mps, quat, w_b = motion.v, motion.q, motion.w
    mu_k, kinetic, hold_w, drag_dir = friction_force
    omega_w = quat_rotate(quat, w_b)
    normals = geo.normal_w
    n_hat = spring_axis(ground, geo.up_w, geo, engage_m) if linear_model else geo.up_w
    v_feet = (foot_velocity(ground, vel_mps, omega_w, geo.offset_w[0], geo.pos_w[0]),
              foot_velocity(ground, vel_mps, omega_w, geo.offset_w[1], geo.pos_w[1]),
              foot_velocity(ground, vel_mps, omega_w, geo.offset_w[2], geo.pos_w[2]),
              foot_velocity(ground, vel_mps, omega_w, geo.offset_w[3], geo.pos_w[3]))
    ff = (foot_force(spring, v_feet[0], geo.pen_m[0], geo.push_w[0], engage_m[0], n_hat,
                     linear_model),
          foot_force(spring, v_feet[1], geo.pen_m[1], geo.push_w[1], engage_m[1], n_hat,
                     linear_model),
          foot_force(spring, v_feet[2], geo.pen_m[2], geo.push_w[2], engage_m[2], n_hat,
                     linear_model),
          foot_force(spring, v_feet[3], geo.pen_m[3], geo.push_w[3], engage_m[3], n_hat,
                     linear_model))
    force = (0.0, 0.0, 0.0)
    torque = (0.0, 0.0, 0.0)
    g = geo.push_norm
    normal = 0.0
    max_pen = -math.inf
    lowest = (0.0, 0.0, 0.0)
    lowest_gamma = 1.0
    stiff = damp = load = load_rate = 0.0
    slips = (in_plane(v_feet[0], normals[0]), in_plane(v_feet[1], normals[1]),
             in_plane(v_feet[2], normals[2]), in_plane(v_feet[3], normals[3]))
    friction = 0.0
    for i in range(4):  # sums in foot order: the same bits on every machine
        f = ff[i]
        stiff += f.stiffness_npm
        damp += f.damping_nspm
        load += f.spring_load_n
        load_rate += f.spring_load_rate_nps
        f_vec = scale(geo.push_w[i], f.force_n)
        speed = norm(slips[i])
        fixed = drag_dir[i]
        along = fixed[0] != 0.0 or fixed[1] != 0.0 or fixed[2] != 0.0
        if kinetic[i] and f.force_n > 0.0 and (speed > 0.0 or along):
            drag = mu_k * f.force_n * g[i]
            f_vec = sub(f_vec, scale(fixed, drag) if along else scale(slips[i], drag / speed))
            friction += drag
        elif f.force_n > 0.0 and not kinetic[i]:
            n_f = normals[i]
            held = sub(hold_w[i], scale(n_f, dot(hold_w[i], n_f)))
            f_vec = add(f_vec, held)
            friction += norm(held)
        force = add(force, f_vec)
        torque = add(torque, cross(geo.offset_w[i], f_vec))
        normal += f.force_n * g[i]
        if geo.pen_m[i] > max_pen:
            lowest = geo.pos_w[i]
            max_pen = geo.pen_m[i]
            lowest_gamma = dot(geo.push_w[i], n_hat)
    return ContactEval(True, geo.pen_m, (ff[0].pen_rate_mps, ff[1].pen_rate_mps,
                                         ff[2].pen_rate_mps, ff[3].pen_rate_mps),
                       (ff[0].force_n, ff[1].force_n, ff[2].force_n, ff[3].force_n), g,
                       force, torque, normal, slips, friction, max_pen, lowest, n_hat, stiff,
                       damp, load, load_rate, lowest_gamma, normals)


@kernel
def no_contact(pos_m):
    """The evaluation of a ship known to be clear of the ground for the whole step."""
    z = (0.0, 0.0, 0.0)
    far = (-math.inf, -math.inf, -math.inf, -math.inf)
    return ContactEval(False, far, (0.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0),
                       (0.0, 0.0, 0.0, 0.0), z, z, 0.0, (z, z, z, z), 0.0, -math.inf,
                       pos_m, unit(pos_m), 0.0, 0.0, 0.0, 0.0, 1.0, (z, z, z, z))
