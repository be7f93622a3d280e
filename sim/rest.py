"""At rest or not: the settle thresholds' margin (:func:`margin_on`), the centre of mass over the
footprint, the feet still, the energy test against the nearest edge (:func:`stable_at_rest`),
and their samples at a tick's sub-step ends (:class:`SettleRun`, MODEL-NOTES 47)."""
from __future__ import annotations

import math
from typing import NamedTuple

from touchdown.sim.compiled import kernel
from touchdown.sim.constants import SETTLE_SLIP_MPS
from touchdown.sim.contact import FEET_UNKNOWN, feet, foot_slip, foot_velocity, under
from touchdown.sim.frames import (body_spin_in_body_frame, effective_gravity, inertia,
    surface_velocity)
from touchdown.sim.friction import per_foot
from touchdown.sim.ship import CONTACT, REST_LANDED, scene_ground
from touchdown.sim.vec import (add, body_axes, cross, dot, fmax, fmin, mul, norm, quat_axis_z,
    quat_from_rotvec, quat_mul, quat_normalize, quat_rotate, quat_rotate_inv, scale, sub, unit)


class SettleRun(NamedTuple):
    """The settle thresholds sampled at a tick's sub-step ends (MODEL-NOTES 47)."""

    sampled: bool  # sampled at every sub-step's end of the tick
    margin: float  # at the last sample
    began_s: float  # where the run of samples that hold, ending at the last, began (from the


#: a tick whose thresholds were not sampled at its sub-steps
NO_RUN = SettleRun(False, -1.0, 0.0)


@kernel
def settle_sample(cfg, sp, s, ground, run, t_prev, t_now):
    """``run`` with a sample at ``t_now`` (the last was at ``t_prev``): where the thresholds'
    smallest margin crosses zero between them, linearly."""
    return settle_sample_on(cfg, sp, s, ground, run, (t_prev, t_now), FEET_UNKNOWN)


@kernel
def settle_sample_seen(cfg, sp, s, ground, run, span, ce):
    """:func:`settle_sample_on` with ``ce``, the contact evaluated at the ship's state on
    ``ground`` (:func:`margin_seen`: the same bits)."""
    t_prev, t_now = span
    if s.surface_state != CONTACT:
        return SettleRun(True, -1.0, t_now)
    return _sampled(run, margin_seen(cfg, sp, s, ground, ce), span)


@kernel
def settle_sample_on(cfg, sp, s, ground, run, span, known):
    """:func:`settle_sample` between the instants ``span`` (t_prev, t_now), with the feet at the
    ship's pose on ``ground`` where ``known`` (sim.contact.KnownFeet) has them."""
    t_prev, t_now = span
    if s.surface_state != CONTACT:
        return SettleRun(True, -1.0, t_now)
    return _sampled(run, margin_known(cfg, sp, s, ground, known), span)


@kernel
def _sampled(run, m, span):
    """``run`` with the sample m (the margin at span's end, span = (t_prev, t_now))."""
    t_prev, t_now = span
    if not m > 0.0:
        return SettleRun(True, m, t_now)
    if run.margin > 0.0:
        return SettleRun(True, m, run.began_s)
    f = run.margin / (run.margin - m)
    return SettleRun(True, m, t_prev + fmin(fmax(f, 0.0), 1.0) * (t_now - t_prev))


# -- 3. settle -----------------------------------------------------------------------------------
@kernel
def over_footprint(cfg, sp, p, q):
    """The centre of mass is over the footprint: the line through it along the effective gravity
    meets the feet's plane inside the square the four feet span. With u the effective "up" in the
    body frame, the line meets the plane at -h (u_x, u_y) / u_z, inside |x| + |y| < a when

        h (|u_x| + |u_y|) < a u_z,

    an exact comparison (toward a foot: tilt < atan(a / h), 37 degrees for the default lander;
    toward the edge between two: atan(a / (sqrt(2) h)), 28 degrees). With leg_radius = 0 nothing is
    over the footprint: the seed's inverted pendulum, which no tilt makes stable."""
    g = effective_gravity(cfg.gm_m3ps2, cfg.omega2, p)
    u = quat_rotate_inv(q, (-g[0], -g[1], -g[2]))
    return sp.com_height_m * (abs(u[0]) + abs(u[1])) < sp.leg_radius_m * u[2]


