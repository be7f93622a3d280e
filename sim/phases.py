"""One ship's tick (:func:`step_ship`: its record loaded into a :class:`sim.ship.Ship`, stored
back in place): a chain of phases, in order, each a function below or a module of its own:

1. ``commands``     throttle and RCS torque actually applied (fuel, hold-mode controller)
2. ``free_flight``  flying and contact ships, sub-step by sub-step (sim.flight): the touchdown
                    instant, integrating with friction at the feet and the passivity guard, the
                    in-flight transitions (contact, crash, liftoff, tipped) and their events; a
                    ship near the ground takes its own ``n_substeps`` sub-steps, a purely vertical
                    one a single exact step, and a ship far above one step with no contact work
3. ``settle``       contact -> landed once the settle thresholds (sim.rest) have held for
                    ``settle_time`` with the centre of mass over the footprint
4. ``pinned``       landed, tipped and crashed ships turn with the body; tipped ships' pivot
                    model (sim.pivot) and righting. (A landed or tipped ship whose engine beats
                    its weight lifts off at the tick's start, ``lift_off``, and flies the tick.)
5. ``burn``         fuel and mass
6. ``observe``      the tick's telemetry

Decisions compare cosines and squared speeds, never angles.
"""
from __future__ import annotations

import math

from touchdown.sim.compiled import constructor, kernel
from touchdown.sim.constants import G0_MPS2
from touchdown.sim.contact import feet, foot_velocity, lowest_foot_penetration
from touchdown.sim.dynamics import Craft, FreeBody, Grip, Motion, ground_at
from touchdown.sim.flight import (crossed_at, feet_clear, fly_clear, free_flight,
    vertical_flight)
from touchdown.sim.frames import (body_spin_in_body_frame, effective_gravity, inertia, pin_pose,
    quat_z, rotate_z, surface_velocity)
from touchdown.sim.friction import per_foot
from touchdown.sim.integrators import EXPONENTIAL, HYBRID, RK4, sub_method
from touchdown.sim.pivot import pinned_motion, pivot_step
from touchdown.sim.rest import rest_pose, settle_margin
from touchdown.sim.ship import (CONTACT, CRASHED, Commands, ENGAGE_AT_GROUND, FLYING, FULL_TIPPED,
    HOLD_OFF, HOLD_RADIAL, LANDED, NO_HOLD, NO_REPORT, Pin, RADIAL_NORMAL, REST_LANDED, Report,
    TIPPED, emit, fresh_footing, load, scene_ground, store, with_footing, with_friction, with_mass,
    with_motion, with_pin, with_settle, with_state)
from touchdown.sim.vec import (cross, dot, fmax, fmin, mul, norm, quat_axis_z, quat_mul,
    quat_rotate, quat_rotate_inv, scale, sub, unit)


#: Squared tilt (rad^2), spin ((rad/s)^2) and slip ((m/s)^2) below which a ship counts as purely
#: vertical. Feet a planet's radius from its centre are placed to ulp(|p|) (2e-10 m on the Moon, 1e-9 m
#: on Earth), which leaves an upright bounce turning at ~1e-10 rad/s: 1e-8 is rounding's level, and
#: what a tilt, spin or slip that small would do over a tick is far below the 1e-7 to which one
#: exact step and sub-steps of the full model agree (tests/test_models.py).
VERTICAL_TOL2 = 1e-16


