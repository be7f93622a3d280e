"""The free flight (phase 2 of sim.phases): a flying or contact ship advanced through one tick in
sub-steps (:func:`free_flight`), each in three stages: (a) the touchdown instant
(:func:`piece_start`: the seed's touchdown rules, :func:`touchdown_rules`, where the first foot
reaches the ground), (b) integrating, friction at the feet and the passivity guard
(:func:`step_piece`, which cuts the sub-step into pieces at every foot that starts or stops
pressing, stops slipping or breaks away, each located by :func:`to_event`; then
:func:`guard_substep`), (c) the in-flight transitions and their events
(:func:`in_flight_transitions`).
"""
from __future__ import annotations

import math
from typing import NamedTuple

from touchdown.sim.compiled import constructor, kernel, separate
from touchdown.sim.contact import (FEET_UNKNOWN, ContactEval, FrictionForce, KnownFeet, Legs,
    feet, foot_offsets_w, foot_positions_w, lowest_foot_penetration, no_contact, rise_rate)
from touchdown.sim.dynamics import (Craft, FreeBody, Holding, Motion, contact_at, contact_inline,
    derivatives_held, ground_at, ground_turn, held_friction, with_drag_dir, with_feet, with_hold)
from touchdown.sim.energy import mechanical, mechanical_at, rotation, total, translation
from touchdown.sim.frames import (Body, body_spin_in_body_frame, pin_pose, quat_z, rotate_z,
    surface_velocity, turned)
from touchdown.sim.friction import (FeetOn, Rigid, coulomb, hold_footprint, law_of, per_foot,
    seed, spread_over_step)
from touchdown.sim.integrators import EXPONENTIAL, RK4, advance, exponential, \
    exponential_end, rk4_held
from touchdown.sim.pivot import pinned_motion, rate_from_momentum
from touchdown.sim.rest import NO_RUN, SettleRun, settle_sample, settle_sample_on, settle_sample_seen
from touchdown.sim.ship import (CONTACT, CRASHED, ENGAGE_AT_GROUND, FLYING, FULL_TIPPED, NO_HOLD,
    NO_SLIP, Pin, Report, Ship, TIPPED, emit, fresh_footing, with_footing, with_friction,
    with_motion, with_pin)
from touchdown.sim.vec import (add, cross, div, dot, fmax, fmin, norm, quat_axis_z, quat_mul,
    quat_normalize, quat_rotate, quat_rotate_inv, scale, sub, unit)


#: A step that ends (or starts) exactly where the feet reach the ground leaves them within rounding
#: of it (ulp(|p|) ~ 2e-10 m on the Moon): the feet count as clear before that instant and as
#: pressing from it, within this margin, so that all of an upright ship's feet engage together.
ONSET_MARGIN_M = 1e-6


@kernel
def align_to_surface(q, r_hat):
    """Attitude turned by the smallest rotation that takes the body's long axis onto r_hat.

    Half-way quaternion: (1 + ez.r, ez x r) normalised (sqrt only)."""
    ez = quat_axis_z(q)
    c = cross(ez, r_hat)
    rot = (1.0 + dot(ez, r_hat), c[0], c[1], c[2])
    if rot[0] <= 0.0:  # upside down: no unique smallest rotation; leave as is
        rot = (1.0, 0.0, 0.0, 0.0)
    return quat_normalize(quat_mul(quat_normalize(rot), q))


@kernel
def ship_energy(fb, ground, p, v, q, w):
    """sim.energy of a free ship at one instant (a ship far above the ground for the whole tick
    stores nothing in its springs: its feet are not looked for)."""
    cr = fb.craft
    return mechanical(Body(cr.gm_m3ps2, cr.body_radius_m, cr.body_omega_radps), cr.mass_kg,
                      cr.inertia_kgm2, Legs(cr.leg_radius_m, cr.com_height_m, cr.k_npm),
                      Motion(p, v, q, w), ground, cr.touching)


@kernel
def ship_energy_at(fb, ground, m, pen_m):
    """:func:`ship_energy` at a state whose feet's penetrations ``pen_m`` a contact evaluation
    has (sim.energy.mechanical_at: the same bits, the feet not looked up again)."""
    cr = fb.craft
    far = -math.inf
    return mechanical_at(Body(cr.gm_m3ps2, cr.body_radius_m, cr.body_omega_radps), cr.mass_kg,
                         cr.inertia_kgm2, cr.k_npm, m, ground,
                         pen_m if cr.touching else (far, far, far, far))


class EnergyRef(NamedTuple):
    """A passive ship's energy at the end of its last sub-step: the total, and its translational
    and rotational parts (conserved each on its own while nothing touches the ship)."""

    total_j: float
    translation_j: float
    rotation_j: float


@kernel
def energy_ref(e):
    return EnergyRef(total(e), translation(e), rotation(e))


@kernel
def _guard_factor(excess, kinetic):
    """sqrt(1 - excess / kinetic): the scale of the kinetic energy that removes ``excess``."""
    if not excess > 0.0:
        return 1.0
    if not kinetic > 0.0:
        return 0.0
    return math.sqrt(fmax(1.0 - excess / kinetic, 0.0))


class Guarded(NamedTuple):
    v: tuple
    w: tuple
    ref: EnergyRef
    removed_j: float


@kernel
def passivity_guard(fb, ground, motion, ref, passive, airborne, pen_m):
    """With no thrust and no RCS nothing can add energy (sim.energy: the dampers, friction and
    every inelastic transition only take it). A step's integration error can (the explicit
    kicks on a rocking ship, measured up to 2.5e-4 of its energy in a tick; free flight's
    Verlet error, 1e-12): where a passive ship's energy rose over the step, its velocities
    relative to the surface are scaled back by sqrt(1 - excess / kinetic) so that it did not,
    a projection onto the sublevel set of the energy (Hairer, Lubich & Wanner, Geometric
    Numerical Integration, IV.4). A ship that touched nothing during the step keeps its
    translational and rotational energies each on its own, so each is guarded on its own (the
    rotation's step is exact for an axisymmetric ship and must not pay for the translation's
    error). The correction is the size of the local error, so the method's order is kept; what
    it removes is reported as ``energy_guard_j`` (``sim.energy_guard``). ``pen_m``: the feet's
    penetrations at ``motion`` (a contact evaluation's there; -inf where none presses)."""
    p, v, q, w = motion
    e = ship_energy_at(fb, ground, motion, pen_m)
    ex_all = total(e) - ref.total_j if passive and not airborne else 0.0
    ex_tr = translation(e) - ref.translation_j if passive and airborne else 0.0
    ex_rot = rotation(e) - ref.rotation_j if passive and airborne else 0.0
    if not (ex_all > 0.0 or ex_tr > 0.0 or ex_rot > 0.0):
        return Guarded(v, w, energy_ref(e), 0.0)
    f_all = _guard_factor(ex_all, e.translational_j + e.rotational_j)
    f_v = f_all * _guard_factor(ex_tr, e.translational_j)
    f_w = f_all * _guard_factor(ex_rot, e.rotational_j)
    # only where a correction is due: (v - v_surf) + v_surf is not v in floating point
    if f_v != 1.0:
        v_surf = surface_velocity(fb.craft.body_omega_radps, p)
        v = add(v_surf, scale(sub(v, v_surf), f_v))
    if f_w != 1.0:
        spin_b = body_spin_in_body_frame(fb.craft.body_omega_radps, q)
        w = add(spin_b, scale(sub(w, spin_b), f_w))
    taken_tr = e.translational_j * (1.0 - f_v * f_v)
    taken_rot = e.rotational_j * (1.0 - f_w * f_w)
    removed = taken_tr + taken_rot
    return Guarded(v, w, EnergyRef(total(e) - removed, translation(e) - taken_tr,
                                   rotation(e) - taken_rot), removed)


class Aligned(NamedTuple):
    p: tuple
    v: tuple
    q: tuple
    w: tuple
    aligned: bool


@kernel
def _lowest(pen):
    """The deepest of four penetrations (sim.contact.lowest_foot_penetration's order)."""
    return fmax(fmax(fmax(pen[0], pen[1]), pen[2]), pen[3])


@kernel
def align_at_touchdown(fb, ground, m, pen_m):
    """The seed's Flying -> Contact rule: attitude snapped to local up and rotation stopped
    (relative to the surface); then the ship moves out along local up so that its deepest foot
    is no deeper than before the snap: turning must not bury the feet (MODEL-NOTES 11). The snap
    must not make energy either (MODEL-NOTES 24): a ship that it would raise (tilted past
    2 atan(a / h), 74 degrees for the default lander) pays for the lift out of its descent speed;
    a ship too slow to pay is not stood up and touches down as it is.

    ``pen_m``: the feet's penetrations at the motion ``m`` on ``ground``, from a contact
    evaluation there (sim.contact.evaluate: sim.contact.feet's bits), so that they are not looked
    up again; the snapped pose's feet are looked up once, for its deepest foot and its springs'
    energy both (a ship not moved out, p1 = p + 0 r_hat, has its feet where they were at p: a
    position equal to p's, the same |foot|, the same penetrations)."""
    p, v, q, w = m
    cr = fb.craft
    r_hat = unit(p)
    q1 = align_to_surface(q, r_hat)
    w1 = body_spin_in_body_frame(cr.body_omega_radps, q1)
    pen_start = pen_m if cr.touching else feet(ground, p, q, cr.leg_radius_m,
                                                cr.com_height_m).pen_m
    pen0 = _lowest(pen_start)
    pen_snap = feet(ground, p, q1, cr.leg_radius_m, cr.com_height_m).pen_m
    pen1 = _lowest(pen_snap)
    lift = fmax(pen1 - pen0, 0.0)
    p1 = add(p, scale(r_hat, lift))
    e1 = (ship_energy_at(fb, ground, Motion(p1, v, q1, w1), pen_snap) if lift == 0.0
          else ship_energy(fb, ground, p1, v, q1, w1))
    cost = total(e1) - total(ship_energy_at(fb, ground, m, pen_start))
    v_rad = dot(sub(v, surface_velocity(fb.craft.body_omega_radps, p)), r_hat)
    spare = v_rad * v_rad - 2.0 * cost / fb.craft.mass_kg
    pays = cost > 0.0 and v_rad < 0.0 and spare >= 0.0
    if not (cost <= 0.0 or pays):
        return Aligned(p, v, q, w, False)
    dv = -math.sqrt(fmax(spare, 0.0)) - v_rad if pays else 0.0
    return Aligned(p1, add(v, scale(r_hat, dv)), q1, w1, True)


@kernel
def hermite_peak(x0, xd0, x1, xd1, h):
    """Largest value over a sub-step of the cubic Hermite interpolant through (x0, x0') and
    (x1, x1'): the deepest penetration between sub-step ends, to O(h^4). Telemetry only."""
    a = 6.0 * (x0 - x1) + 3.0 * h * (xd0 + xd1)
    b = 6.0 * (x1 - x0) - h * (4.0 * xd0 + 2.0 * xd1)
    c = h * xd0
    best = fmax(x0, x1)
    disc = b * b - 4.0 * a * c
    root = math.sqrt(fmax(disc, 0.0))
    for sgn in (-1.0, 1.0):
        if a != 0.0:
            s = (-b + sgn * root) / (2.0 * a)
        elif b != 0.0:
            s = -c / b
        else:
            s = 0.0
        if disc >= 0.0 and s > 0.0 and s < 1.0 and math.isfinite(x0) and math.isfinite(x1):
            s2 = s * s
            s3 = s * s * s
            xs = ((2.0 * s3 - 3.0 * s2 + 1.0) * x0 + (s3 - 2.0 * s2 + s) * h * xd0
                  + (-2.0 * s3 + 3.0 * s2) * x1 + (s3 - s2) * h * xd1)
            best = fmax(best, xs)
    return best


class SubStep(NamedTuple):
    """One integrator (sub-)step followed by friction's impulses."""

    p: tuple
    v: tuple
    q: tuple
    w: tuple
    sliding: tuple
    friction_n: float  # the feet's friction impulse over the step divided by it
    peak_penetration_m: float  # the method's own deepest penetration inside the step
    located: bool  # whether the method located it
    pressed: bool  # whether any foot pressed during the step
    hold_w: tuple  # each holding foot's static friction over it (sim.friction.Friction)


class FootRoles(NamedTuple):
    """How each foot takes part in a step."""

    engage: tuple  # it presses from penetration > -engage (sim.contact.evaluate)
    sliding: tuple  # its friction regime
    dragged: tuple  # it is dragged by its kinetic friction as a force
    absorbing: bool  # the contact is the absorbers' (SEED-NOTES 1)


class StepFrom(NamedTuple):
    """Where a step of the method starts: its instant, the ship's motion there, and the contact
    evaluated there (with the feet's roles the step is taken with)."""

    t_s: float  # from the tick's start
    motion: Motion
    ce: ContactEval


@separate
def substep(cfg, fb, roles, h, start):
    """One step of the method from ``start`` (a :class:`StepFrom`), the feet pressing from
    ``roles.engage`` and those of ``roles.dragged`` dragged by kinetic friction as a force
    (``start.ce`` evaluated so); then Coulomb's impulses at the other pressing feet (or the seed's
    law), spread over the step, and a held footprint kept where the ground carried it."""
    engage, sliding, dragged, absorbing = roles
    t_start, motion, ce_start = start
    p, v, q, w = motion
    z4 = (False, False, False, False)
    body = with_feet(fb, engage, dragged)
    carried = fb.grip.hold_w
    f0 = ce_start.foot_force_n
    holding = ((f0[0] > 0.0 and not sliding[0]) or (f0[1] > 0.0 and not sliding[1])
               or (f0[2] > 0.0 and not sliding[2]) or (f0[3] > 0.0 and not sliding[3]))
    # (no holding foot presses at the start: none will inside, a foot's touch ending the piece)
    if fb.craft.method == RK4 and holding and per_foot(cfg):
        # the holding feet's static friction inside the step, as their constraint's force
        # (MODEL-NOTES 46); what it gave them is what the impulses after the step start from
        held = (not sliding[0], not sliding[1], not sliding[2], not sliding[3])
        rh = rk4_held(with_hold(body, NO_HOLD), h, motion, ce_start, absorbing, t_start,
                      Holding(held, cfg.friction_static))
        res = rh.stepped
        hi = rh.held_impulse_w
        carried = (scale(hi[0], 1.0 / h), scale(hi[1], 1.0 / h), scale(hi[2], 1.0 / h),
                   scale(hi[3], 1.0 / h))
    else:
        res = advance(fb.craft.method, body, h, motion, ce_start, absorbing, t_start)
    j = res.foot_impulse_ns
    pressed = j[0] != 0.0 or j[1] != 0.0 or j[2] != 0.0 or j[3] != 0.0
    if not pressed:  # no foot pressed: no friction (nor any foot's regime) to keep
        return SubStep(res.p, res.v, res.q, res.w, z4, 0.0, res.peak_penetration_m, res.located,
                       pressed, NO_HOLD)
    ground_end = ground_at(fb, t_start + h)
    law = law_of(cfg)
    if not per_foot(cfg):
        j_n = j[0] + j[1] + j[2] + j[3]
        fr = seed(law, fb.craft.mass_kg, res.p, res.v, res.w, j_n, ground_end)
        return SubStep(res.p, fr.vel_mps, res.q, res.w, fr.sliding, fr.impulse_ns / h,
                       res.peak_penetration_m, res.located, pressed, NO_HOLD)
    ft = feet(ground_end, res.p, res.q, fb.craft.leg_radius_m, fb.craft.com_height_m)
    fr = coulomb(law, Rigid(fb.craft.mass_kg, fb.craft.inertia_kgm2), res, FeetOn(ground_end, ft),
                 sliding, FrictionForce(fb.craft.mu_k, dragged, carried, NO_HOLD), h)
    p2, q2 = spread_over_step(res.p, res.q, res.v, fr.vel_mps, res.w, fr.omega_body_radps, h)
    if fr.held and fr.impulse_ns > 0.0:
        c_turn, s_turn = ground_turn(fb, h)
        ft2 = feet(ground_end, p2, q2, fb.craft.leg_radius_m, fb.craft.com_height_m)
        # the feet where the step began (what ce_start was evaluated on): their positions only,
        # no ground under them (its centre of pressure reads nothing else)
        pos0 = foot_positions_w(p, foot_offsets_w(q, fb.craft.leg_radius_m,
                                                  fb.craft.com_height_m))
        p2 = hold_footprint(p2, pos0, ft2, j, c_turn, s_turn)
    return SubStep(p2, fr.vel_mps, q2, fr.omega_body_radps, fr.sliding, fr.impulse_ns / h,
                   res.peak_penetration_m, res.located, pressed, fr.hold_w)