@kernel
def springs_energy(k_leg, ft, e0_j):
    """e0_j + sum_i k x_i^2 / 2 over the pressing feet (x_i > 0), J: the legs' stored energy,
    added foot by foot to e0_j in feet order."""
    e = e0_j
    for i in range(4):
        x = fmax(ft.pen_m[i], 0.0)
        e = e + 0.5 * k_leg * x * x
    return e


@kernel
def _saddle_sag(m, g_mag, up, k_leg, g_i):
    """x_s = m g (up . g_i) / (2 k_i |g_i|^2): a foot's sag where it and one other carry the weight
    along their pushes (:func:`stable_at_rest`)."""
    return m * g_mag * dot(up, g_i) / (2.0 * k_leg * dot(g_i, g_i))


@kernel
def stable_at_rest(cfg, sp, s, ft):
    """The ship has too little energy to leave the equilibrium it rests in (MODEL-NOTES 45): its
    kinetic energy relative to the surface is below the barrier over every edge of its footprint.
    The barrier over the edge of feet i, j is the potential at the saddle the ship passes to topple
    over it, less the potential now (``ft``: the feet at the ship's pose, sim.contact.feet):

        B = m g (z_s - z) + k_i (x_s,i^2 + x_s,j^2) / 2 - sum_feet k_i x_k^2 / 2,

    at the saddle the two feet carry the whole weight along their pushes (x_s = m g (up . g_i) /
    (2 k_i |g_i|^2)), the others are clear, and the centre of mass stands straight above the line
    through the two, at its distance L from it: z_s is the line's midpoint, sunk from the feet's
    depth now to x_s, raised by L sqrt(1 - (l . up)^2) (l the line's direction, up against the
    effective gravity). A ship whose springs store more than that saddle asks (a soft-legged ship
    standing on a slope near its edge limit loads its downhill feet as it turns) has no barrier
    left. The seed's "stable" (an energy test, SEED-NOTES 3)."""
    m = s.mass_kg
    p, q = s.motion.p, s.motion.q
    if not sp.leg_radius_m > 0.0:  # four feet at one point: no edge holds anything
        return False
    k_leg = 0.25 * sp.stiffness_per_kg * m
    g = effective_gravity(cfg.gm_m3ps2, cfg.omega2, p)
    g_mag = norm(g)
    up = (-g[0] / g_mag, -g[1] / g_mag, -g[2] / g_mag)
    om = cfg.omega_radps
    v_rel = sub(s.motion.v, surface_velocity(om, p))
    w_rel = sub(s.motion.w, body_spin_in_body_frame(om, q))
    i_b = inertia((sp.inertia0_kgm2[0], sp.inertia0_kgm2[1], sp.inertia0_kgm2[2]), sp.mass0_kg, m)
    kinetic = 0.5 * m * dot(v_rel, v_rel) + 0.5 * dot(w_rel, mul(i_b, w_rel))
    stored = springs_energy(k_leg, ft, 0.0)
    # each foot's sag at a saddle it carries (the same for both edges it spans)
    sag = (_saddle_sag(m, g_mag, up, k_leg, ft.push_w[0]),
           _saddle_sag(m, g_mag, up, k_leg, ft.push_w[1]),
           _saddle_sag(m, g_mag, up, k_leg, ft.push_w[2]),
           _saddle_sag(m, g_mag, up, k_leg, ft.push_w[3]))
    least = math.inf
    for i in range(4):
        j = (i + 1) % 4  # feet 0, 1, 2, 3 go round the footprint: i, i + 1 span an edge
        p_i, p_j = ft.pos_w[i], ft.pos_w[j]
        line = unit(sub(p_j, p_i))
        r = sub(p, p_i)
        arm = norm(sub(r, scale(line, dot(r, line))))
        x_i, x_j = sag[i], sag[j]
        sink = 0.5 * ((x_i - ft.pen_m[i]) + (x_j - ft.pen_m[j]))
        mid = scale(add(p_i, p_j), 0.5)
        lu = dot(line, up)
        rise = arm * math.sqrt(fmax(1.0 - lu * lu, 0.0)) - dot(sub(p, mid), up) - sink
        least = fmin(least, m * g_mag * rise + 0.5 * k_leg * (x_i * x_i + x_j * x_j) - stored)
    return kinetic < least