@kernel
def commands(here, s, inp):
    """Applied throttle and RCS torque. The hold-mode controller (flying and contact) is a PD law,
    tau = -I (w_c^2 err + 2 w_c omega_rel), saturated at max_rcs_torque; a non-zero manual RCS
    command on an axis overrides it there. No fuel, or a crashed ship: nothing fires."""
    cfg, sp = here.cfg, here.sp
    live = s.fuel_kg > 0.0 and s.surface_state != CRASHED
    if not live:
        return Commands(0.0, 0.0 * sp.max_thrust_n, (0.0, 0.0, 0.0), False)
    throttle = fmin(fmax(inp.throttle, 0.0), 1.0)
    max_tau = sp.max_rcs_torque_nm
    auto = (0.0, 0.0, 0.0)
    hold = int(inp.hold)
    if hold != HOLD_OFF and (s.surface_state == FLYING or s.surface_state == CONTACT):
        bw = cfg.bandwidth_radps
        omega_rel = sub(s.motion.w, body_spin_in_body_frame(cfg.omega_radps, s.motion.q))
        up_b = quat_rotate_inv(s.motion.q, unit(s.motion.p))
        err = cross((0.0, 0.0, 1.0), up_b) if hold == HOLD_RADIAL else (0.0, 0.0, 0.0)
        i_ctl = inertia((sp.inertia0_kgm2[0], sp.inertia0_kgm2[1], sp.inertia0_kgm2[2]),
                        sp.mass0_kg, s.mass_kg)
        bw2, two_bw = bw * bw, 2.0 * bw
        tau = mul(i_ctl, (bw2 * err[0] - two_bw * omega_rel[0], bw2 * err[1] - two_bw * omega_rel[1],
                          bw2 * err[2] - two_bw * omega_rel[2]))
        auto = (fmin(fmax(tau[0], -max_tau), max_tau), fmin(fmax(tau[1], -max_tau), max_tau),
                fmin(fmax(tau[2], -max_tau), max_tau))
    rcs = (0.0, 0.0, 0.0)
    m0 = fmin(fmax(inp.rcs[0], -1.0), 1.0) * max_tau
    m1 = fmin(fmax(inp.rcs[1], -1.0), 1.0) * max_tau
    m2 = fmin(fmax(inp.rcs[2], -1.0), 1.0) * max_tau
    rcs = (m0 if m0 != 0.0 else auto[0], m1 if m1 != 0.0 else auto[1],
           m2 if m2 != 0.0 else auto[2])
    thrust = throttle * sp.max_thrust_n
    return Commands(throttle, thrust, rcs, thrust > 0.0 or m0 != 0.0 or m1 != 0.0 or m2 != 0.0)


# -- 2. free flight ------------------------------------------------------------------------------
@kernel
def near_ground(here, s, cmd):
    """True for a ship that might touch the ground within this tick (conservative bound): its
    centre of mass less than ``reach`` (twice the tick's motion under its speed and the largest
    acceleration, and a metre) above the highest ground plus the feet's reach below it (their
    distance from it, sqrt(h^2 + a^2), at any attitude: ``sim.tight_reach``). On a slope the
    ground's plane is taken under the ship, rising by tan(slope) over every metre the feet and the
    tick's motion can reach sideways."""
    cfg, terrain, sp, cos0, sin0 = here.cfg, here.terrain, here.sp, here.turn.cos0, here.turn.sin0
    dt = cfg.dt_s
    # how far below the centre of mass a foot can be: its distance from it, |(+-a, 0, -h)| =
    # sqrt(h^2 + a^2) at any attitude (sim.contact.foot_offsets_w), however the ship turns within
    # the tick; the sum h + a bounds it too, loosely (0.8's; sim.tight_reach false)
    com_h, leg_a = sp.com_height_m, sp.leg_radius_m
    reach_down = math.sqrt(com_h * com_h + leg_a * leg_a) if cfg.tight_reach else com_h + leg_a
    speed = norm(s.motion.v)
    accel = cfg.surface_gravity_mps2 + cmd.thrust_n / s.mass_kg
    reach = 2.0 * (speed * dt + accel * dt * dt) + 1.0
    plane = 0.0
    if cfg.slope_tan != 0.0:
        east = -sin0 * s.motion.p[0] + cos0 * s.motion.p[1]
        plane = (terrain.slope_east * east + terrain.slope_north * s.motion.p[2]
                 + cfg.slope_tan * (reach_down + reach))
    clearance = norm(s.motion.p) - cfg.body_radius_m - cfg.terrain_max_m - plane - reach_down
    return clearance < reach