@kernel
def _a_down(fb, p, q, r_hat):
    """Acceleration toward the ground along local up in free flight: g - T cos(tilt) / m."""
    cr = fb.craft
    return cr.gm_m3ps2 / dot(p, p) - cr.thrust_n * dot(quat_axis_z(q), r_hat) / cr.mass_kg


#: Most contact events one sub-step is split at: a foot starting to press (its onset) or ceasing
#: to (its release), each located and stepped to.
MAX_PIECES = 8


#: Most pieces a sub-step is cut into where Coulomb's law is stiff (sim.stiff_substep), beside
#: those cut at events: a 25 ms sub-step in 1 ms pieces
MAX_REFINED = 25


#: Most trial steps locating one event (regula falsi, Anderson-Bjorck), and where it stops: within
#: EVENT_TOL_M of it (a foot's penetration, or its force over its stiffness; a position a
#: planet's radius from its centre is known to ~1e-9 m), or the bracket narrower than EVENT_TOL_S.
MAX_EVENT_ITERATIONS = 40


EVENT_TOL_M = 1e-9


EVENT_TOL_S = 1e-12


#: an engage threshold no penetration passes: a foot kept from pressing (sim.contact.evaluate)
NEVER = -math.inf

#: an engage threshold every penetration passes: a foot kept pressing (sim.contact.evaluate)
ALWAYS = math.inf


class Memo(NamedTuple):
    """A contact evaluation and what it was evaluated at: the free-flight loop asks for the
    contact at one state several times (a piece's end for its drag, its breakaway and its events,
    the sub-step's end for the guard, the next sub-step's start), and an evaluation is a pure
    function of these, so one asked again with all of them equal is the same bits. (The
    FreeBody's drag_dir is not kept: every memo is made and asked with free_flight's own, which
    only to_event's trial steps change, and they ask none.)"""

    valid: bool
    ce: ContactEval
    t_s: float  # from the tick's start (the ground there: ground_at)
    motion: Motion
    absorbing: bool
    engage: tuple
    kinetic: tuple  # the FreeBody's grip (sim.dynamics.with_feet)
    hold_w: tuple  # the FreeBody's (with_hold)


@kernel
def _same4(a, b):
    return a[0] == b[0] and a[1] == b[1] and a[2] == b[2] and a[3] == b[3]


@kernel
def _same3(a, b):
    return a[0] == b[0] and a[1] == b[1] and a[2] == b[2]


@kernel
def _same_vecs(a, b):
    return _same3(a[0], b[0]) and _same3(a[1], b[1]) and _same3(a[2], b[2]) and _same3(a[3], b[3])


@kernel
def _same_motion(a, b):
    return _same3(a.p, b.p) and _same3(a.v, b.v) and _same4(a.q, b.q) and _same3(a.w, b.w)


@kernel
def memo_of(fb, ce, t_s, m, absorbing, engage):
    """The :class:`Memo` of ``ce``, evaluated by ``contact_at(fb, ground_at(fb, t_s), m, ...)``."""
    g = fb.grip
    return Memo(True, ce, t_s, m, absorbing, engage, g.kinetic, g.hold_w)


@kernel
def no_memo(m):
    """A :class:`Memo` that matches nothing."""
    return Memo(False, no_contact(m.p), 0.0, m, False, ENGAGE_AT_GROUND, NO_SLIP, NO_HOLD)


@kernel
def memo_at(memo, here, fb, t_s, m, absorbing, engage):
    """Whether ``memo`` was evaluated by ``contact_at(fb, ground_at(fb, t_s), m, absorbing,
    engage)``: at exactly these. ``here``: the caller knows it was at the motion ``m`` itself
    (nothing has moved the ship since: the same bits, so the motion's 13 values need not be
    compared)."""
    return (memo.valid and memo.t_s == t_s and memo.absorbing == absorbing
            and _same4(memo.engage, engage) and _same4(memo.kinetic, fb.grip.kinetic)
            and (here or _same_motion(memo.motion, m)) and _same_vecs(memo.hold_w, fb.grip.hold_w))


@kernel
def contact_memo(memo, here, fb, t_s, m, absorbing, engage):
    """``contact_at(fb, ground_at(fb, t_s), m, absorbing, engage)``: ``memo``'s if it was
    evaluated at exactly these (:func:`memo_at`), else evaluated here, inline
    (sim.dynamics.contact_inline: no call with ~80 arguments, no ContactEval passed back)."""
    if memo_at(memo, here, fb, t_s, m, absorbing, engage):
        return memo.ce
    return contact_inline(fb, ground_at(fb, t_s), m, absorbing, engage)


class FootEvents(NamedTuple):
    """Which feet change over a step: those that start to press (``onset``: not pressing at its
    start, in the ground at its end), those that stop (``release``: pressing at its start, their
    spring-damper no longer pushing at its end, or, absorbed, out of the ground), and the sliding
    feet whose slip turned round (``stop``: dragged by kinetic friction, their slip at the end
    against their slip at the start, ``stop_dir``: they stop where their slip along it is zero,
    and stick there: MODEL-NOTES 46)."""

    onset: tuple
    release: tuple
    stop: tuple
    stop_dir: tuple
    stop_speed: tuple  # each stopping foot's slip at the step's start, m/s
    #: the holding feet (their regime static) break away where holding them would take more
    #: than their cones give (sim.dynamics.held_friction's use past 1); mu_s (0: not asked)
    break_mu: float
    any: bool


@kernel
def _pressing(ce, absorbing, engage):
    """The feet that press at an evaluation: touching and pushing (or touching, absorbed)."""
    f, pen = ce.foot_force_n, ce.pen_m
    return ((pen[0] > -engage[0]) and (absorbing or f[0] > 0.0),
            (pen[1] > -engage[1]) and (absorbing or f[1] > 0.0),
            (pen[2] > -engage[2]) and (absorbing or f[2] > 0.0),
            (pen[3] > -engage[3]) and (absorbing or f[3] > 0.0))


@kernel
def _gaps(fb, t_s, motion, absorbing, ev):
    """How far each foot of ``ev`` is past its event at the state ``motion``, m: positive once it
    has happened. Onset: its penetration; release: -(k x + c x') / k (absorbed: -x). Returns the
    largest."""
    ce = contact_inline(fb, ground_at(fb, t_s), motion, absorbing, ENGAGE_AT_GROUND)
    c_leg = fb.craft.c_absorb_nspm if absorbing else fb.craft.c_nspm
    out = -math.inf
    for i in range(4):
        if ev.onset[i]:
            out = fmax(out, ce.pen_m[i])
        if ev.release[i]:
            if absorbing:
                out = fmax(out, -ce.pen_m[i])
            else:
                out = fmax(out, -(ce.pen_m[i] + (c_leg / fb.craft.k_npm) * ce.pen_rate_mps[i]))
        if ev.stop[i]:  # a slip's turning (m/s): past it once the slip runs against where it ran
            out = fmax(out, -dot(ce.slip_w[i], ev.stop_dir[i]))
    if ev.break_mu > 0.0:  # the holding feet's breakaway: their cones used past the full
        kin = fb.grip.kinetic
        held = (not kin[0], not kin[1], not kin[2], not kin[3])
        hf = held_friction(fb, ground_at(fb, t_s), ce, motion, Holding(held, ev.break_mu))
        out = fmax(out, hf.use - 1.0)
    return out


@kernel
def foot_events(ce_start, ce, absorbing, engage):
    """The feet that start or stop pressing between a step's start (``ce_start``) and its end
    (``ce``: the contact there, evaluated with the same ``engage``)."""
    before = _pressing(ce_start, absorbing, engage)
    after = _pressing(ce, absorbing, engage)
    pen = ce.pen_m
    onset = ((not before[0]) and pen[0] > 0.0 and not ce_start.pen_m[0] > -engage[0],
             (not before[1]) and pen[1] > 0.0 and not ce_start.pen_m[1] > -engage[1],
             (not before[2]) and pen[2] > 0.0 and not ce_start.pen_m[2] > -engage[2],
             (not before[3]) and pen[3] > 0.0 and not ce_start.pen_m[3] > -engage[3])
    release = (before[0] and not after[0], before[1] and not after[1],
               before[2] and not after[2], before[3] and not after[3])
    z = (0.0, 0.0, 0.0)
    found = False
    for i in range(4):
        found = found or onset[i] or release[i]
    return FootEvents(onset, release, NO_SLIP, (z, z, z, z), (0.0, 0.0, 0.0, 0.0), 0.0, found)


#: m/s: a sliding foot whose slip along where it ran is under this at a located event has stopped
STOPPED_MPS = 1e-6


@kernel
def stop_speeds(ce, stop):
    """|s_i| at ``ce`` for the feet of ``stop`` (0 for the others)."""
    z = (0.0, 0.0, 0.0, 0.0)
    for i in range(4):
        v = norm(ce.slip_w[i]) if stop[i] else 0.0
        z = (v if i == 0 else z[0], v if i == 1 else z[1], v if i == 2 else z[2],
             v if i == 3 else z[3])
    return z


#: a located stop is one where what is left of a foot's slip across where it ran is under this
#: fraction of what it was: a slip that only turned (its size kept up by the ship's turning) has
#: not stopped
STOP_LEFT = 0.1


@kernel
def turned_round(fb, t_s, st, absorbing, ev):
    """The feet of ``ev.stop`` whose slip has turned round by the end of ``st`` (the located event
    is the earliest of the feet's: the others stop later) and come to rest there (what is left of
    it across where it ran under STOP_LEFT of what it was)."""
    ce = contact_at(fb, ground_at(fb, t_s), Motion(st.p, st.v, st.q, st.w), absorbing,
                    ENGAGE_AT_GROUND)
    out = (False, False, False, False)
    for i in range(4):
        s_i = ce.slip_w[i]
        along = dot(s_i, ev.stop_dir[i])
        left = norm(sub(s_i, scale(ev.stop_dir[i], along)))
        done = (ev.stop[i] and along <= STOPPED_MPS
                and left <= fmax(STOP_LEFT * ev.stop_speed[i], cfg_stick(fb)))
        out = (out[0] or (done and i == 0), out[1] or (done and i == 1),
               out[2] or (done and i == 2), out[3] or (done and i == 3))
    return out


@kernel
def cfg_stick(fb):
    """A slip left at a located stop that counts as none, m/s (the default stick speed's
    order: the rigid feet's kinematic micro-slips)."""
    return 1e-4


@kernel
def holds(cfg, fb, t_s, st, ft, ev):
    """(stuck, slid on): the feet of ``ev.stop`` that stick at the end of ``st`` (the located
    instant the first of them stopped): their slip has turned round there
    (:func:`turned_round`), and static friction can hold them, with the feet that already hold
    (sim.dynamics.held_friction, within mu_s of their load); and those that cannot: a foot whose
    slip the ship's own turning keeps up (a foot under an impact's load on a ship turning over
    it) slides on, and for the rest of the sub-step its stops are not located (its friction is
    an impulse after each piece: Coulomb's law is stiff there)."""
    done = turned_round(fb, t_s, st, ft.absorbing, ev)
    if not (done[0] or done[1] or done[2] or done[3]):
        return done, NO_SLIP
    sl = st.sliding
    held = (not (sl[0] and not done[0]), not (sl[1] and not done[1]),
            not (sl[2] and not done[2]), not (sl[3] and not done[3]))
    # the feet asked to hold take no kinetic friction among the other forces: a stopping foot was
    # dragged up to its stop, and its drag, counted with the static force that would hold it,
    # asked 1.03 of its cone where the reference's law at the same state asks 0.83 (MODEL-NOTES 70)
    kin = fb.grip.kinetic
    body = with_feet(fb, fb.grip.engage_m, (kin[0] and not held[0], kin[1] and not held[1],
                                            kin[2] and not held[2], kin[3] and not held[3]))
    ground = ground_at(fb, t_s)
    ce = contact_at(body, ground, Motion(st.p, st.v, st.q, st.w), ft.absorbing, ENGAGE_AT_GROUND)
    hf = held_friction(body, ground, ce, Motion(st.p, st.v, st.q, st.w),
                       Holding(held, cfg.friction_static))
    if hf.capped:
        return NO_SLIP, done
    return done, NO_SLIP


class Piece(NamedTuple):
    """A stretch of a sub-step stepped up to the instant a foot starts or stops pressing."""

    tau_s: float  # its length
    step: SubStep
    found: bool  # False: none of the feet asked changes within the stretch