#: most Newton steps of :func:`rest_pose` (it converges in two or three from a settled ship)
REST_POSE_STEPS = 8
#: a step shorter than this (m, at the feet and the centre of mass) ends them
REST_POSE_TOL_M = 1e-12
#: a rest pose further than this (m or rad) from where the ship settled is not taken
REST_POSE_MAX = 0.05


@kernel
def _rest_energy(k_leg, m_kg, g, p, p0, ft):
    """The potential the rest pose minimises: -m g . (p - p0) + sum k_i x_i^2 / 2 (x_i > 0)."""
    return springs_energy(k_leg, ft, -m_kg * dot(g, sub(p, p0)))


@kernel
def rest_pose(cfg, sp, m_kg, p, q, ground):
    """Where a ship that settles comes to rest, its feet held where they stand (MODEL-NOTES 55).

    A ship lands while it may still rock by a little (the settle thresholds allow 0.01 rad/s);
    pinned at that instant it would keep the rock's displacement (a 0.05 deg tilt, 3 mm at the
    centre of mass of the default lander) forever, where the rock, damped, ends at the
    equilibrium. With its feet held by static friction, a ship moves only in the three ways that
    move every foot along the feet's plane's normal (to first order): turning by phi about the
    two axes e_x, e_y in that plane through its centre c = p - h e_z, and moving by u along e_z.
    The rest pose is the least of the potential over them,

        V = -m g . (p - p0) + sum_i k_i x_i^2 / 2    (x_i > 0; g the effective gravity),

    found by Newton steps on the exact gradient dV = -m g . dp - sum_i k_i x_i g_i . df_i
    (g_i = -grad x_i, df_i = dphi x (f_i - c) + du e_z) with the Hessian sum_i k_i (g_i . df_i)^2
    less the weight's m h |g . e_z| on each turn. Returns the pose, or (p, q) unchanged where the
    Hessian is not positive definite (fewer than three feet hold the ship), the pose is further
    than REST_POSE_MAX from where it settled, or its potential is not lower (so no energy is
    made)."""
    a, h = sp.leg_radius_m, sp.com_height_m
    k_leg = 0.25 * sp.stiffness_per_kg * m_kg
    g = effective_gravity(cfg.gm_m3ps2, cfg.omega2, p)
    pr, qr = p, q
    for _ in range(REST_POSE_STEPS):
        ex, ey, ez = body_axes(qr)
        c = sub(pr, scale(ez, h))
        ft = feet(ground, pr, qr, a, h)
        dp0, dp1, dp2 = cross(ex, sub(pr, c)), cross(ey, sub(pr, c)), ez
        r0 = -m_kg * dot(g, dp0)
        r1 = -m_kg * dot(g, dp1)
        r2 = -m_kg * dot(g, dp2)
        tilt_k = m_kg * h * dot(g, ez)  # the weight's second derivative on a turn (< 0)
        h00, h11, h22 = tilt_k, tilt_k, 0.0
        h01 = h02 = h12 = 0.0
        for i in range(4):
            x = ft.pen_m[i]
            if not x > 0.0:
                continue
            gi = ft.push_w[i]
            arm = sub(ft.pos_w[i], c)
            j0, j1, j2 = dot(gi, cross(ex, arm)), dot(gi, cross(ey, arm)), dot(gi, ez)
            f = k_leg * x
            r0, r1, r2 = r0 - f * j0, r1 - f * j1, r2 - f * j2
            h00, h11, h22 = h00 + k_leg * j0 * j0, h11 + k_leg * j1 * j1, h22 + k_leg * j2 * j2
            h01, h02, h12 = h01 + k_leg * j0 * j1, h02 + k_leg * j0 * j2, h12 + k_leg * j1 * j2
        # H theta = -r by Cramer's rule, after the leading minors say H is positive definite
        m1 = h00
        m2 = h00 * h11 - h01 * h01
        det = (h00 * (h11 * h22 - h12 * h12) - h01 * (h01 * h22 - h12 * h02)
               + h02 * (h01 * h12 - h11 * h02))
        if not (m1 > 0.0 and m2 > 0.0 and det > 0.0):
            return p, q
        b0, b1, b2 = -r0, -r1, -r2
        t0 = (b0 * (h11 * h22 - h12 * h12) - h01 * (b1 * h22 - h12 * b2)
              + h02 * (b1 * h12 - h11 * b2)) / det
        t1 = (h00 * (b1 * h22 - h12 * b2) - b0 * (h01 * h22 - h12 * h02)
              + h02 * (h01 * b2 - b1 * h02)) / det
        t2 = (h00 * (h11 * b2 - b1 * h12) - h01 * (h01 * b2 - b1 * h02)
              + b0 * (h01 * h12 - h11 * h02)) / det
        turn = quat_from_rotvec(add(scale(ex, t0), scale(ey, t1)))
        pr = add(add(c, quat_rotate(turn, sub(pr, c))), scale(ez, t2))
        qr = quat_normalize(quat_mul(turn, qr))
        if (abs(t0) + abs(t1)) * (h + a) + abs(t2) < REST_POSE_TOL_M:
            break
    moved = sub(pr, p)
    dq = quat_mul(qr, (q[0], -q[1], -q[2], -q[3]))
    turned = 2.0 * norm((dq[1], dq[2], dq[3]))
    if not (dot(moved, moved) < REST_POSE_MAX * REST_POSE_MAX and turned < REST_POSE_MAX):
        return p, q
    v0 = _rest_energy(k_leg, m_kg, g, p, p, feet(ground, p, q, a, h))
    v1 = _rest_energy(k_leg, m_kg, g, pr, p, feet(ground, pr, qr, a, h))
    if not v1 <= v0:
        return p, q
    return pr, qr