@kernel
def clear_tick(here, s, cmd):
    """:func:`clear_tick_of` the ship as :func:`free_body` builds it (for a caller without it)."""
    return clear_tick_of(here, s, free_body(here, s, cmd, False, here.cfg.method))


@kernel
def clear_tick_of(here, s, fb):
    """A flying ship that near_ground keeps near the ground but whose feet cannot reach it within
    the tick (sim.flight.feet_clear over dt from its lowest foot's height: a bound on every
    foot's speed and acceleration relative to the ground, however the ship turns; on a plane
    slope, as feet_clear bounds no bump's steepness): it flies the tick in one step, as a ship
    far above does (``sim.clear_tick``; MODEL-NOTES 63). near_ground's test is the centre of
    mass's, with a metre's margin; this one is the feet's own. ``fb``: the ship this tick
    (:func:`free_body`; its craft's constants, and its ground at the tick's start)."""
    cfg, sp = here.cfg, here.sp
    if not cfg.clear_tick or here.terrain.n_bumps != 0 or s.surface_state != FLYING:
        return False
    ground = ground_at(fb, 0.0)
    pen = lowest_foot_penetration(ground, s.motion.p, s.motion.q, sp.leg_radius_m,
                                  sp.com_height_m)
    return feet_clear(cfg, fb.craft, s.motion, pen, cfg.dt_s)


@kernel
def purely_vertical(here, s, cmd):
    """A ship whose motion this tick is along the local vertical only: upright, not turning, not
    slipping, no RCS torque, level ground under the whole footprint, a body that does not spin.
    For it every kick of the exponential method is zero, so its one step per tick is already
    exact and sub-steps would only repeat it (``sim.vertical_one_step``)."""
    cfg, terrain, sp = here.cfg, here.terrain, here.sp
    if cfg.omega_radps != 0.0 or cfg.slope_tan != 0.0:
        return False
    r_hat = unit(s.motion.p)
    tilt = cross(quat_axis_z(s.motion.q), r_hat)
    v_rad = dot(s.motion.v, r_hat)
    slip = sub(s.motion.v, scale(r_hat, v_rad))
    rcs = cmd.rcs_torque_body_nm
    if not (dot(tilt, tilt) < VERTICAL_TOL2 and dot(s.motion.w, s.motion.w) < VERTICAL_TOL2
            and dot(slip, slip) < VERTICAL_TOL2 and rcs[0] == 0.0 and rcs[1] == 0.0
            and rcs[2] == 0.0):
        return False
    # the terrain's coordinates of a point are its body-fixed (y, z): (east, north) at the site
    for j in range(terrain.n_bumps):
        de = s.motion.p[1] - terrain.bumps[j, 0]
        dn = s.motion.p[2] - terrain.bumps[j, 1]
        clear = terrain.bumps[j, 2] + sp.leg_radius_m + 1.0
        if not de * de + dn * dn > clear * clear:
            return False
    return True


#: A ship moving along local up faster than this near the ground strikes it, or rebounds from it
#: (sim.impact_substep), m/s; so does one with a foot that meets the ground, or leaves it, faster
#: than this along the ground's normal, and one pressed deeper than IMPACT_SAGS times its static sag.
IMPACT_SPEED_MPS = 1.0


IMPACT_SAGS = 10.0