@separate
def to_event(cfg, fb, roles, h, start, ev):
    """The earliest instant inside (0, h) of a step from ``start`` (a :class:`StepFrom`) at which
    one of the feet of ``ev`` starts or stops pressing, and the step to it (the feet about to press
    kept from pressing): regula falsi (Anderson-Bjorck) on :func:`_gaps`, each trial a step of
    the method from the start. A contact that starts or ends inside a step is thus integrated like
    a crossing, for any foot (the fourth as the first), and happens where it does, not at the
    step's end. The step returned ends just past the event (its gap within EVENT_TOL_M above
    zero)."""
    engage, sliding, dragged, absorbing = roles
    t0 = start.t_s
    on = ev.onset
    # an absorbed foot's force jumps to zero where it leaves the ground (c x' is not zero
    # there): kept pressing through the trials, so that no stage of a trial ending just past
    # its release (EVENT_TOL_M) loses its pull (rk4's last stage, a sixth of the piece's pull:
    # MODEL-NOTES 52); a foot about to press kept from pressing likewise. Not with the
    # exponential method (sim.flow_release): its flow lets go at the release itself, and a pull
    # kept on past it reached its closing kick as a damper's pull after the release (MODEL-NOTES 66)
    off = (ev.release if absorbing and not (cfg.flow_release and fb.craft.method == EXPONENTIAL)
           else NO_SLIP)
    held_off = (NEVER if on[0] else (ALWAYS if off[0] else engage[0]),
                NEVER if on[1] else (ALWAYS if off[1] else engage[1]),
                NEVER if on[2] else (ALWAYS if off[2] else engage[2]),
                NEVER if on[3] else (ALWAYS if off[3] else engage[3]))
    held_roles = FootRoles(held_off, sliding, dragged, absorbing)
    body = with_feet(fb, held_off, dragged)
    t_lo = 0.0
    g_lo = _gaps(body, t0, start.motion, absorbing, ev)
    st_hi = substep(cfg, fb, held_roles, h, start)
    g_hi = _gaps(body, t0 + h, Motion(st_hi.p, st_hi.v, st_hi.q, st_hi.w), absorbing, ev)
    if not (g_hi > 0.0 and g_lo < 0.0):
        if off[0] or off[1] or off[2] or off[3]:  # (the pull kept on held it in the ground)
            return Piece(h, substep(cfg, fb, roles, h, start), False)
        return Piece(h, st_hi, False)
    if g_hi <= EVENT_TOL_M:  # the step's end is already just past the event
        return Piece(h, st_hi, True)
    # the trials aim half the tolerance past the event, so that they end inside it from either
    # side; Anderson-Bjorck: an end kept twice has its value scaled by how much the other end's
    # fell (1 - G_new / G_old), by half where that is not positive (Illinois's factor)
    aim = 0.5 * EVENT_TOL_M
    G_lo, G_hi = g_lo - aim, g_hi - aim
    t_hi = h
    side = 0
    for _ in range(MAX_EVENT_ITERATIONS):
        t = (t_lo * G_hi - t_hi * G_lo) / (G_hi - G_lo)
        if not (t > t_lo and t < t_hi):
            t = 0.5 * (t_lo + t_hi)
        st = substep(cfg, fb, held_roles, t, start)
        g = _gaps(body, t0 + t, Motion(st.p, st.v, st.q, st.w), absorbing, ev)
        if g > 0.0 and g <= EVENT_TOL_M:
            return Piece(t, st, True)
        G = g - aim
        if G > 0.0:
            if side == 1:
                f = 1.0 - G / G_hi
                G_lo = (f if f > 0.0 else 0.5) * G_lo
            t_hi, G_hi, st_hi = t, G, st
            side = 1
        else:
            if side == -1:
                f = 1.0 - G / G_lo
                G_hi = (f if f > 0.0 else 0.5) * G_hi
            t_lo, G_lo = t, G
            side = -1
        if t_hi - t_lo <= EVENT_TOL_S:
            break
    return Piece(t_hi, st_hi, True)


#: A sliding foot is dragged by its kinetic friction as a force, integrated with the springs, and
#: the instant its slip turns round is located (FootEvents.stop); one whose own friction could stop
#: it within DRAG_REACH times the step takes its friction as an impulse of mu_k J_i after the step
#: instead (sim.friction.coulomb): so near its stop a force of fixed size turning round with the
#: slip inside the method's stages would leave the slip where it was.
DRAG_REACH = 1.0


#: a sliding foot that its friction could stop within STIFF_REACH of the step and that is not
#: slowing takes its friction as an impulse (step_piece): the drag's direction would turn faster
#: than rk4's stages follow (its rate over the step past ~2.8)
STIFF_REACH = 0.4


#: a sub-step is cut into pieces (sim.stiff_substep) where a sliding foot that is not slowing
#: could stop within PIECE_REACH of it: below STIFF_REACH it would take an impulse after the
#: step, first order in it; between the two it is dragged, and its drag turns with its slip at a
#: rate of 1 / (the time its friction takes to stop it), which rk4 over 1 to 2.5 such times damps
#: wrongly (MODEL-NOTES 46)
PIECE_REACH = 1.0


@kernel
def _inv_mass_along(fb, q, i, s_hat):
    """1 / m_eff of foot i along the unit ``s_hat``: 1 / m + (r x s_hat) . I^-1 (r x s_hat)."""
    arm = quat_rotate_inv(q, cross(foot_offsets_w(q, fb.craft.leg_radius_m,
                                                  fb.craft.com_height_m)[i], s_hat))
    return 1.0 / fb.craft.mass_kg + dot(arm, div(arm, fb.craft.inertia_kgm2))


@kernel
def _could_stop(cfg, fb, ce0, ce1, q, i, h):
    """Whether foot i's own kinetic friction could slow its slip (at ``ce0``) to the stick speed
    within DRAG_REACH h: (|s| - stick) m_eff / (mu_k N) < DRAG_REACH h, N the larger of the foot's
    normal forces at the step's ends (``ce0``, ``ce1``: an impact's grows fast), m_eff the ship's
    mass as the foot feels it along its slip, 1 / m_eff = 1 / m + (r x s_hat) . I^-1 (r x s_hat)."""
    s0 = ce0.slip_w[i]
    speed = norm(s0)
    if not speed > cfg.stick_speed_mps:
        return True
    drag = fb.craft.mu_k * fmax(ce0.foot_force_n[i] * ce0.push_norm[i],
                          ce1.foot_force_n[i] * ce1.push_norm[i])
    s_hat = unit(s0)
    inv_m = _inv_mass_along(fb, q, i, s_hat)
    return (speed - cfg.stick_speed_mps) < DRAG_REACH * h * drag * inv_m


@kernel
def _could_stop_rated(cfg, fb, sr, ce0, ce1, i, h):
    """:func:`_could_stop` with foot i's |s| and 1 / m_eff taken from ``sr``, the
    :class:`SlipRates` rated at ``ce0`` and the attitude asked (slip_rates forms them by the same
    operations: the same bits, without the foot's offsets, its arm and the divisions again)."""
    speed = sr.speed[i]
    if not speed > cfg.stick_speed_mps:  # (stick >= 0: a foot that slips, inv_mass formed)
        return True
    drag = fb.craft.mu_k * fmax(ce0.foot_force_n[i] * ce0.push_norm[i],
                          ce1.foot_force_n[i] * ce1.push_norm[i])
    return (speed - cfg.stick_speed_mps) < DRAG_REACH * h * drag * sr.inv_mass[i]


class SlipRates(NamedTuple):
    """Each foot's slip, how fast it changes along itself, and how fast its own kinetic friction
    alone would slow it (sim.flight.slip_rates)."""

    speed: tuple  # |s_i|, m/s
    rate: tuple  # d|s_i|/dt, m/s^2, from every force at once
    own: tuple  # mu_k N_i / m_eff,i, m/s^2
    across: tuple  # |ds_i/dt - (d|s_i|/dt) s_hat_i|, m/s^2: what turns the slip
    #: 1 / m_eff,i along s_hat_i (:func:`_inv_mass_along`'s), 1/kg; 0 where the foot does not slip
    inv_mass: tuple = (0.0, 0.0, 0.0, 0.0)


@kernel
def slip_rates(cfg, fb, ground, ce, m):
    """:class:`SlipRates` at the contact ``ce`` of the state ``m`` (the holding feet's friction
    among the forces, sim.dynamics.held_friction). A foot coming to a stop has its slip falling at
    least half as fast as its own friction would slow it; one whose slip the ship's turning keeps
    up (under an impact's load, the other feet sliding and one holding) has not, though its
    friction could stop it within a step: its slip is a balance, and Coulomb's law there is stiff
    (its direction turns within a fraction of the step)."""
    kin = fb.grip.kinetic
    held = (not kin[0], not kin[1], not kin[2], not kin[3])
    d, _ = derivatives_held(fb, ground, ce, m, Holding(held, cfg.friction_static))
    off = foot_offsets_w(m.q, fb.craft.leg_radius_m, fb.craft.com_height_m)
    omega_w = quat_rotate(m.q, m.w)
    alpha_w = quat_rotate(m.q, d[3])
    spin = (0.0, 0.0, fb.craft.body_omega_radps)
    speeds = (0.0, 0.0, 0.0, 0.0)
    rates = (0.0, 0.0, 0.0, 0.0)
    owns = (0.0, 0.0, 0.0, 0.0)
    acrosses = (0.0, 0.0, 0.0, 0.0)
    inv_ms = (0.0, 0.0, 0.0, 0.0)
    for i in range(4):
        s0 = ce.slip_w[i]
        speed = norm(s0)
        rate = 0.0
        own = 0.0
        across = 0.0
        inv_m = 0.0
        if speed > 0.0:
            s_hat = unit(s0)
            r = off[i]
            acc = add(add(d[1], cross(alpha_w, r)), cross(omega_w, cross(omega_w, r)))
            acc = sub(acc, cross(spin, add(m.v, cross(omega_w, r))))
            rate = dot(acc, s_hat)
            across = norm(sub(acc, scale(s_hat, rate)))
            arm = quat_rotate_inv(m.q, cross(r, s_hat))
            inv_m = 1.0 / fb.craft.mass_kg + dot(arm, div(arm, fb.craft.inertia_kgm2))
            own = fb.craft.mu_k * ce.foot_force_n[i] * ce.push_norm[i] * inv_m
        speeds = (speed if i == 0 else speeds[0], speed if i == 1 else speeds[1],
                  speed if i == 2 else speeds[2], speed if i == 3 else speeds[3])
        rates = (rate if i == 0 else rates[0], rate if i == 1 else rates[1],
                 rate if i == 2 else rates[2], rate if i == 3 else rates[3])
        owns = (own if i == 0 else owns[0], own if i == 1 else owns[1],
                own if i == 2 else owns[2], own if i == 3 else owns[3])
        acrosses = (across if i == 0 else acrosses[0], across if i == 1 else acrosses[1],
                    across if i == 2 else acrosses[2], across if i == 3 else acrosses[3])
        inv_ms = (inv_m if i == 0 else inv_ms[0], inv_m if i == 1 else inv_ms[1],
                  inv_m if i == 2 else inv_ms[2], inv_m if i == 3 else inv_ms[3])
    return SlipRates(speeds, rates, owns, acrosses, inv_ms)


#: no foot slips
NO_RATES = SlipRates((0.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0),
                     (0.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0))


@kernel
def slowing(sr, i):
    """Foot i's slip falls at least half as fast as its own friction would slow it."""
    return sr.speed[i] > 0.0 and sr.own[i] > 0.0 and sr.rate[i] < -0.5 * sr.own[i]


@kernel
def stopping(cfg, dragged, sr, ce0, ce1, h):
    """The dragged feet that stop inside a step of h: slowing (:func:`slowing`) at a rate that
    brings them to the stick speed within 1.5 h, or whose slip turned round in a trial step
    (``ce1``, its end; ``ce0``, its start); as a FootEvents of stops, each along the foot's slip
    at the start."""
    z = (0.0, 0.0, 0.0)
    stop = (False, False, False, False)
    stop_dir = (z, z, z, z)
    found = False
    for i in range(4):
        s0 = ce0.slip_w[i]
        soon = sr.speed[i] - cfg.stick_speed_mps < -1.5 * h * sr.rate[i]
        now = (dragged[i] and dot(s0, s0) > 0.0 and slowing(sr, i)
               and (soon or dot(ce1.slip_w[i], s0) < 0.0))
        d = unit(s0) if now else z
        found = found or now
        stop = (now if i == 0 else stop[0], now if i == 1 else stop[1], now if i == 2 else stop[2],
                now if i == 3 else stop[3])
        stop_dir = (d if i == 0 else stop_dir[0], d if i == 1 else stop_dir[1],
                    d if i == 2 else stop_dir[2], d if i == 3 else stop_dir[3])
    return FootEvents(NO_SLIP, NO_SLIP, stop, stop_dir, stop_speeds(ce0, stop), 0.0, found)


#: a stopping foot's slip turns on its way to the stop where what turns it, over what slows it,
#: is past this (about the angle, rad, it turns by at its present rates: |across| T / |s| with
#: T = |s| / -rate); then it may pass its least short of zero (MODEL-NOTES 58)
TURN_REACH = 0.5


@kernel
def turns(stop, sr):
    """Whether the slip of a foot of ``stop.stop`` turns on its way to its stop: its rates
    (``sr``) turn it by more than TURN_REACH rad before it gets there."""
    for i in range(4):
        if stop.stop[i] and sr.across[i] > -TURN_REACH * sr.rate[i]:
            return True
    return False


@kernel
def approach_time(cfg, stop, sr):
    """The shortest time the feet of ``stop.stop`` take to slow to the stick speed at their
    present rates (``sr``), s."""
    out = math.inf
    for i in range(4):
        if stop.stop[i] and sr.rate[i] < 0.0:
            out = fmin(out, (sr.speed[i] - cfg.stick_speed_mps) / -sr.rate[i])
    return out


@kernel
def _turned_any(stop, ce0, ce1):
    """Whether the slip of any foot of ``stop.stop`` runs against where it ran (at ``ce0``) at
    ``ce1``."""
    out = False
    for i in range(4):
        out = out or (stop.stop[i] and dot(ce1.slip_w[i], ce0.slip_w[i]) < 0.0)
    return out


@kernel
def dragged_feet(cfg, fb, sliding, sr, ce0, ce1, h):
    """The sliding feet dragged by their friction as a force over a step of h: those that could
    not stop within it (:func:`_could_stop`, its slip's terms from ``sr``, the
    :class:`SlipRates` at ``ce0``: :func:`_could_stop_rated`; none under the seed's law)."""
    out = (False, False, False, False)
    if fb.craft.mu_k > 0.0:
        for i in range(4):
            d = sliding[i] and not _could_stop_rated(cfg, fb, sr, ce0, ce1, i, h)
            out = (out[0] or (d and i == 0), out[1] or (d and i == 1),
                   out[2] or (d and i == 2), out[3] or (d and i == 3))
    return out


@kernel
def with_stopping(drag, near, stiff, sr):
    """The feet of ``near`` and those of ``drag`` coming to a stop (:func:`slowing`, from ``sr``)
    whose stops are looked for (not of ``stiff``): dragged, so that their stop is located."""
    return (near[0] or (drag[0] and not stiff[0] and slowing(sr, 0)),
            near[1] or (drag[1] and not stiff[1] and slowing(sr, 1)),
            near[2] or (drag[2] and not stiff[2] and slowing(sr, 2)),
            near[3] or (drag[3] and not stiff[3] and slowing(sr, 3)))