@kernel
def feet_still(cfg, sp, s, ft, ground, up_ground):
    """The margin of a ship's feet being at rest (> 0: they are): every pressing foot slipping
    slower than SETTLE_SLIP_MPS (as a fraction of it), and the footprint able to hold
    the weight by static friction, the effective gravity's part along the ground under the centre
    of mass within mu_s of its part into it (-1 where it is not: a ship on a slope steeper than
    atan(mu_s) is never at rest, however slowly it starts to slide). ``ft``: the feet at the
    ship's pose on ``ground`` (sim.contact.feet)."""
    m = s.motion
    omega_w = quat_rotate(m.q, m.w)
    worst = 0.0
    for i in range(4):
        if ft.pen_m[i] > 0.0:
            u = foot_velocity(ground, m.v, omega_w, ft.offset_w[i], ft.pos_w[i])
            slip = foot_slip(m.p, u, ft.pos_w[i], ft.push_w[i])
            worst = fmax(worst, dot(slip, slip))
    return _still_margin(cfg, s, worst, up_ground)


@kernel
def feet_still_seen(cfg, s, ce, up_ground):
    """:func:`feet_still` from ``ce``, the contact evaluated at the ship's state on the ground:
    its penetrations and slips are the feet's and foot_slip's (sim.contact.forces forms them by
    the same operations: the same bits), so no foot is looked up."""
    worst = 0.0
    for i in range(4):
        if ce.pen_m[i] > 0.0:
            slip = ce.slip_w[i]
            worst = fmax(worst, dot(slip, slip))
    return _still_margin(cfg, s, worst, up_ground)


@kernel
def _still_margin(cfg, s, worst, up_ground):
    """:func:`feet_still`'s margin from the largest squared slip of a pressing foot, m^2/s^2."""
    m = s.motion
    g = effective_gravity(cfg.gm_m3ps2, cfg.omega2, m.p)
    g_n = dot(g, up_ground)
    g_t = sub(g, scale(up_ground, g_n))
    if dot(g_t, g_t) > cfg.friction_static * cfg.friction_static * g_n * g_n:
        return -1.0
    return (SETTLE_SLIP_MPS - math.sqrt(worst)) / SETTLE_SLIP_MPS


@kernel
def settle_margin(here, s):
    """:func:`margin_on` the ground at the body's angle at the tick's end."""
    cfg = here.cfg
    return margin_on(cfg, here.sp, s, scene_ground(cfg, here.terrain, here.turn.cos1,
                                                   here.turn.sin1))