@kernel
def striking(here, s):
    """A ship near the ground that strikes it, or rebounds, within the tick (MODEL-NOTES 53):

    - in contact, its centre of mass moving along local up faster than IMPACT_SPEED_MPS at the
      tick's start (a ship turning over a foot, whose end the impact's sub-steps resolve); a
      flying ship's feet alone say whether it meets the ground within the tick (MODEL-NOTES 60;
      ``sim.flying_strike_by_centre``: its centre too, 0.8's);
    - or one of its feet (velocity u_i = v + w x r_i over the ground, penetration x_i, the ground's
      push g_i = -grad x_i, so that x_i' = -g_i . u_i) moving along the ground's normal faster than
      IMPACT_SPEED_MPS, |g_i . u_i| > IMPACT_SPEED_MPS |g_i|, and either in the ground (x_i > 0:
      striking or rebounding) or approaching it (x_i' > 0) with a gap -x_i the tick covers at its
      present rate and IMPACT_SPEED_MPS more, -x_i < (x_i' + IMPACT_SPEED_MPS) dt (the margin: a
      foot swinging down while the ship rocks may speed up within the tick). A rocking ship's
      later feet strike while its centre of mass moves slowly: foot 1 and 2 of a 2.2 m/s touchdown
      onto 14 degrees, 0.75 s after its first, at 1.6-1.7 m/s, under 48-64 kN within 25 ms;
    - or its deepest foot pressed deeper than IMPACT_SAGS times its static sag g / w^2 (a ship at
      rest, even on a slope that loads its downhill feet more, is far from any of these)."""
    cfg, terrain, sp, cos0, sin0 = here.cfg, here.terrain, here.sp, here.turn.cos0, here.turn.sin0
    m = s.motion
    r_hat = unit(m.p)
    v_rad = dot(sub(m.v, surface_velocity(cfg.omega_radps, m.p)), r_hat)
    centre = s.surface_state != FLYING or cfg.flying_strike_by_centre
    if centre and abs(v_rad) > IMPACT_SPEED_MPS:
        return True
    ground = scene_ground(cfg, terrain, cos0, sin0)
    ft = feet(ground, m.p, m.q, sp.leg_radius_m, sp.com_height_m)
    omega_w = quat_rotate(m.q, m.w)
    fast2 = IMPACT_SPEED_MPS * IMPACT_SPEED_MPS
    dt = cfg.dt_s
    pen = -math.inf
    for i in range(4):
        x = ft.pen_m[i]
        pen = fmax(pen, x)
        g = ft.push_w[i]
        rate = -dot(g, foot_velocity(ground, m.v, omega_w, ft.offset_w[i], ft.pos_w[i]))  # x_i'
        if rate * rate > fast2 * dot(g, g) and (x > 0.0 or (rate > 0.0 and -x < (
                rate + IMPACT_SPEED_MPS) * dt)):
            return True
    return pen > IMPACT_SAGS * cfg.surface_gravity_mps2 / sp.stiffness_per_kg


@constructor
def free_body(here, s, cmd, touching, method):
    """The ship as the free flight moves it this tick (sim.dynamics.FreeBody): its mass and
    inertia, thrust and torque, legs and springs, the body and the ground under it at the tick's
    start, its friction."""
    cfg, terrain, sp, cos0, sin0 = here.cfg, here.terrain, here.sp, here.turn.cos0, here.turn.sin0
    m = s.mass_kg
    two_omega_m = 2.0 * sp.contact_omega_radps * m  # c = 2 zeta sqrt(k m) = 2 zeta omega m
    craft = Craft(m, inertia((sp.inertia0_kgm2[0], sp.inertia0_kgm2[1], sp.inertia0_kgm2[2]),
                             sp.mass0_kg, m),
                  cmd.thrust_n, cmd.rcs_torque_body_nm, sp.leg_radius_m, sp.com_height_m,
                  sp.stiffness_per_kg * m, cfg.damping_ratio * two_omega_m,
                  cfg.absorb_damping_ratio * two_omega_m, cfg.gm_m3ps2,
                  cfg.body_radius_m, cfg.omega_radps, terrain,
                  cfg.surface_normal == RADIAL_NORMAL, cos0, sin0, touching,
                  method == EXPONENTIAL, method,
                  cfg.friction_kinetic if per_foot(cfg) else 0.0)
    return FreeBody(craft, Grip(ENGAGE_AT_GROUND, s.footing.sliding, s.footing.hold_w, NO_HOLD))