@kernel
def regimes_on_touch(cfg, ce, sliding, fresh):
    """Each foot's friction regime as it starts to press (``fresh``): kinetic if it meets the
    ground slipping faster than the stick speed."""
    out = sliding
    for i in range(4):
        now = sliding[i]
        if fresh[i]:
            s = ce.slip_w[i]
            now = dot(s, s) > cfg.stick_speed_mps * cfg.stick_speed_mps
        out = (now if i == 0 else out[0], now if i == 1 else out[1],
               now if i == 2 else out[2], now if i == 3 else out[3])
    return out


@kernel
def at_ground(ce, engage, a_down):
    """The feet at the ground now (within ONSET_MARGIN_M of it) and going into it (or at rest on
    it while the ship accelerates down, ``a_down`` > 0): they press from this instant (their
    engage threshold becomes the margin). Returns the new thresholds and whether any foot is at
    the ground."""
    out = engage
    reach = False
    for i in range(4):
        rate = ce.pen_rate_mps[i]
        if abs(ce.pen_m[i]) < ONSET_MARGIN_M and (rate > 0.0 or (rate == 0.0 and a_down > 0.0)):
            reach = True
            if not ce.pen_m[i] > -engage[i]:
                out = (ONSET_MARGIN_M if i == 0 else out[0], ONSET_MARGIN_M if i == 1 else out[1],
                       ONSET_MARGIN_M if i == 2 else out[2], ONSET_MARGIN_M if i == 3 else out[3])
    return out, reach


@kernel
def engaged_near(ce):
    """Every foot within ONSET_MARGIN_M of the ground presses (after a touchdown's alignment has
    moved them all)."""
    pen = ce.pen_m
    return (ONSET_MARGIN_M if pen[0] > -ONSET_MARGIN_M else 0.0,
            ONSET_MARGIN_M if pen[1] > -ONSET_MARGIN_M else 0.0,
            ONSET_MARGIN_M if pen[2] > -ONSET_MARGIN_M else 0.0,
            ONSET_MARGIN_M if pen[3] > -ONSET_MARGIN_M else 0.0)


class Touchdown(NamedTuple):
    """The seed's Flying -> Contact rules applied at the instant the first foot reaches the
    ground."""

    p: tuple
    v: tuple
    q: tuple
    w: tuple
    impact_mps: float  # the centre of mass's descent speed there, relative to the surface
    absorbing: bool
    aligned: bool


@kernel
def touchdown(cfg, fb, ground, m, pen_m):
    """An impact slower than bounce_speed is taken by the absorbers from its first instant
    (SEED-NOTES 1); the seed's alignment (align_on_touchdown) happens here (MODEL-NOTES 18).
    ``m``: the ship's motion at the touchdown; ``pen_m``: its feet's penetrations there
    (:func:`align_at_touchdown`)."""
    p, v, q, w = m
    r_hat = unit(p)
    impact = -dot(sub(v, surface_velocity(fb.craft.body_omega_radps, p)), r_hat)
    aligned = False
    if cfg.align_on_touchdown:
        al = align_at_touchdown(fb, ground, m, pen_m)
        p, v, q, w, aligned = al.p, al.v, al.q, al.w, al.aligned
    return Touchdown(p, v, q, w, impact, impact < cfg.bounce_speed_mps, aligned)


@kernel
def clear_instant(fb, ground, ce, motion, h):
    """How long before the end of a (sub-)step the last foot left the ground, for a ship whose
    feet are all clear at its end: the lowest foot's flight back to the ground, at the rate its
    gap grows (sim.contact.rise_rate) under g - T cos(tilt) / m (exact for a vertical bounce
    under uniform gravity, and for a plane slope's gap; the spring had let go before). Clamped
    to the step."""
    p, v, q, w = motion
    r_hat = unit(p)
    z = -ce.max_penetration_m
    om = fb.craft.body_omega_radps
    spin = cross(quat_rotate(q, w), sub(ce.lowest_foot_w, p))
    if ground.terrain.level:
        u = dot(add(sub(v, surface_velocity(om, ce.lowest_foot_w)), spin), r_hat)
    else:
        u = rise_rate(ground, ce.lowest_foot_w, add(v, spin), unit(ce.lowest_foot_w))
    a_dn = _a_down(fb, p, q, r_hat)
    disc = u * u + 2.0 * a_dn * z
    denom = u + math.sqrt(fmax(disc, 0.0))
    if not (z > 0.0 and disc >= 0.0 and denom > 0.0):
        return 0.0
    return fmin(2.0 * z / denom, h)


@kernel
def crossed_at(a0, a1, level, t0, t1):
    """The instant a quantity going from a0 (at t0) to a1 (at t1) passed ``level``, linearly."""
    d = a1 - a0
    if d == 0.0:
        return t1
    f = fmin(fmax((level - a0) / d, 0.0), 1.0)
    return t0 + f * (t1 - t0)


class Flight(NamedTuple):
    """A free ship after its tick of flight."""

    ship: Ship
    report: Report
    run: "SettleRun"  # the settle thresholds at its sub-steps' ends (NO_RUN: not sampled)


class SubStepStart(NamedTuple):
    """A sub-step: where it starts and ends, and its start's state, as its end's transitions
    compare with it."""

    t_s: float  # from the tick's start
    t_end_s: float  # where it ends, from the tick's start
    h_s: float  # its length
    pen_m: float  # the deepest foot's penetration
    v_rad_mps: float  # velocity along local up
    cos_tilt: float


# -- 2a. the touchdown instant: a piece of a sub-step at its start -------------------------------
class PieceStart(NamedTuple):
    """A piece of a sub-step at its start: the seed's touchdown rules applied if the first foot is
    at the ground here, each foot's friction regime as it meets it, and the contact the piece is
    stepped from."""

    ship: Ship
    t_s: float  # from the tick's start
    engage: tuple  # each foot's engage threshold from here (sim.contact.evaluate)
    drag: tuple  # the sliding feet dragged by kinetic friction as a force
    ce: ContactEval  # the contact at this instant
    carried: tuple  # the holding feet's friction the piece's FreeBody carries
    aligned: bool  # a touchdown here stood the ship up (align_on_touchdown)
    e_ref: EnergyRef  # the passivity guard's reference (measured anew after an alignment)
    stop: bool  # tipped or crashed at the touchdown: pinned for the rest of the tick
    memo: Memo  # the last contact evaluated (``ce``'s, where it was evaluated here)


@kernel
def touchdown_rules(cfg, om, p, v, q, impact_mps, aligned):
    """The seed's rules at a touchdown, the one place they are written (both the located
    touchdown, :func:`touchdown_transitions`, and the last-resort one at a sub-step's end,
    :func:`in_flight_transitions`, apply them): crashed above crash_speed, else contact; a ship
    lying down already (tilted past tipped_angle and not stood up by the alignment) goes on at
    once to tipped, or to crashed if it moves faster than crash_speed relative to the ground: its
    hull, which the model does not have, is what touches (MODEL-NOTES 12). Returns the state the
    touchdown enters and the state it goes on to at the same instant (the same state if none)."""
    if impact_mps > cfg.crash_speed_mps:
        return CRASHED, CRASHED
    if not aligned and dot(quat_axis_z(q), unit(p)) < cfg.cos_tipped:
        v_rel = sub(v, surface_velocity(om, p))
        return CONTACT, (CRASHED if dot(v_rel, v_rel) > cfg.crash_speed2 else TIPPED)
    return CONTACT, CONTACT


@kernel
def emit_touchdown(log, entered, then, impact_mps, t_s):
    """A touchdown's transitions, in order, each with the descent speed at the touchdown."""
    emit(log, FLYING, entered, -impact_mps, t_s)
    if then != entered:
        emit(log, entered, then, -impact_mps, t_s)


@kernel
def touchdown_transitions(cfg, fb, s, td, t_abs, log):
    """The transitions of a touchdown located at ``t_abs`` (``s`` already aligned), emitted in
    order; returns the state they lead to (:func:`touchdown_rules`)."""
    m = s.motion
    entered, then = touchdown_rules(cfg, fb.craft.body_omega_radps, m.p, m.v, m.q, td.impact_mps,
                                    td.aligned)
    emit_touchdown(log, entered, then, td.impact_mps, t_abs)
    return then


@kernel
def pinned_at(fb, s, ce, t_s):
    """The pin of a ship that tips or crashes ``t_s`` into the tick: its pose in the body-fixed
    frame, and a tipped ship's pivot (its lowest foot) and rate of turn about it."""
    m = s.motion
    c, s_ = turned(fb.craft.cos0, fb.craft.sin0, fb.craft.body_omega_radps, t_s)
    pin_p, pin_q = pin_pose(m.p, m.q, c, s_)
    if s.surface_state != TIPPED:
        return Pin(pin_p, pin_q, s.pin.pivot_bf_m, s.pin.rate_radps)
    return Pin(pin_p, pin_q, rotate_z(ce.lowest_foot_w, c, -s_),
               rate_from_momentum(fb.craft.body_omega_radps, fb.craft.mass_kg,
                                  fb.craft.inertia_kgm2, m, ce.lowest_foot_w))


@kernel
def piece_start(cfg, fb, ps, onset_now, here, log):
    """A piece's start ``ps`` (:class:`PieceStart`: the ship, its instant ``t_s`` into the tick,
    the feet's engage thresholds, the guard's reference and the last contact evaluated, as the
    last piece left them; ``fb`` carrying the held feet's friction) with its touchdown instant's
    rules applied: where the first foot is at the ground while the ship flies, the seed's
    touchdown (its alignment, the absorbers, its transitions: MODEL-NOTES 18); then the feet that
    meet the ground sliding or holding (``onset_now``: those the last located event touched).
    ``here``: ``ps.memo`` was evaluated at the ship's motion itself (:func:`contact_memo_here`)."""
    s, t_abs, engage, e_ref, memo = ps.ship, ps.t_s, ps.engage, ps.e_ref, ps.memo
    ground_y = ground_at(fb, t_abs)
    m, ft = s.motion, s.footing
    drag = ft.sliding
    carried = fb.grip.hold_w
    aligned = False
    fb_y = with_feet(fb, engage, drag)
    ce_y = contact_memo(memo, here, fb_y, t_abs, m, ft.absorbing, engage)
    memo = memo_of(fb_y, ce_y, t_abs, m, ft.absorbing, engage)
    touched = False  # the seed's touchdown here moved the ship (the memo is not at m then)
    was = engage
    engage, reach = at_ground(ce_y, engage, _a_down(fb, m.p, m.q, unit(m.p)))
    if reach and s.surface_state == FLYING:
        # the first foot is at the ground: the seed's touchdown, here and now
        td = touchdown(cfg, fb, ground_y, m, ce_y.pen_m)
        m = Motion(td.p, td.v, td.q, td.w)
        touched = True
        aligned = td.aligned
        carried = NO_HOLD
        fb = with_hold(fb, NO_HOLD)
        ft = fresh_footing(td.absorbing)
        drag = ft.sliding
        s = with_footing(with_motion(s, FLYING, m), ft)
        ce_y = contact_at(with_feet(fb, ENGAGE_AT_GROUND, drag), ground_y, m, ft.absorbing,
                          ENGAGE_AT_GROUND)
        engage = engaged_near(ce_y)
        was = ENGAGE_AT_GROUND
        s = with_motion(s, touchdown_transitions(cfg, fb, s, td, t_abs, log), m)
        if s.surface_state != CONTACT:
            s = with_pin(s, pinned_at(fb, s, ce_y, t_abs))
            return PieceStart(s, t_abs, engage, drag, ce_y, carried, aligned, e_ref, True,
                              no_memo(m))
        if cfg.energy_guard and aligned:  # the snap never adds energy; measure from after it
            # (ce_y's penetrations are at m on ground_y: sim.energy.mechanical's bits)
            e_ref = energy_ref(ship_energy_at(fb, ground_y, m, ce_y.pen_m))
    if per_foot(cfg):  # a foot meets the ground sliding or holding
        fresh = (engage[0] > was[0] or onset_now[0], engage[1] > was[1] or onset_now[1],
                 engage[2] > was[2] or onset_now[2], engage[3] > was[3] or onset_now[3])
        drag = regimes_on_touch(cfg, ce_y, ft.sliding, fresh)
        s = with_footing(s, with_friction(ft, drag, ft.hold_w))
    fb_y = with_feet(fb, engage, drag)
    if touched:
        hit = memo_at(memo, False, fb_y, t_abs, m, ft.absorbing, engage)
    else:  # the memo is this instant's, at m, with fb's held friction: only the roles changed
        hit = (memo.valid and _same4(memo.engage, engage)
               and _same4(memo.kinetic, fb_y.grip.kinetic))
    ce_y = memo.ce if hit else contact_inline(fb_y, ground_y, m, ft.absorbing, engage)
    return PieceStart(s, t_abs, engage, drag, ce_y, carried, aligned, e_ref, False,
                      memo_of(fb_y, ce_y, t_abs, m, ft.absorbing, engage))


# -- 2b. integrating: a piece of a sub-step, then the guard at the sub-step's end ----------------
class Fine(NamedTuple):
    """How a sub-step is cut where a sliding foot's friction is stiff (sim.stiff_substep)."""

    piece_s: float  # the shortest piece (0: no pieces)
    floor_s: float  # the feet its friction would stop sooner than this take no pieces


#: no pieces
NOT_FINE = Fine(0.0, 0.0)


class PieceStep(NamedTuple):
    """A piece stepped: to the sub-step's end, or to the instant a foot starts or stops pressing,
    or a sliding foot stops."""

    step: SubStep
    tau_s: float  # how far it went
    split: bool  # it ended at a foot's event before the sub-step's end
    onset: tuple  # the feet that event touched
    stopped: tuple  # the sliding feet that stopped there (they stick from there)
    slid_on: tuple  # the sliding feet whose slip turned round there but that cannot stick
    broke: tuple  # the holding feet that broke away there (kinetic from there)
    memo: Memo  # the last contact evaluated at the piece's end
    #: ``memo`` was evaluated at ``step``'s end state itself (with the piece's held friction)
    memo_here: bool
    refined: bool  # it was cut short where Coulomb's law is stiff, at no event (sim.stiff_substep)