@kernel
def margin_on(cfg, sp, s, ground):
    """The settle thresholds' smallest margin, each as a fraction of its threshold (> 0: all
    hold): radial and tangential speed and angular speed against theirs (on their squares), the
    tilt's cosine against cos(settle_tilt), the centre of mass over the footprint and every foot
    held by its static friction (each +1 or -1; the seed's friction law lands on the speeds alone).

    The settle tilt is measured from the ground's normal under the centre of mass (the contact
    model's: the terrain's, or radial with ``contact.surface_normal = "radial"``), so a ship
    standing square on a slope lands; on level ground it is local vertical, the seed's
    (MODEL-NOTES 44). The tipped angle and the reported tilt stay measured from local vertical."""
    return margin_known(cfg, sp, s, ground, FEET_UNKNOWN)


@kernel
def margin_known(cfg, sp, s, ground, known):
    """:func:`margin_on`, with the feet at the ship's pose on ``ground`` where ``known``
    (sim.contact.KnownFeet) has them (looked up otherwise)."""
    m, up_ground, decided = _margin_motion(cfg, sp, s, ground)
    if decided:
        return m
    # the feet where they stand, looked up once for both tests
    ft = (known.feet if known.known
          else feet(ground, s.motion.p, s.motion.q, sp.leg_radius_m, sp.com_height_m))
    if per_foot(cfg):
        m = fmin(m, feet_still(cfg, sp, s, ft, ground, up_ground))
    # at rest, but with the energy to pass an edge of its footprint: not stable (MODEL-NOTES 45)
    if m > 0.0 and not stable_at_rest(cfg, sp, s, ft):
        return fmin(m, -1.0)
    return m


@kernel
def margin_seen(cfg, sp, s, ground, ce):
    """:func:`margin_known` with ``ce``, the contact evaluated at the ship's state on ``ground``:
    the feet's slips read from it (:func:`feet_still_seen`), the feet looked up only where the
    energy test asks for them (the same bits)."""
    m, up_ground, decided = _margin_motion(cfg, sp, s, ground)
    if decided:
        return m
    if per_foot(cfg):
        m = fmin(m, feet_still_seen(cfg, s, ce, up_ground))
    if m > 0.0 and not stable_at_rest(cfg, sp, s, feet(ground, s.motion.p, s.motion.q,
                                                          sp.leg_radius_m, sp.com_height_m)):
        return fmin(m, -1.0)
    return m


@kernel
def _margin_motion(cfg, sp, s, ground):
    """:func:`margin_known`'s margins of the motion, the tilt and the footprint: (the margin so
    far, the ground's up under the centre of mass, whether it is the margin: the feet's tests are
    not asked)."""
    om = cfg.omega_radps
    r_hat = unit(s.motion.p)
    up_ground = unit(under(ground, s.motion.p)[1])
    v_rel = sub(s.motion.v, surface_velocity(om, s.motion.p))
    v_rad = dot(v_rel, r_hat)
    v_tan = sub(v_rel, scale(r_hat, v_rad))
    omega_rel = sub(s.motion.w, body_spin_in_body_frame(om, s.motion.q))
    # each as a fraction of its threshold, linear in the speed (a speed falling at a steady rate,
    # as friction slows it, crosses its threshold where its margin does: the instant the
    # thresholds begin to hold is interpolated on it, MODEL-NOTES 47)
    lin, ang = math.sqrt(cfg.settle_lin2), math.sqrt(cfg.settle_ang2)
    m = fmin((lin - abs(v_rad)) / lin, (lin - norm(v_tan)) / lin)
    m = fmin(m, (ang - norm(omega_rel)) / ang)
    m = fmin(m, (dot(quat_axis_z(s.motion.q), up_ground) - cfg.cos_settle_tilt)
             / (1.0 - cfg.cos_settle_tilt))
    coulomb = per_foot(cfg)
    rest = cfg.landed_model == REST_LANDED
    # a ship sliding slower than settle_linear_vel is not at rest: pinned, it would stop dead, and
    # on a slope steeper than atan(mu_s) never slide (MODEL-NOTES 44). 0.7 (``attached``) asked
    # every foot's friction to be static; at rest (MODEL-NOTES 45) the feet must be still and the
    # footprint able to hold the weight by static friction
    slides = coulomb and not rest and (s.footing.sliding[0] or s.footing.sliding[1]
                                       or s.footing.sliding[2] or s.footing.sliding[3])
    if not over_footprint(cfg, sp, s.motion.p, s.motion.q) or slides:
        return fmin(m, -1.0), up_ground, True
    return m, up_ground, not (rest and (coulomb or m > 0.0))