@constructor
def stepped_by(fb, touching, method):
    """``fb`` (:func:`free_body`) as the tick steps it: near the ground (``touching``: its
    contact looked up) or known clear of it, by ``method`` (sim.integrators.sub_method's), which
    fits the pressing feet's linear model where it is the exponential one. The craft is built
    once a tick; what the tick's path decides (sim.phases.near_ground, :func:`clear_tick_of`,
    :func:`purely_vertical`) sets these three of its fields."""
    cr = fb.craft
    return FreeBody(Craft(cr.mass_kg, cr.inertia_kgm2, cr.thrust_n, cr.rcs_torque_body_nm,
                          cr.leg_radius_m, cr.com_height_m, cr.k_npm, cr.c_nspm,
                          cr.c_absorb_nspm, cr.gm_m3ps2, cr.body_radius_m,
                          cr.body_omega_radps, cr.terrain, cr.radial, cr.cos0, cr.sin0, touching,
                          method == EXPONENTIAL, method, cr.mu_k), fb.grip)


@kernel
def unturned(cfg, cos1, sin1):
    """A body that does not turn, at its tick's end angle (``cos1``, ``sin1``) of zero: the ground
    there (sim.ship.scene_ground) is the free flight's (sim.dynamics.ground_at), field for field,
    so what the flight evaluated on its ground at the tick's end holds for the phases after it."""
    return (cfg.omega_radps == 0.0 and cos1 == 1.0 and sin1 == 0.0
            and math.copysign(1.0, sin1) > 0.0)


@kernel
def settle(here, s, cmd, run, log):
    """Contact -> landed once tilt, angular and linear speeds have stayed under their thresholds
    for ``settle_time`` (SEED-NOTES 3: the bottom of a bounce, where v_radial = 0, never lands),
    with the centre of mass over the footprint (the seed's "ship stable"; MODEL-NOTES 26). The
    instant the thresholds began to hold is interpolated between the samples around it (linearly
    in their smallest margin, :func:`margin_on`), so the ship lands, at a tick's end, once they
    have held for settle_time in continuous time, and the event carries the instant they had
    (MODEL-NOTES 20). ``run`` (a :class:`SettleRun`): the samples at every sub-step's end of the
    tick (MODEL-NOTES 47), where there were; otherwise the tick's ends alone."""
    cfg, cos1, sin1 = here.cfg, here.turn.cos1, here.turn.sin1
    # a sampled run's last sample is margin_on of this very state at the tick's end (the free
    # flight samples its last sub-step's end after its transitions, and hands the run on only
    # where the ship is in contact there, unpinned); on a body that does not turn the ground it
    # sampled on (sim.dynamics.ground_at) is the one settle_margin builds, field for field
    margin = (run.margin if run.sampled and unturned(cfg, cos1, sin1)
              else settle_margin(here, s))
    # a ship whose engine or RCS the player fires is not at rest (MODEL-NOTES 45)
    driven = cfg.landed_model == REST_LANDED and cmd.driven
    ok = s.surface_state == CONTACT and margin > 0.0 and not driven
    dt = cfg.dt_s
    if not ok:
        held = 0.0
    elif run.sampled:  # sampled at every sub-step's end (MODEL-NOTES 47)
        held = dt - run.began_s
    elif s.footing.settle_ticks > 0:
        held = s.footing.settle_for_s + dt
    else:  # they began to hold inside this tick: where the margin crossed zero
        prev = s.footing.settle_margin
        f = prev / (prev - margin) if prev < 0.0 else 0.0
        held = (1.0 - fmin(fmax(f, 0.0), 1.0)) * dt
    ticks = s.footing.settle_ticks + 1 if ok else 0
    ft = s.footing
    if not (ok and held >= cfg.settle_time_s - 1e-9 * dt):
        return with_footing(s, with_settle(ft, ticks, held, margin))
    m = s.motion
    # a state of rest is where the rock that is left ends (MODEL-NOTES 55); the seed's attached
    # state keeps the pose it settled in
    p, q = m.p, m.q
    if cfg.landed_model == REST_LANDED:
        p, q = rest_pose(cfg, here.sp, s.mass_kg, m.p, m.q,
                         scene_ground(cfg, here.terrain, cos1, sin1))
    pp, pq = pin_pose(p, q, cos1, sin1)
    om = cfg.omega_radps
    emit(log, CONTACT, LANDED, 0.0, fmin(fmax(dt - (held - cfg.settle_time_s), 0.0), dt))
    landed = with_motion(s, LANDED, Motion(p, surface_velocity(om, p), q,
                                           body_spin_in_body_frame(om, q)))
    landed = with_footing(landed, with_settle(with_friction(ft, ft.sliding, NO_HOLD), 0, 0.0,
                                              margin))
    return with_pin(landed, Pin(pp, pq, s.pin.pivot_bf_m, s.pin.rate_radps))