@constructor
def step_piece(cfg, fb, start, rem, may_split, stiff, fine):
    """One step of the method over the ``rem`` left of the sub-step from ``start`` (a
    :class:`PieceStart`), a sliding foot that could stop within it taking its friction as an
    impulse instead; cut at the first foot that starts or stops pressing inside it, located
    (:func:`to_event`), unless ``may_split`` is False (the pieces' bound); and, where a sliding
    foot would take its friction as an impulse (:func:`stiff_feet`), no longer than the time its
    friction would take to stop it, nor shorter than ``fine.piece_s`` (0: the step whole), for
    the feet it would take ``fine.floor_s`` or longer to stop (a :class:`Fine`). ``stiff``: the
    feet whose stops are not located for the rest of the sub-step."""
    fine_s = fine.piece_s
    s, t_abs = start.ship, start.t_s
    m, ft = s.motion, s.footing
    engage, drag, ce_y = start.engage, start.drag, start.ce
    whole = rem
    sr = NO_RATES
    rated = False  # sr is the sliding feet's at the piece's start
    if (fine_s > 0.0 and rem > fine_s * (1.0 + 1e-9) and fb.craft.mu_k > 0.0
            and (drag[0] or drag[1] or drag[2] or drag[3])):
        body = with_feet(fb, engage, drag)
        sr = slip_rates(cfg, body, ground_at(fb, t_abs), ce_y, m)
        rated = True
        t_stop = stiff_feet(cfg, body, start, sr, PIECE_REACH * rem, stiff, fine.floor_s)
        if t_stop < math.inf:
            # Coulomb's law is stiff at such a foot: its impulse after the step is first order
            # in the step, and its drag turns faster than rk4's stages follow (MODEL-NOTES 46);
            # the piece is cut to equal parts no longer than the time its friction would take to
            # stop it, and than stiff_substep at the least, each taken as a piece of its own
            piece = fmax(fine_s, t_stop)
            if at_transition(cfg, body, start, sr, fine_s):
                # another foot is about to break away or has just begun to slide: the impulses
                # after a piece of stiff_substep, the stiff foot's kinetic one among them, would
                # hold it (its slip within what they take out over the piece); the pieces go
                # down to the stiff foot's stop time, so that it stays a force and the other
                # foot's breakaway is located (MODEL-NOTES 58)
                piece = fmax(TRANSITION_PIECE * fine_s, t_stop)
            if rem > piece * (1.0 + 1e-9):
                rem = rem / math.ceil(rem / piece - 1e-9)
    if fb.craft.mu_k > 0.0 and (drag[0] or drag[1] or drag[2] or drag[3]):
        # the dragged feet that the step's end cannot make dragged are taken off before it:
        # their friction could stop them within STIFF_REACH of it at their load here alone (the
        # larger load of the step's ends only makes that likelier: :func:`_could_stop`), and
        # they are not kept dragged to have their stop located; stepped with them dragged, the
        # step was taken again without them (a micro-slip near rest, every piece), the same
        # step as this one wherever no other foot's role turned on the first one's end
        body = with_feet(fb, engage, drag)
        if not rated:
            sr = slip_rates(cfg, body, ground_at(fb, t_abs), ce_y, m)
            rated = True
        may = dragged_feet(cfg, body, drag, sr, ce_y, ce_y, STIFF_REACH * rem)
        if may_split:
            may = with_stopping(drag, may, stiff, sr)
        if may[0] != drag[0] or may[1] != drag[1] or may[2] != drag[2] or may[3] != drag[3]:
            drag = may
            ce_y = contact_at(with_feet(fb, engage, drag), ground_at(fb, t_abs), m, ft.absorbing,
                              engage)
    st = substep(cfg, fb, FootRoles(engage, ft.sliding, drag, ft.absorbing), rem,
                 StepFrom(t_abs, m, ce_y))
    t_e = t_abs + rem
    memo = start.memo
    # the memo is at st's end with the feet's roles of now (with_feet(fb, engage, drag)): the
    # piece's own evaluations at its end find it without comparing anything
    at_end = False
    if fb.craft.mu_k > 0.0 and (drag[0] or drag[1] or drag[2] or drag[3]):
        body = with_feet(fb, engage, drag)
        m_e = Motion(st.p, st.v, st.q, st.w)
        ce_e = contact_memo(memo, False, body, t_e, m_e, ft.absorbing, engage)
        memo = memo_of(body, ce_e, t_e, m_e, ft.absorbing, engage)
        at_end = True
        # a sliding foot whose friction could stop it within a fraction of the step (a foot
        # under an impact's load, where Coulomb's law is stiff) takes its friction as an impulse
        # after it, from the feet's impulses solved together (sim.friction.coulomb), which stops
        # it without turning it round; so does every foot that could stop within the step once
        # the pieces' bound is reached
        # a foot whose slip the ship's turning keeps up is dragged too while the direction of
        # its drag, which turns with its slip at a rate of its friction's deceleration over its
        # slip, stays within what the method's stages follow (STIFF_REACH of the step)
        # (sr: rated above, at ce_y's slips and loads, which a re-evaluation with another drag
        # leaves as they are: the feet's springs and velocities, not their friction)
        near = dragged_feet(cfg, body, drag, sr, ce_y, ce_e, STIFF_REACH * rem)
        if may_split:  # of those, the ones coming to a stop are dragged, and their stop located
            near = with_stopping(drag, near, stiff, sr)
        if near[0] != drag[0] or near[1] != drag[1] or near[2] != drag[2] or near[3] != drag[3]:
            drag = near
            body = with_feet(fb, engage, drag)
            ce_y = contact_at(body, ground_at(fb, t_abs), m, ft.absorbing, engage)
            st = substep(cfg, fb, FootRoles(engage, ft.sliding, drag, ft.absorbing), rem,
                         StepFrom(t_abs, m, ce_y))
            m_e = Motion(st.p, st.v, st.q, st.w)
            # (the memo's kinetic feet are the old drag: it cannot serve)
            ce_e = contact_at(body, ground_at(fb, t_e), m_e, ft.absorbing, engage)
            memo = memo_of(body, ce_e, t_e, m_e, ft.absorbing, engage)
        if may_split:
            # one that stops later in the step (its friction could stop it, or its slip turned
            # round): dragged along where it slid until the instant its slip along there is
            # zero, located, and holding from there (MODEL-NOTES 46)
            stop = stopping(cfg, drag, sr, ce_y, ce_e, rem)
            if stop.any and fine_s > 0.0:
                # its slip turns as it slows (the other forces' part across it is not slowed):
                # stepped with its drag against its slip in pieces of half the time its stop
                # takes, down to a twentieth of stiff_substep, and only that last stretch dragged
                # along where it slid (MODEL-NOTES 51); outside an impact's sub-steps where it
                # turns by more than TURN_REACH on its way (a slip that passes its least short of
                # zero, dragged along where it slid, missed the turn: MODEL-NOTES 58)
                half = 0.5 * approach_time(cfg, stop, sr)
                if (half > 0.05 * fine_s and (fine.floor_s == 0.0 or turns(stop, sr))
                        and rem > half * (1.0 + 1e-9)):
                    st = substep(cfg, fb, FootRoles(engage, ft.sliding, drag, ft.absorbing), half,
                                 StepFrom(t_abs, m, ce_y))
                    return PieceStep(st, half, True, NO_SLIP, NO_SLIP, NO_SLIP, NO_SLIP, memo,
                                     False, True)
            if stop.any:
                pc = to_event(cfg, with_drag_dir(fb, stop.stop_dir),
                              FootRoles(engage, ft.sliding, drag, ft.absorbing), rem,
                              StepFrom(t_abs, m, ce_y), stop)
                if pc.found and pc.tau_s < rem:
                    stuck_now, slid_on = holds(cfg, body, t_abs + pc.tau_s, pc.step, ft, stop)
                    return PieceStep(pc.step, pc.tau_s, True, NO_SLIP, stuck_now, slid_on,
                                     NO_SLIP, memo, False, False)
                # it does not stop within the step after all: the step dragged along where it slid
                # (the trial's drag, turning round with a slip near zero inside the method's
                # stages, may have left the slip where it was)
                if _turned_any(stop, ce_y, ce_e):
                    st = pc.step
                    at_end = False
    if may_split and not at_end:
        # the contact at the piece's end, for the breakaway's check and the events (one site:
        # the breakaway's check is only asked where they are)
        body = with_feet(fb, engage, drag)
        m_e = Motion(st.p, st.v, st.q, st.w)
        ce_e = contact_memo(memo, False, body, t_e, m_e, ft.absorbing, engage)
        memo = memo_of(body, ce_e, t_e, m_e, ft.absorbing, engage)
        at_end = True
    held = (not drag[0] and ce_y.foot_force_n[0] > 0.0, not drag[1] and ce_y.foot_force_n[1] > 0.0,
            not drag[2] and ce_y.foot_force_n[2] > 0.0, not drag[3] and ce_y.foot_force_n[3] > 0.0)
    if (may_split and fb.craft.method == RK4 and per_foot(cfg)
            and cfg.friction_static > 0.0 and (held[0] or held[1] or held[2] or held[3])):
        # the holding feet break away where holding them would take more than their cones give:
        # located, and kinetic from there (MODEL-NOTES 46)
        body = with_feet(fb, engage, drag)
        held = (not drag[0], not drag[1], not drag[2], not drag[3])
        ground_e = ground_at(fb, t_e)
        m_e = Motion(st.p, st.v, st.q, st.w)
        ce_e = memo.ce  # (may_split: evaluated at st's end above)
        holding = Holding(held, cfg.friction_static)
        if held_friction(body, ground_e, ce_e, m_e, holding).use > 1.0:
            hf0 = held_friction(body, ground_at(fb, t_abs), ce_y, m, holding)
            if hf0.use < 1.0:
                brk = FootEvents(NO_SLIP, NO_SLIP, NO_SLIP, NO_HOLD, (0.0, 0.0, 0.0, 0.0),
                                 cfg.friction_static, True)
                pc = to_event(cfg, fb, FootRoles(engage, ft.sliding, drag, ft.absorbing), rem,
                              StepFrom(t_abs, m, ce_y), brk)
                if pc.found and pc.tau_s < rem:
                    return PieceStep(pc.step, pc.tau_s, True, NO_SLIP, NO_SLIP, NO_SLIP,
                                     pressing_held(body, t_abs + pc.tau_s, pc.step, ft, held),
                                     memo, False, False)
    if may_split:
        # the contact at the step's end is kept (memo): the guard asks for it again at the
        # sub-step's end where no foot's regime changed (guard_substep), as does the next piece
        body = with_feet(fb, engage, drag)
        ce_e = memo.ce  # (evaluated at st's end above)
        ev = foot_events(ce_y, ce_e, ft.absorbing, engage)
        if ev.any:
            pc = to_event(cfg, fb, FootRoles(engage, ft.sliding, drag, ft.absorbing), rem,
                          StepFrom(t_abs, m, ce_y), ev)
            if pc.found and pc.tau_s < rem:
                return PieceStep(pc.step, pc.tau_s, True, ev.onset, NO_SLIP, NO_SLIP, NO_SLIP,
                                 memo, False, False)
    # a refined piece ends before the sub-step does: the next piece starts there
    return PieceStep(st, rem, rem < whole, NO_SLIP, NO_SLIP, NO_SLIP, NO_SLIP, memo, at_end,
                     rem < whole)


#: a holding foot carrying this fraction of its static cone (mu_s N) or more is about to break
#: away (:func:`at_transition`)
NEAR_CONE = 0.9


#: the shortest piece next to a foot at its transition, as a fraction of sim.stiff_substep
TRANSITION_PIECE = 0.1


@kernel
def at_transition(cfg, fb, start, sr, h):
    """Some pressing foot is at its stick/slip transition at a piece's ``start`` (a
    :class:`PieceStart`): holding (not dragged, regime static) with NEAR_CONE of mu_s N_i or
    more carried over the last step, or sliding, not slowing (:func:`slowing`, from ``sr``), and
    slow enough that its own friction could stop it within TRANSITION_PIECE h
    (:func:`_could_stop`): it has just broken away. (Within h it would be every stiff foot that
    is not slowing: +14% pieces over envelope touchdowns.) Where a stiff foot takes its friction
    as an impulse after a piece of h, the impulses solved together would hold such a foot (its
    slip stays within what they take out of it), while its static cone alone would not
    (MODEL-NOTES 58)."""
    ft, ce, drag, q = start.ship.footing, start.ce, start.drag, start.ship.motion.q
    mu_s = cfg.friction_static
    for i in range(4):
        load = ce.foot_force_n[i] * ce.push_norm[i]
        if not load > 0.0:
            continue
        if not ft.sliding[i] and not drag[i]:
            if norm(ft.hold_w[i]) >= NEAR_CONE * mu_s * load:
                return True
        elif not slowing(sr, i) and _could_stop(cfg, fb, ce, ce, q, i, TRANSITION_PIECE * h):
            return True
    return False


@kernel
def _stop_time(cfg, fb, ce, q, i):
    """The time foot i's own kinetic friction alone would take to slow its slip (at ``ce``) to the
    stick speed, s: (|s| - stick) m_eff / (mu_k N) (:func:`_could_stop`'s terms at one end)."""
    s0 = ce.slip_w[i]
    speed = norm(s0)
    if not speed > cfg.stick_speed_mps:
        return 0.0
    drag = fb.craft.mu_k * ce.foot_force_n[i] * ce.push_norm[i]
    s_hat = unit(s0)
    inv_m = _inv_mass_along(fb, q, i, s_hat)
    return (speed - cfg.stick_speed_mps) / (drag * inv_m)


#: outside an impact, a sliding foot slower than this takes no pieces of its own (stiff_feet): it
#: slips under 25 um in a 25 ms sub-step, and its friction as an impulse after the step errs by
#: less; such micro-slips, held up by a ship's slow turn as it comes to rest, have stop times just
#: above stiff_substep and cut a sub-step into 20-40 pieces (MODEL-NOTES 61), m/s
MICRO_SLIP_MPS = 1e-3


@kernel
def stiff_feet(cfg, fb, start, sr, h, stiff, floor_s):
    """The shortest time to stop (:func:`_stop_time`) of the sliding feet that press at a piece's
    ``start`` (a :class:`PieceStart`) and would take their friction as an impulse after a step
    of h, or be dragged where rk4's stages would not follow their drag's turning
    (:func:`step_piece`): their own friction could stop them within h (:func:`_could_stop`), and
    they are not coming to a stop (:func:`slowing`, from ``sr``; a foot of ``stiff`` whatever it
    does); of those, the ones it would take ``floor_s`` or longer to and, where ``floor_s`` is
    not 0 (outside an impact), slipping at MICRO_SLIP_MPS or faster. Infinite where there is
    none."""
    drag, ce, q = start.drag, start.ce, start.ship.motion.q
    out = math.inf
    for i in range(4):
        # (the rates' test first: a foot coming to a stop asks no _could_stop)
        if (drag[i] and ce.foot_force_n[i] > 0.0 and (stiff[i] or not slowing(sr, i))
                and _could_stop(cfg, fb, ce, ce, q, i, h)):
            t_stop = _stop_time(cfg, fb, ce, q, i)
            micro = floor_s > 0.0 and norm(ce.slip_w[i]) < MICRO_SLIP_MPS
            if t_stop >= floor_s and not micro:
                out = fmin(out, t_stop)
    return out