# -- 4. pinned -----------------------------------------------------------------------------------
@kernel
def pinned(here, s, cmd, log):
    """Landed, tipped and crashed ships: body-fixed poses mapped to the inertial frame at the
    tick's end; tipped ships turn about their pivot foot (sim.pivot.pivot_step), righted (back to
    contact) when tilt < tipped_angle while turning upright. Velocities are those of the pinned
    motion (a tipped ship's turn included). (Liftoff: :func:`lift_off`, at the tick's start.)"""
    cfg, sp, cos1, sin1 = here.cfg, here.sp, here.turn.cos1, here.turn.sin1
    om = cfg.omega_radps
    surf = s.surface_state
    p_bf, q_bf, pivot = s.pin.pos_bf_m, s.pin.quat_bf, s.pin.pivot_bf_m
    rate = s.pin.rate_radps
    m = s.mass_kg
    righted = False
    if surf == TIPPED:  # the pivot model (an upright ship has no axis to turn about)
        i_b = inertia((sp.inertia0_kgm2[0], sp.inertia0_kgm2[1], sp.inertia0_kgm2[2]),
                      sp.mass0_kg, m)
        ps = pivot_step(cfg, s.pin, m, i_b, cmd.rcs_torque_body_nm)
        p_bf, q_bf, rate = ps.pos_bf_m, ps.quat_bf, ps.rate_radps
        righted = ps.righted
        if ps.hull_crash:
            surf = CRASHED
        elif ps.righted:
            surf = CONTACT
    if om == 0.0:  # the body-fixed frame is the inertial one
        c, s_ = 1.0, 0.0
        p, q = p_bf, q_bf
    else:
        c, s_ = cos1, sin1
        p = rotate_z(p_bf, c, s_)
        q = quat_mul(quat_z(c, s_), q_bf)
    turning = surf == TIPPED or righted
    v, w = pinned_motion(om, p, q, rotate_z(pivot, c, s_), rate if turning else 0.0)
    if surf != s.surface_state:
        v_rad = dot(sub(v, surface_velocity(om, p)), unit(p))
        # the tilt passing tipped_angle (righted) inside the tick; a hull crash at its end
        t_ev = cfg.dt_s
        if righted:
            t_ev = crossed_at(dot(quat_axis_z(s.pin.quat_bf), unit(s.pin.pos_bf_m)),
                              dot(quat_axis_z(q_bf), unit(p_bf)), cfg.cos_tipped, 0.0, cfg.dt_s)
        emit(log, s.surface_state, surf, v_rad, t_ev)
    ft = s.footing
    footing = fresh_footing(True) if righted else with_friction(ft, ft.sliding, NO_HOLD)
    s = with_footing(with_motion(s, surf, Motion(p, v, q, w)), footing)
    return with_pin(s, Pin(p_bf, q_bf, pivot, 0.0 if (righted or surf == CRASHED) else rate))


@kernel
def lift_off(cfg, s, cmd, log):
    """Landed or tipped -> flying at the tick's start, when the engine's push along local up beats
    the weight in the effective gravity (MODEL-NOTES 25): the tick is then flown with its thrust
    (its fuel buys its motion), from the pinned pose and motion at that instant."""
    up = unit(s.motion.p)
    weight = -s.mass_kg * dot(effective_gravity(cfg.gm_m3ps2, cfg.omega2, s.motion.p), up)
    if not cmd.thrust_n * dot(quat_axis_z(s.motion.q), up) > weight:
        return s
    emit(log, s.surface_state, FLYING, 0.0, 0.0)
    return with_pin(with_footing(with_state(s, FLYING), fresh_footing(True)),
                    Pin(s.pin.pos_bf_m, s.pin.quat_bf, s.pin.pivot_bf_m, 0.0))


@kernel
def unsettle(s, log):
    """Landed -> contact at the tick's start: the player's engine (below liftoff) or RCS changes
    the balance a landed ship rested in, and the physics decides again from its pinned pose at rest
    (MODEL-NOTES 45). The contact goes on on the springs it had."""
    emit(log, LANDED, CONTACT, 0.0, 0.0)
    return with_footing(with_state(s, CONTACT), fresh_footing(s.footing.absorbing))


# -- 5. burn -------------------------------------------------------------------------------------
@kernel
def burn(here, s, cmd):
    """Fuel used this tick: T / (Isp g0) for the engine, sum|tau| / (arm Isp_rcs g0) for the RCS."""
    cfg, sp = here.cfg, here.sp
    rcs = cmd.rcs_torque_body_nm
    rcs_thrust = (abs(rcs[0]) + abs(rcs[1]) + abs(rcs[2])) / sp.rcs_arm_m
    flow = cmd.thrust_n / (sp.isp_s * G0_MPS2) + rcs_thrust / (sp.rcs_isp_s * G0_MPS2)
    used = fmin(flow * cfg.dt_s, s.fuel_kg)
    return with_mass(s, s.mass_kg - used, s.fuel_kg - used)


# -- 6. observe ----------------------------------------------------------------------------------
@kernel
def observe(here, s, cmd, report, out):
    """Telemetry at the end of the tick, into the ship's output record, in place. Forces come from
    the free-flight phase's ``report`` (free ships) or are the weight (landed, tipped)."""
    cfg, terrain, sp, cos1, sin1 = here.cfg, here.terrain, here.sp, here.turn.cos1, here.turn.sin1
    om = cfg.omega_radps
    # (the flight's evaluation at the tick's end has it, where its ground is this one)
    if unturned(cfg, cos1, sin1) and not math.isnan(report.lowest_m):
        pen = report.lowest_m
    else:
        pen = lowest_foot_penetration(scene_ground(cfg, terrain, cos1, sin1), s.motion.p,
                                      s.motion.q, sp.leg_radius_m, sp.com_height_m)
    r_hat = unit(s.motion.p)
    v_rel = sub(s.motion.v, surface_velocity(om, s.motion.p))
    v_rad = dot(v_rel, r_hat)
    held = s.surface_state == LANDED or (s.surface_state == TIPPED and report.normal_n == 0.0
                                         and report.friction_n == 0.0)
    if held:
        normal = -s.mass_kg * dot(effective_gravity(cfg.gm_m3ps2, cfg.omega2, s.motion.p), r_hat)
    elif s.surface_state == CRASHED:
        normal = 0.0
    else:
        normal = report.normal_n
    out.altitude_m = -pen
    out.penetration_m = fmax(pen, 0.0)
    out.peak_penetration_m = fmax(fmax(report.peak_penetration_m, pen), 0.0)
    out.cos_tilt = dot(quat_axis_z(s.motion.q), r_hat)
    out.v_radial_mps = v_rad
    out.v_tangential_mps = norm(sub(v_rel, scale(r_hat, v_rad)))
    out.normal_force_n = normal
    out.friction_force_n = 0.0 if held else report.friction_n
    out.throttle = cmd.throttle
    for k in range(3):
        out.rcs_torque_body_nm[k] = cmd.rcs_torque_body_nm[k]
    out.energy_guard_j = report.guard_j