@kernel
def pressing_held(fb, t_s, st, ft, held):
    """The feet of ``held`` that press at the end of ``st``."""
    ce = contact_at(fb, ground_at(fb, t_s), Motion(st.p, st.v, st.q, st.w), ft.absorbing,
                    ENGAGE_AT_GROUND)
    f = ce.foot_force_n
    return (held[0] and f[0] > 0.0, held[1] and f[1] > 0.0, held[2] and f[2] > 0.0,
            held[3] and f[3] > 0.0)


@kernel
def broken(st, broke):
    """``st`` with the feet of ``broke`` kinetic from its end (a located breakaway)."""
    sl = st.sliding
    return SubStep(st.p, st.v, st.q, st.w,
                   (sl[0] or broke[0], sl[1] or broke[1], sl[2] or broke[2], sl[3] or broke[3]),
                   st.friction_n, st.peak_penetration_m, st.located, st.pressed, st.hold_w)


@kernel
def stuck(st, stopped):
    """``st`` with the sliding feet of ``stopped`` holding from its end: their slip turned round
    there (a located stop), and static friction holds them while it can (MODEL-NOTES 46)."""
    sl = st.sliding
    return SubStep(st.p, st.v, st.q, st.w,
                   (sl[0] and not stopped[0], sl[1] and not stopped[1], sl[2] and not stopped[2],
                    sl[3] and not stopped[3]),
                   st.friction_n, st.peak_penetration_m, st.located, st.pressed, st.hold_w)


@kernel
def stepped(s, st):
    """``s`` moved by a (piece of a) sub-step ``st``: its motion, each foot's regime and the held
    feet's friction."""
    return with_footing(with_motion(s, s.surface_state, Motion(st.p, st.v, st.q, st.w)),
                        with_friction(s.footing, st.sliding, st.hold_w))


class Pieces(NamedTuple):
    """What the pieces of one sub-step did together."""

    touched: bool  # a foot pressed during any of them
    located: bool  # the method located every piece's deepest penetration
    peak_m: float  # the deepest penetration it located inside them
    friction_n: float  # the last piece's friction
    aligned: bool  # a touchdown inside the sub-step stood the ship up
    onset: tuple  # the feet the last located event touched (they meet the ground there)
    memo_here: bool  # the last piece's memo was evaluated at its end state (PieceStep.memo_here)


class SubStepEnd(NamedTuple):
    """A sub-step's end after the passivity guard."""

    ship: Ship
    ce: ContactEval  # the contact there (the dampers following any velocity the guard scaled)
    e_ref: EnergyRef
    removed_j: float  # what the guard took
    memo: Memo  # ce's


@kernel
def is_passive(fb):
    """No thrust and no RCS torque: nothing can add energy (:func:`passivity_guard`)."""
    return (fb.craft.thrust_n == 0.0 and fb.craft.rcs_torque_body_nm[0] == 0.0
            and fb.craft.rcs_torque_body_nm[1] == 0.0 and fb.craft.rcs_torque_body_nm[2] == 0.0)


@kernel
def guard_substep(cfg, fb, s, e_ref, pieces, start, memo):
    """The contact at a sub-step's end (``start.t_end_s`` into the tick; ``memo``'s if it was
    evaluated there; ``pieces.memo_here``: at the ship's motion itself, with ``fb``'s held
    friction), and the passivity guard there (``sim.energy_guard``)."""
    t_end = start.t_end_s
    m, ft = s.motion, s.footing
    ground = ground_at(fb, t_end)
    fb_now = with_feet(fb, ENGAGE_AT_GROUND, ft.sliding)
    if pieces.memo_here:  # (and with fb's held friction: the last piece's)
        hit = (memo.valid and memo.t_s == t_end and memo.absorbing == ft.absorbing
               and _same4(memo.engage, ENGAGE_AT_GROUND) and _same4(memo.kinetic, ft.sliding))
    else:
        hit = memo_at(memo, False, fb_now, t_end, m, ft.absorbing, ENGAGE_AT_GROUND)
    ce = memo.ce if hit else contact_inline(fb_now, ground, m, ft.absorbing, ENGAGE_AT_GROUND)
    if not cfg.energy_guard:
        return SubStepEnd(s, ce, e_ref, 0.0,
                          memo_of(fb_now, ce, t_end, m, ft.absorbing, ENGAGE_AT_GROUND))
    # airborne: clear of the ground at both ends and nothing pressed between (a bilateral
    # absorber's pull passes no positive impulse, yet trades translation for rotation)
    airborne = not pieces.touched and start.pen_m < 0.0 and ce.max_penetration_m < 0.0
    gd = passivity_guard(fb, ground, m, e_ref, is_passive(fb), airborne, ce.pen_m)
    s = with_motion(s, s.surface_state, Motion(m.p, gd.v, m.q, gd.w))
    if gd.removed_j > 0.0:  # the dampers' forces follow the velocities it scaled
        ce = contact_at(fb_now, ground, Motion(m.p, gd.v, m.q, gd.w), ft.absorbing,
                        ENGAGE_AT_GROUND)
    return SubStepEnd(s, ce, gd.ref, gd.removed_j,
                      memo_of(fb_now, ce, t_end, s.motion, ft.absorbing, ENGAGE_AT_GROUND))


@kernel
def substep_peak(fb, start, pieces, pen, v_rad, h):
    """The deepest penetration over a sub-step: located by the method, or interpolated between
    its ends (telemetry)."""
    if pieces.located:
        return fmax(fmax(start.pen_m, pen), pieces.peak_m)
    return hermite_peak(start.pen_m, -start.v_rad_mps, pen, -v_rad, h)


# -- 2c. transitions and their events at a sub-step's end ----------------------------------------
class Transitioned(NamedTuple):
    """A sub-step's end after the in-flight transitions."""

    ship: Ship
    ce: ContactEval
    e_ref: EnergyRef
    v_rad_mps: float  # velocity along local up before any touchdown's alignment
    stop: bool  # pinned for the rest of the tick (crashed, on the hull, the pivot model's)
    moved: bool  # a touchdown's alignment moved the ship (the end's memo is not at its motion)


@kernel
def in_flight_transitions(cfg, fb, ground, end, start, pieces, log):
    """The in-flight transitions, decided on a sub-step's end state: a touchdown the onsets did
    not locate (the method's last resort), a crash in contact, a liftoff (all feet clear and
    moving away), a tip past tipped_angle (or its crash); each emitted with the instant it
    happened inside the sub-step. ``end``: the sub-step's end after the guard (a SubStepEnd);
    ``start``: the sub-step (a SubStepStart); ``ground``: the ground at its end."""
    s, ce, e_ref = end.ship, end.ce, end.e_ref
    t_end, h = start.t_end_s, start.h_s
    om = fb.craft.body_omega_radps
    m, ft = s.motion, s.footing
    p, v, q, w = m.p, m.v, m.q, m.w
    surf = s.surface_state
    aligned = pieces.aligned
    r_hat = unit(p)
    v_rad = dot(v, r_hat)
    v_rad_before = start.v_rad_mps
    pen = ce.max_penetration_m
    was = surf
    cos_tilt = dot(quat_axis_z(q), r_hat)
    # a touchdown the onsets did not locate (the method's last resort): at the step's end
    touch = was == FLYING and pen > 0.0 and v_rad < 0.0
    a_down = _a_down(fb, p, q, r_hat)
    impact = -v_rad
    if touch and v_rad_before < 0.0:
        # the speed at the crossing, from the ballistic motion on the clear side of it
        above_before = fmax(-start.pen_m, 0.0)
        impact = math.sqrt(fmax(v_rad_before * v_rad_before + 2.0 * a_down * above_before, 0.0))
    # rising from the ground: along its normal, as the feet see it (on a slope a ship hopping
    # off its downhill feet can rise from the ground while it descends; MODEL-NOTES 50)
    rise = rise_rate(ground, p, v, r_hat)
    separation = math.sqrt(fmax(rise * rise + 2.0 * a_down * fmax(-pen, 0.0), 0.0))
    # in contact: descending faster than crash_speed at either end of the sub-step (the
    # damper may already have slowed it by the end)
    tipped = was == TIPPED  # the full model's tipped ship (MODEL-NOTES 48)
    crash_in_contact = ((was == CONTACT or tipped)
                        and fmin(v_rad, v_rad_before) < -cfg.crash_speed_mps)
    touch_ok = touch and not impact > cfg.crash_speed_mps
    if touch_ok:
        ft = fresh_footing(impact < cfg.bounce_speed_mps)
        if cfg.align_on_touchdown:
            # (the end's evaluation ``ce`` is at m's pose on this ground)
            al = align_at_touchdown(fb, ground, m, ce.pen_m)
            p, v, q, w = al.p, al.v, al.q, al.w
            aligned = al.aligned
            ce = contact_at(with_feet(fb, ENGAGE_AT_GROUND, ft.sliding), ground, Motion(p, v, q,
                            w), ft.absorbing, ENGAGE_AT_GROUND)
            if cfg.energy_guard and al.aligned:  # the snap never adds energy; from after it
                e_ref = energy_ref(ship_energy_at(fb, ground, Motion(p, v, q, w), ce.pen_m))
        cos_tilt = dot(quat_axis_z(q), r_hat)
    entered, then = CONTACT, CONTACT
    if touch:
        entered, then = touchdown_rules(cfg, om, p, v, q, impact, aligned)
    crash = then == CRASHED or crash_in_contact
    # all feet clear and moving away: a bounce or a thrust-off (the align of a touchdown can
    # lift a foot clear while the ship still descends; that is not a liftoff)
    lift = was == CONTACT and not crash and ce.max_penetration_m < 0.0 and rise > 0.0
    # past tipped_angle in contact (a touchdown lying down: touchdown_rules)
    tip = was == CONTACT and not lift and not crash and cos_tilt < cfg.cos_tipped
    v_rel = sub(v, surface_velocity(om, p))
    tip_crash = tip and dot(v_rel, v_rel) > cfg.crash_speed2
    crash = crash or tip_crash
    tip = (tip and not tip_crash) or then == TIPPED
    # a tipped ship turning back under tipped_angle is righted; one whose tilt reaches
    # tipped_rest lies on its hull: at rest there (an inelastic stop), or crashed if it hit it
    # faster than crash_speed
    righted = tipped and not crash and cos_tilt > cfg.cos_tipped and cos_tilt > start.cos_tilt
    hull = tipped and not crash and not righted and cos_tilt <= cfg.cos_tipped_rest
    hull_crash = hull and dot(v_rel, v_rel) > cfg.crash_speed2
    crash = crash or hull_crash
    if touch_ok:
        surf = CONTACT
    if lift:
        surf = FLYING
    if tip:
        surf = TIPPED
    if righted:
        surf = CONTACT
    if crash:
        surf = CRASHED
    # pinned for the rest of the tick: crashed, at rest on the hull, or handed to the pivot model
    stop = crash or (hull and not hull_crash) or (tip and cfg.tipped_model != FULL_TIPPED)
    s = with_footing(with_motion(s, surf, Motion(p, v, q, w)), ft)
    if stop:
        pin = pinned_at(fb, s, ce, t_end)
        if hull:  # at rest on the hull
            pin = Pin(pin.pos_bf_m, pin.quat_bf, pin.pivot_bf_m, 0.0)
        s = with_pin(s, pin)
    # when each happened inside the sub-step
    if touch:
        t_ev = t_end
    elif lift:
        t_ev = t_end - clear_instant(fb, ground, ce, Motion(p, v, q, w), h)
    elif crash_in_contact:
        t_ev = crossed_at(v_rad_before, v_rad, -cfg.crash_speed_mps, start.t_s, t_end)
    elif righted:
        t_ev = crossed_at(start.cos_tilt, cos_tilt, cfg.cos_tipped, start.t_s, t_end)
    elif hull_crash:
        t_ev = crossed_at(start.cos_tilt, cos_tilt, cfg.cos_tipped_rest, start.t_s, t_end)
    else:  # tipped (or its crash): the tilt passing tipped_angle
        t_ev = crossed_at(start.cos_tilt, cos_tilt, cfg.cos_tipped, start.t_s, t_end)
    if touch:
        emit_touchdown(log, entered, then, impact, t_end)
    elif surf != was:
        if was == FLYING:
            speed = -impact
        elif surf == FLYING:
            speed = separation
        else:
            speed = v_rad
        emit(log, was, surf, speed, t_ev)
    return Transitioned(s, ce, e_ref, v_rad, stop, touch_ok and cfg.align_on_touchdown)


# -- 2. free flight: the stages in order ----------------------------------------------------------
@kernel
def fly_clear(cfg, fb, s):
    """A ship clear of the ground for the whole tick (``fb.craft.touching`` False:
    sim.phases.near_ground found it out of the feet's reach): one step of the method over the tick
    under gravity, thrust and RCS torque, then the passivity guard; no foot can press, so no event,
    friction or transition can happen. The same operations, in the same order, as
    :func:`free_flight` took for such a ship before this path (the same bits: the golden logs'
    bounces fly 100 m and more up), without its pieces, contact evaluations and transitions;
    free_flight now only ever steps a ship near the ground."""
    m, ft = s.motion, s.footing
    dt = cfg.dt_s
    res = advance(fb.craft.method, fb, dt, m, no_contact(m.p), ft.absorbing, 0.0)
    v, w, removed = res.v, res.w, 0.0
    if cfg.energy_guard:
        far = -math.inf  # (clear of the ground: no foot in it)
        # (sim.energy.mechanical of a ship clear of the ground, inlined: the same bits)
        e_ref = energy_ref(ship_energy_at(fb, ground_at(fb, 0.0), m, (far, far, far, far)))
        gd = passivity_guard(fb, ground_at(fb, dt), Motion(res.p, res.v, res.q, res.w), e_ref,
                             is_passive(fb), True, (far, far, far, far))
        v, w, removed = gd.v, gd.w, gd.removed_j
    s = with_footing(with_motion(s, s.surface_state, Motion(res.p, v, res.q, w)),
                     with_friction(ft, ft.sliding, NO_HOLD))
    return Flight(s, Report(0.0, 0.0, 0.0, 0.0 + removed, math.nan),  # as free_flight sums it
                  NO_RUN)


#: Most pieces a purely vertical ship's tick is cut into (:func:`vertical_flight`): a flight to
#: the feet's onset, the touchdown's rules there, the rest of the tick; one more spare.
MAX_VERTICAL_PIECES = 4


#: m: how far past the ground the onset's instant puts the lowest foot (to_event's aim: half of
#: EVENT_TOL_M), so that the feet count as at the ground there (within ONSET_MARGIN_M)
ONSET_AIM_M = 0.5 * EVENT_TOL_M


@kernel
def vertical_onset(fb, ce, m, h):
    """:func:`vertical_onset_at` ONSET_AIM_M into the ground."""
    return vertical_onset_at(fb, ce, m, h, ONSET_AIM_M)