# -- the step ------------------------------------------------------------------------------------
@constructor
def step_ship(here, rec, inp, out, log):
    """One ship's tick: the phases above, in order. ``rec`` is updated in place, ``out`` written,
    the transitions appended to ``log`` (an :class:`EventLog`); ``here``: the scene and this ship
    this tick (a :class:`sim.ship.Here`)."""
    cfg, sp = here.cfg, here.sp
    s = load(rec)
    cmd = commands(here, s, inp)
    report = NO_REPORT
    if s.surface_state == LANDED or s.surface_state == TIPPED:
        s = lift_off(cfg, s, cmd, log)
    if s.surface_state == LANDED and cfg.landed_model == REST_LANDED and cmd.driven:
        s = unsettle(s, log)
    # a tipped ship moves by the full model, unless it rests on its hull and no RCS fires
    # (MODEL-NOTES 48); under the pivot model (0.7's) it is pinned and turns about its foot
    moving_tipped = (s.surface_state == TIPPED and cfg.tipped_model == FULL_TIPPED
                     and not (on_hull(cfg, s) and not rcs_fires(cmd)))
    if s.surface_state == FLYING or s.surface_state == CONTACT or moving_tipped:
        # the ship this tick (its touching and method are set once the path is chosen, below)
        fb = free_body(here, s, cmd, False, cfg.method)
        fine = (s.surface_state != FLYING
                or (near_ground(here, s, cmd) and not clear_tick_of(here, s, fb)))
        exact_one = (fine and cfg.vertical_one_step
                     and (cfg.method == EXPONENTIAL or cfg.method == HYBRID)
                     and purely_vertical(here, s, cmd))
        n_sub = sp.n_substeps if fine and not exact_one else 1
        strikes = fine and not exact_one and striking(here, s)
        if strikes and cfg.impact_substeps > n_sub:
            n_sub = cfg.impact_substeps
        method = sub_method(cfg.method, fine and not exact_one)
        fb = stepped_by(fb, fine, method)
        # an impact's static friction changes too fast to be carried over: impulses alone; with
        # rk4 the holding feet's friction is inside the step (substep), nothing is carried
        held_inside = method == RK4 and per_foot(cfg)
        # a ship in contact may take coarser sub-steps where nothing the finer ones resolve can
        # happen in them (sim.coarse_substep, MODEL-NOTES 57; decided on its contact at the start)
        coarse = (cfg.coarse_substeps > 0 and cfg.coarse_substeps < n_sub and not strikes
                  and s.surface_state == CONTACT and method == RK4 and per_foot(cfg))
        if not fine:
            fl = fly_clear(cfg, fb, s)
        elif exact_one and cfg.vertical_path and per_foot(cfg):
            # motion along the local vertical alone: its own path (MODEL-NOTES 65)
            fl = vertical_flight(here, fb, s, log)
        else:
            fl = free_flight(here, fb, s, n_sub, not (strikes or held_inside), coarse, log)
        s, report = fl.ship, fl.report
        if fine:
            s = settle(here, s, cmd, fl.run, log)
            if s.surface_state != fl.ship.surface_state:  # landed, at its rest pose
                report = Report(report.friction_n, report.normal_n, report.peak_penetration_m,
                                report.guard_j, math.nan)
    else:
        s = pinned(here, s, cmd, log)
    s = burn(here, s, cmd)
    store(s, rec)
    observe(here, s, cmd, report, out)


@kernel
def rcs_fires(cmd):
    rcs = cmd.rcs_torque_body_nm
    return rcs[0] != 0.0 or rcs[1] != 0.0 or rcs[2] != 0.0


@kernel
def on_hull(cfg, s):
    """A tipped ship at rest on its hull: tilted to tipped_rest or past it and not moving
    relative to the surface (the pose the full model leaves it in when its hull meets the ground,
    or a tipped start lying there)."""
    m = s.motion
    om = cfg.omega_radps
    if dot(quat_axis_z(m.q), unit(m.p)) > cfg.cos_tipped_rest + 1e-12:
        return False
    v_rel = sub(m.v, surface_velocity(om, m.p))
    w_rel = sub(m.w, body_spin_in_body_frame(om, m.q))
    return dot(v_rel, v_rel) == 0.0 and dot(w_rel, w_rel) == 0.0