#: m: a flying vertical ship whose lowest foot the ballistic flow keeps this far above the ground
#: through the tick (and none of whose feet presses) flies it as a ship clear of it (fly_clear):
#: far beyond what the flow leaves out (gravity's change over the tick, |foot|'s curvature)
VERTICAL_CLEAR_M = 1e-3


@kernel
def vertical_onset_at(fb, ce, m, h, aim_m):
    """How long a purely vertical ship none of whose feet presses (``ce``) flies before its lowest
    foot reaches ``aim_m`` into the ground, within ``h`` (math.inf: not within it). Its gap
    z = -x + aim_m closes at the foot's rate u = x' and accelerates by a = gamma a_down
    (g - T / m along local up, gamma the foot's push along the spring axis): the root of
    u t + a t^2 / 2 = z, t = 2 z / (u + sqrt(u^2 + 2 a z)) (no cancellation: the form
    sim.flight.clear_instant takes). The flight is the exponential method's ballistic flow under
    the gravity of the step's start, whose position this is exactly; what is left (the gravity's
    change over the flight, ~1e-6 of a metre's fall, and the curvature of |foot| in the height,
    (a / R)^2) moves the foot by far less than ONSET_MARGIN_M."""
    best = 0
    for i in range(1, 4):
        if ce.pen_m[i] > ce.pen_m[best]:
            best = i
    x = ce.pen_m[best]
    u = ce.pen_rate_mps[best]
    a = ce.lowest_gamma * _a_down(fb, m.p, m.q, unit(m.p))
    z = aim_m - x
    if not z > 0.0:
        return 0.0
    disc = u * u + 2.0 * a * z
    if not disc >= 0.0:
        return math.inf
    denom = u + math.sqrt(disc)
    if not denom > 0.0:
        return math.inf
    t = 2.0 * z / denom
    return t if t < h else math.inf


@kernel
def _none_presses(ce, engage):
    pen = ce.pen_m
    return not (pen[0] > -engage[0] or pen[1] > -engage[1] or pen[2] > -engage[2]
                or pen[3] > -engage[3])


#: every foot kept from pressing (to_event's held_off for feet about to press)
NEVER4 = (NEVER, NEVER, NEVER, NEVER)


@constructor
def pressing_none(fb):
    """``fb`` as a ship known to be clear of the ground (``Craft.touching`` False: its contact
    evaluations are sim.contact.no_contact's), for a flight of :func:`vertical_flight` in which no
    foot can press at its end: the feet the ballistic flow keeps VERTICAL_CLEAR_M above the
    ground, or kept from pressing (NEVER4) up to the onset. There every foot's force is exactly
    0.0 (sim.contact.foot_force: a foot that does not engage), so the evaluation's sums of force
    and torque are +0.0 (each starts at 0.0 and adds signed zeros) and its feet's forces 0.0, as
    no_contact's: the method's step (its closing kick, the feet's impulses) and the energies
    (no foot in the ground at the flight's start, none pressing at its end: no spring stores
    anything) are the same bits without it."""
    cr = fb.craft
    return FreeBody(Craft(cr.mass_kg, cr.inertia_kgm2, cr.thrust_n, cr.rcs_torque_body_nm,
                          cr.leg_radius_m, cr.com_height_m, cr.k_npm, cr.c_nspm,
                          cr.c_absorb_nspm, cr.gm_m3ps2, cr.body_radius_m,
                          cr.body_omega_radps, cr.terrain, cr.radial, cr.cos0, cr.sin0, False,
                          cr.linear_model, cr.method, cr.mu_k), fb.grip)


@separate
def vertical_flight(here, fb, s, log):
    """A purely vertical ship near the ground (sim.phases.purely_vertical, with the exponential
    method's one step a tick) through its tick without :func:`free_flight`'s general machinery
    (``sim.vertical_path``, MODEL-NOTES 65). Its motion is along the local vertical: the pressing
    feet are one linear spring-damper whose exact flow the exponential method steps
    (sim.integrators.exponential, its release located inside the step, the ballistic arc after
    it), and no foot slips, so no friction acts (free_flight's Coulomb solve gives four sticking
    feet impulses of rounding's size). The tick is cut only where the feet reach the ground: that
    instant is the root of the ballistic flow's quadratic (:func:`vertical_onset`), not
    to_event's search by trial steps; the feet are kept from pressing up to it, as to_event keeps
    them. At each piece's start :func:`piece_start` applies the touchdown's rules as in
    free_flight; at the tick's end, the passivity guard (:func:`guard_substep`), the in-flight
    transitions (:func:`in_flight_transitions`: a liftoff and its instant, a crash in contact)
    and the settle samples, the same functions on the same records as free_flight's one
    sub-step. (The release is not a piece of its own: the settle thresholds are sampled at the
    tick's end, not at the release too.)"""
    cfg, sp, cos1, sin1 = here.cfg, here.sp, here.turn.cos1, here.turn.sin1
    dt = cfg.dt_s
    fb = with_hold(fb, NO_HOLD)
    m, ft0 = s.motion, s.footing
    ground0 = ground_at(fb, 0.0)
    engage = ENGAGE_AT_GROUND
    ce = contact_inline(with_feet(fb, engage, ft0.sliding), ground0, m, ft0.absorbing, engage)
    if (s.surface_state == FLYING and _none_presses(ce, engage)
            and vertical_onset_at(fb, ce, m, dt, -VERTICAL_CLEAR_M) == math.inf):
        # its feet stay clear of the ground through the tick: a flight clear of it (none looked
        # up: every foot starts more than VERTICAL_CLEAR_M above it and presses nowhere)
        return fly_clear(cfg, pressing_none(fb), s)
    memo = memo_of(with_feet(fb, engage, ft0.sliding), ce, 0.0, m, ft0.absorbing, engage)
    # (the feet's penetrations the evaluation has: sim.energy.mechanical's bits)
    e_ref = (energy_ref(ship_energy_at(fb, ground0, m, ce.pen_m)) if cfg.energy_guard
             else EnergyRef(0.0, 0.0, 0.0))
    r_hat = unit(m.p)
    start = SubStepStart(0.0, dt, dt, ce.max_penetration_m, dot(m.v, r_hat),
                         dot(quat_axis_z(m.q), r_hat))
    run = SettleRun(True, ft0.settle_margin,
                    -ft0.settle_for_s if ft0.settle_ticks > 0 else 0.0)
    sample = s.surface_state == CONTACT
    t_seen = 0.0  # the instant of the last sample
    t_in = 0.0
    touched = False
    aligned = False
    peak = -math.inf
    stop = False
    end_memo = no_memo(m)  # the last step's contact at its end (exponential_end)
    end_feet = FEET_UNKNOWN  # and its feet, where that end is the tick's
    for k in range(MAX_VERTICAL_PIECES):
        ps = PieceStart(s, t_in, engage, s.footing.sliding, ce, NO_HOLD, aligned, e_ref, False,
                        memo)
        ps = piece_start(cfg, fb, ps, NO_SLIP, True, log)
        s, engage, ce, e_ref = ps.ship, ps.engage, ps.ce, ps.e_ref
        aligned = aligned or ps.aligned
        if ps.stop:
            stop = True
            break
        rem = dt - t_in
        ft = s.footing
        tau = math.inf
        if k < MAX_VERTICAL_PIECES - 1 and _none_presses(ce, engage):
            tau = vertical_onset(fb, ce, s.motion, rem)
        if tau < rem and tau > 0.0:
            # the flight to the feet's onset, the feet kept from pressing up to it
            # (no foot presses at its end: pressing_none's evaluation there, not looked up)
            st = exponential(with_feet(pressing_none(fb), NEVER4, ft.sliding), tau, s.motion, ce,
                             ft.absorbing, t_in)
        else:
            tau = rem
            fb_step = with_feet(fb, engage, ft.sliding)
            # (its contact at the final motion is not asked of the closing kick: a third forces
            # phase there cost more instructions than the guard's own evaluation, callgrind,
            # session 15, docs/issue36/session15-bounce.txt)
            se = exponential_end(fb_step, rem, s.motion, ce, ft.absorbing, t_in)
            st = se.stepped
            # the guard's evaluation where it was made at its state, instant and feet' roles
            end_memo = memo_of(fb_step, se.ce, t_in + rem, se.motion, ft.absorbing, se.engage)
            end_feet = KnownFeet(t_in + rem == dt, se.feet)
        j = st.foot_impulse_ns
        touched = touched or j[0] != 0.0 or j[1] != 0.0 or j[2] != 0.0 or j[3] != 0.0
        peak = fmax(peak, st.peak_penetration_m)
        m = Motion(st.p, st.v, st.q, st.w)
        s = with_footing(with_motion(s, s.surface_state, m),
                         with_friction(ft, ft.sliding, NO_HOLD))
        t_in = t_in + tau
        if not t_in < dt:
            t_in = dt
            break
        # the next piece starts at the onset, with the feet's engage thresholds as they were
        engage = ENGAGE_AT_GROUND
        fb_y = with_feet(fb, engage, ft.sliding)
        ce = contact_inline(fb_y, ground_at(fb, t_in), m, ft.absorbing, engage)
        memo = memo_of(fb_y, ce, t_in, m, ft.absorbing, engage)
        if sample:  # the thresholds at the onset too, as free_flight samples them at its events
            run = settle_sample(cfg, sp, s, ground_at(fb, t_in), run, t_seen, t_in)
            t_seen = t_in
    peak_t = 0.0
    guard_j = 0.0
    ce_end = ce
    if not stop:
        pieces = Pieces(touched, True, peak, 0.0, aligned, NO_SLIP, False)
        end = guard_substep(cfg, fb, s, e_ref, pieces, start, end_memo)
        guard_j = end.removed_j
        m = end.ship.motion
        peak_t = fmax(0.0, substep_peak(fb, start, pieces, end.ce.max_penetration_m,
                                        dot(m.v, unit(m.p)), dt))
        ground = ground_at(fb, dt)
        tr = in_flight_transitions(cfg, fb, ground, end, start, pieces, log)
        s, ce_end = tr.ship, tr.ce
        if sample:
            # the feet at the step's end pose (closing_kick's geometry), where the ship is there
            known = KnownFeet(end_feet.known and _same3(s.motion.p, end_memo.motion.p)
                              and _same4(s.motion.q, end_memo.motion.q), end_feet.feet)
            run = settle_sample_on(cfg, sp, s, ground, run, (t_seen, dt), known)
        stop = tr.stop
    if stop:
        s, ce_end = pinned_at_end(fb, s, cos1, sin1, dt)
    s = unheld(s, stop)
    return Flight(s, Report(0.0, abs(ce_end.normal_n), peak_t, 0.0 + guard_j,
                            lowest_of(ce_end)),
                  run if sample and s.surface_state == CONTACT else NO_RUN)


#: m: what a flying ship's lowest foot keeps above the ground beyond twice the most its feet can
#: close on it over a sub-step, to take a whole max_substep in an impact's tick (clear_within)
CLEAR_MARGIN_M = 0.1


@kernel
def clear_within(cfg, fb, m, ce, h):
    """:func:`feet_clear` for a ship at the motion ``m`` whose contact there is ``ce``."""
    return feet_clear(cfg, fb.craft, m, ce.max_penetration_m, h)


@kernel
def feet_clear(cfg, cr, m, max_penetration_m, h):
    """Whether no foot of a ship (``cr``: its Craft) at the motion ``m``, its deepest foot's
    penetration ``max_penetration_m``, can reach the ground within h: its lowest foot's height
    above the ground, -max penetration, more than twice
    (1 + tan(slope)) (u h + a h^2) and CLEAR_MARGIN_M, with u = |v - Omega z x p| + (|w| + Omega) d
    the most a foot moves relative to the ground and a = GM / |p|^2 + Omega^2 |p| + 2 Omega |v_rel|
    + T / m + ((|tau| + I_max |w|^2) / I_min + |w|^2) d its most acceleration (gravity, the
    body's turning, thrust; Euler's equations' I dw/dt = tau - w x I w, and the centripetal
    term), d = sqrt(h_com^2 + a_leg^2) every foot's distance from the centre of mass. A foot's
    height above a plane slope changes by at most (1 + tan(slope)) times its displacement (the
    bumps' steepness is not bounded here: a caller asks only on a plane)."""
    om = abs(cr.body_omega_radps)
    d = math.sqrt(cr.com_height_m * cr.com_height_m + cr.leg_radius_m * cr.leg_radius_m)
    v_rel = sub(m.v, surface_velocity(cr.body_omega_radps, m.p))
    w2 = dot(m.w, m.w)
    w = math.sqrt(w2)
    i = cr.inertia_kgm2
    i_min = fmin(fmin(i[0], i[1]), i[2])
    i_max = fmax(fmax(i[0], i[1]), i[2])
    tau = norm(cr.rcs_torque_body_nm)
    u = norm(v_rel) + (w + om) * d
    r2 = dot(m.p, m.p)
    a = (cr.gm_m3ps2 / r2 + om * om * math.sqrt(r2) + 2.0 * om * norm(v_rel)
         + abs(cr.thrust_n) / cr.mass_kg + ((tau + i_max * w2) / i_min + w2) * d)
    return -max_penetration_m > (2.0 * (1.0 + cfg.slope_tan) * (u * h + a * h * h)
                                 + CLEAR_MARGIN_M)


#: a ship in contact takes a tick as one coarse sub-step (sim.coarse_substep, :func:`coarse_tick`)
#: only where its rocking mode's w h is under this: a squat ship (w = 13.9 rad/s) sliding on its
#: four feet down 39.3 degrees grows a pitching oscillation at w h = 0.69 (one 50 ms sub-step)
#: and stops sliding; at 0.56 (40 ms) and 0.49 (half the stiffness) it slides as at 25 ms
COARSE_WH = 0.5

#: m/s: the margin on each foot's rate along the ground's normal over a coarse sub-step: no foot
#: starts or stops pressing within it (a foot's acceleration, spring and damper, ~0.1 m/s in 50 ms)
COARSE_MARGIN_MPS = 0.2

#: a sliding foot allows a coarse sub-step if its slip outlasts this many of them at its own
#: kinetic friction's deceleration plus the surface gravity (it neither stops nor turns stiff
#: within it: sim.flight.step_piece's pieces and impulses ask for less than one)
COARSE_SLIP_STEPS = 4.0

#: the settle thresholds' margin (sim.rest.margin_on: each a fraction of its threshold) above
#: which a ship is near enough to rest for the landing instant's samples to want every sub-step
COARSE_SETTLE_MARGIN = -1.0

#: the settle thresholds' margin over which a ship whose thresholds have held for sim.coarse_held
#: takes the coarse sub-step (MODEL-NOTES 69: a ship just over them may dip under inside it)
COARSE_HELD_MARGIN = 0.25


@kernel
def coarse_tick(cfg, fb, s, ce, h):
    """Whether a ship in contact (``ce``: its contact at the tick's start) takes a sub-step of
    ``h`` (sim.coarse_substep) where it would take max_substep's (MODEL-NOTES 57): a pure
    function of the state, true only where nothing the finer sub-steps resolve can happen in it:

    - its rocking mode, w^2 = (k/2) a^2 / I_transverse, has w h under COARSE_WH;
    - it is not near rest: the settle thresholds' margin at the last tick's end is under
      COARSE_SETTLE_MARGIN (the landing instant is interpolated between sub-steps' ends), or
      at rest already: with ``cfg.coarse_held_s`` over 0 (sim.coarse_held), the thresholds have
      held for that long and hold by over COARSE_HELD_MARGIN of each (MODEL-NOTES 69);
    - no foot starts or stops pressing within it: a pressing foot's gap to its release (its
      penetration, or k x + c x' over k) and a clear foot's height above the ground are more than
      (|x'| + COARSE_MARGIN_MPS) h; with ``cfg.coarse_release`` a pressing foot whose force
      still pushes may be nearer its release where another pressing foot is that far from its
      own (the release is located inside the sub-step, as in the finer ones, and the ship stays
      carried: MODEL-NOTES 68);
    - every sliding foot that presses slips faster than COARSE_SLIP_STEPS h (mu_k N_i / m_eff,i +
      g): it cannot stop, nor its friction turn stiff, within the sub-step."""
    cr = fb.craft
    ft = s.footing
    i_t = fmin(cr.inertia_kgm2[0], cr.inertia_kgm2[1])
    w2 = 0.5 * cr.k_npm * cr.leg_radius_m * cr.leg_radius_m / i_t
    # (and the four feet's bounce, w^2 = k / m, well inside rk4's stability)
    if not (w2 * h * h < COARSE_WH * COARSE_WH and cr.k_npm / cr.mass_kg * h * h < 1.0):
        return False
    # (a ship whose thresholds have held for sim.coarse_held already: the instant they began to
    # hold is found, what its sub-steps' ends resolve is only a dip under them; MODEL-NOTES 69)
    held = (cfg.coarse_held_s > 0.0 and ft.settle_ticks > 0
            and ft.settle_for_s >= cfg.coarse_held_s and ft.settle_margin > COARSE_HELD_MARGIN)
    if not (ft.settle_margin < COARSE_SETTLE_MARGIN or held):
        return False
    absorbing = ft.absorbing
    c_over_k = (cr.c_absorb_nspm if absorbing else cr.c_nspm) / cr.k_npm
    g = cr.gm_m3ps2 / dot(s.motion.p, s.motion.p)
    releasing = False  # a pressing foot near its release (sim.coarse_release)
    carried = False  # a pressing foot far from its release
    for i in range(4):
        x = ce.pen_m[i]
        rate = ce.pen_rate_mps[i]
        reach = (abs(rate) + COARSE_MARGIN_MPS) * h
        if x > 0.0 and (absorbing or ce.foot_force_n[i] > 0.0):
            gap = x if absorbing else x + c_over_k * rate
            if gap > reach:
                carried = True
            elif cfg.coarse_release and ce.foot_force_n[i] > 0.0:
                # a foot that still pushes: its release is located inside the sub-step, as in
                # the finer ones, where another foot carries the ship through it (MODEL-NOTES 68)
                releasing = True
            else:
                return False
            if ft.sliding[i]:
                s0 = ce.slip_w[i]
                speed = norm(s0)
                if not speed > 0.0:
                    return False
                s_hat = unit(s0)
                own = (cr.mu_k * ce.foot_force_n[i] * ce.push_norm[i]
                       * _inv_mass_along(fb, s.motion.q, i, s_hat))
                if not speed > COARSE_SLIP_STEPS * h * (own + g):
                    return False
        elif not -x > reach:
            return False
    return carried or not releasing


@kernel
def lowest_of(ce):
    """The deepest foot's penetration from an evaluation ``ce`` at the ship's state at its tick's
    end (sim.contact.lowest_foot_penetration of the same feet: the same bits; its feet are
    evaluate's, sim.contact.feet's numbers), NaN for a ship whose feet were not looked for."""
    pen = ce.pen_m
    if not ce.touching:
        return math.nan
    return fmax(fmax(fmax(pen[0], pen[1]), pen[2]), pen[3])


@kernel
def pinned_at_end(fb, s, cos1, sin1, dt):
    """A ship pinned during the tick (crashed, tipped to the pivot model, or at rest on its hull):
    carried with the body to the tick's end (the body's angles ``cos1``, ``sin1`` there), moving
    as pinned; its state and its contact evaluated there."""
    surf = s.surface_state
    ft = s.footing
    pin = s.pin
    p = rotate_z(pin.pos_bf_m, cos1, sin1)
    q = quat_mul(quat_z(cos1, sin1), pin.quat_bf)
    v, w = pinned_motion(fb.craft.body_omega_radps, p, q, rotate_z(pin.pivot_bf_m, cos1, sin1),
                         pin.rate_radps if surf == TIPPED else 0.0)
    s = with_motion(s, surf, Motion(p, v, q, w))
    ce = contact_at(with_feet(fb, ENGAGE_AT_GROUND, ft.sliding), ground_at(fb, dt),
                    Motion(p, v, q, w), ft.absorbing, ENGAGE_AT_GROUND)
    return s, ce


@kernel
def unheld(s, pinned_now):
    """The ship at its tick's end with no foot's static friction carried where no foot holds:
    not in contact, unless tipped and moving by the full model (``pinned_now``: pinned within
    the tick)."""
    surf = s.surface_state
    ft = s.footing
    if surf != CONTACT and not (surf == TIPPED and not pinned_now):
        return with_footing(s, with_friction(ft, ft.sliding, NO_HOLD))
    return s


# (inlined into its one caller, sim.phases.step_ship, itself inlined into the loop over ticks:
# no call passing the scene, the FreeBody and the Ship by value and the Flight back through
# memory; session15-glue)
@kernel
def free_flight(here, fb, s, n_sub, carry, coarse, log):
    """Advance a free ship near the ground (``fb.craft.touching``; one clear of it takes
    :func:`fly_clear`) by one tick in ``n_sub`` equal sub-steps, each in three stages:

    a. the touchdown instant (:func:`piece_start`): where the first foot reaches the ground, the
       seed's touchdown rules apply there;
    b. integrating (:func:`step_piece`, then :func:`guard_substep`): every foot that starts or
       stops pressing inside the sub-step is located and stepped to, the sub-step going on from
       there in pieces (a. again at each); the passivity guard at its end;
    c. the transitions and their events (:func:`in_flight_transitions`), on the sub-step's end
       state.

    Transitions are emitted in the order they happen, each with the instant it happened. ``carry``:
    the holding feet's friction is carried from step to step as a force (sim.friction.coulomb);
    without it, impulses alone. In an impact's tick (``n_sub`` impact sub-steps), a flying ship
    whose feet cannot reach the ground within a sub-step of max_substep (:func:`clear_within`)
    takes that many of the impact's sub-steps as one (``sim.coarse_when_clear``): nothing
    presses in it, and its flight is what a ship near the ground takes at max_substep.
    ``coarse``: a ship in contact that :func:`coarse_tick` finds quiet at the tick's start takes
    the scene's ``coarse_substeps`` instead of ``n_sub`` (sim.coarse_substep)."""
    cfg, sp, cos1, sin1 = here.cfg, here.sp, here.turn.cos1, here.turn.sin1
    dt = cfg.dt_s
    m = s.motion
    friction_n = 0.0
    peak = 0.0
    guard_j = 0.0
    ground0 = ground_at(fb, 0.0)
    # evaluated with the held feet's friction the first piece carries in (none where it is
    # not carried: impulses alone, or inside the step), so that the first piece's start finds
    # it (contact_memo) instead of evaluating the same state again; the fields used before
    # that (penetrations, their rates, the feet's forces and slips) do not depend on it
    fb0 = with_hold(fb, s.footing.hold_w if carry else NO_HOLD)
    ce = contact_inline(fb0, ground0, m, s.footing.absorbing, ENGAGE_AT_GROUND)
    # a ship in contact where nothing the finer sub-steps resolve can happen takes the coarse
    # ones (sim.coarse_substep, MODEL-NOTES 57)
    if coarse and coarse_tick(cfg, fb, s, ce, dt / cfg.coarse_substeps):
        n_sub = cfg.coarse_substeps
    h = dt / n_sub
    memo = memo_of(fb0, ce, 0.0, m, s.footing.absorbing, ENGAGE_AT_GROUND)
    memo_here = True  # memo was evaluated at s.motion itself (nothing has moved the ship since)
    v_rad = dot(m.v, unit(m.p))
    # (the feet's penetrations the evaluation at m has: sim.energy.mechanical's bits)
    e_ref = (energy_ref(ship_energy_at(fb, ground0, m, ce.pen_m)) if cfg.energy_guard
             else EnergyRef(0.0, 0.0, 0.0))
    carried = fb.grip.hold_w  # the friction the FreeBody carries (with_hold)
    ft0 = s.footing
    # the settle thresholds at the tick's start: held for settle_for_s already, or not
    run = SettleRun(True, ft0.settle_margin,
                    -ft0.settle_for_s if ft0.settle_ticks > 0 else 0.0)
    sample = s.surface_state == CONTACT
    t_seen = 0.0  # the instant of the last sample
    pinned_now = False  # crashed, tipped to the pivot model, or at rest on the hull: pinned
    # the stiff feet's pieces (sim.stiff_substep), in every sub-step; outside an impact not for
    # the feet their friction would stop within the shortest piece (a rocking ship's micro-slips)
    impact = cfg.impact_substeps > 0 and n_sub >= cfg.impact_substeps
    fine = Fine(cfg.stiff_substep_s, 0.0 if impact else cfg.stiff_substep_s)
    # a flying ship clear of the ground for a max_substep takes it whole (sim.coarse_when_clear):
    # r_clear of the impact's sub-steps; on a plane (clear_within bounds no bump's steepness)
    r_clear = 1
    if impact and cfg.coarse_when_clear and sp.n_substeps > 0 and here.terrain.n_bumps == 0:
        r_clear = n_sub // sp.n_substeps
    u = 0  # the impact's sub-steps done
    for _j in range(n_sub):
        if u >= n_sub:
            break
        m = s.motion
        k_sub = 1
        if (r_clear > 1 and u + r_clear <= n_sub and s.surface_state == FLYING
                and clear_within(cfg, fb, m, ce, r_clear * h)):
            k_sub = r_clear
        h_j = k_sub * h
        start = SubStepStart(u * h, (u + k_sub) * h, h_j, ce.max_penetration_m, v_rad,
                             dot(quat_axis_z(m.q), unit(m.p)))
        u += k_sub
        engage = ENGAGE_AT_GROUND
        t_in = 0.0  # how far into the sub-step the ship has been stepped
        pieces = Pieces(False, True, -math.inf, friction_n, False, NO_SLIP, False)
        stop = False
        stiff = NO_SLIP  # the feet whose stops are not located for the rest of the sub-step
        events = 0  # the pieces cut at an event
        refined = 0  # the pieces cut short where Coulomb's law is stiff (sim.stiff_substep)
        for k in range(MAX_PIECES + MAX_REFINED + 1):
            t_abs = start.t_s + t_in
            carried = s.footing.hold_w if carry else NO_HOLD
            fb_k = with_hold(fb, carried)
            ps = PieceStart(s, t_abs, engage, s.footing.sliding, ce, carried, pieces.aligned, e_ref,
                            False, memo)
            ps = piece_start(cfg, fb_k, ps, pieces.onset, memo_here, log)
            s, engage, carried, e_ref = ps.ship, ps.engage, ps.carried, ps.e_ref
            pieces = Pieces(pieces.touched, pieces.located, pieces.peak_m,
                            pieces.friction_n, pieces.aligned or ps.aligned, pieces.onset,
                            pieces.memo_here)
            if ps.stop:
                stop = True
                pinned_now = True
                break
            fb_k = with_hold(fb, carried)
            pc = step_piece(cfg, fb_k, ps, h_j - t_in, events < MAX_PIECES, stiff,
                            fine if refined < MAX_REFINED else NOT_FINE)
            memo = pc.memo
            memo_here = pc.memo_here  # (stepped keeps st's motion, bit for bit)
            st = pc.step
            # (a foot that broke away here slips from zero: its stop is not looked for again
            # in this sub-step, where it would be found at once)
            stiff = (stiff[0] or pc.slid_on[0] or pc.broke[0],
                     stiff[1] or pc.slid_on[1] or pc.broke[1],
                     stiff[2] or pc.slid_on[2] or pc.broke[2],
                     stiff[3] or pc.slid_on[3] or pc.broke[3])
            s = stepped(s, broken(stuck(st, pc.stopped), pc.broke))
            pieces = Pieces(pieces.touched or st.pressed, pieces.located and st.located,
                            fmax(pieces.peak_m, st.peak_penetration_m), st.friction_n,
                            pieces.aligned, pc.onset, pc.memo_here)
            if not pc.split:
                break
            if pc.refined:
                refined += 1
            else:
                events += 1
            t_in = t_in + pc.tau_s  # from the event, with the feet that press there
            if sample:  # the thresholds at the event too (a stop changes them at once)
                run = settle_sample(cfg, sp, s, ground_at(fb_k, start.t_s + t_in), run, t_seen,
                                    start.t_s + t_in)
                t_seen = start.t_s + t_in
        friction_n = pieces.friction_n
        if stop:
            break
        fb_k = with_hold(fb, carried)
        t_end = start.t_end_s
        ground = ground_at(fb_k, t_end)
        end = guard_substep(cfg, fb_k, s, e_ref, pieces, start, memo)
        guard_j = guard_j + end.removed_j
        m = end.ship.motion
        peak = fmax(peak, substep_peak(fb, start, pieces, end.ce.max_penetration_m,
                                       dot(m.v, unit(m.p)), h_j))
        tr = in_flight_transitions(cfg, fb_k, ground, end, start, pieces, log)
        s, ce, e_ref, v_rad = tr.ship, tr.ce, tr.e_ref, tr.v_rad_mps
        # the end's contact serves the next sub-step's start where it asks for the same
        memo = end.memo
        memo_here = not tr.moved
        if sample:
            # (ce: the contact at s's state on this ground, the guard's or the transitions')
            run = settle_sample_seen(cfg, sp, s, ground, run, (t_seen, t_end), ce)
            t_seen = t_end
        if tr.stop:
            pinned_now = True
            break
    fb_k = with_hold(fb, carried)
    if pinned_now:
        s, ce = pinned_at_end(fb_k, s, cos1, sin1, dt)
    s = unheld(s, pinned_now)
    return Flight(s, Report(friction_n, abs(ce.normal_n), peak, guard_j, lowest_of(ce)),
                  run if sample and s.surface_state == CONTACT else NO_RUN)
