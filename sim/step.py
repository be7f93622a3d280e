"""The tick: ``step(params, state, inputs) -> (state, outputs, events)``, a pure function.

The batch is stepped by one loop over its ships (:func:`step_ships`), compiled (sim.compiled);
inside it, one ship's tick is a chain of phases, in order, each a function below:

1. ``commands``     throttle and RCS torque actually applied (fuel, hold-mode controller)
2. ``free_flight``  flying and contact ships: integrate, friction at the feet, the passivity
                    guard, and the in-flight transitions (contact, crash, liftoff, tipped) at
                    every sub-step; a ship near the ground takes its own ``n_substeps``
                    sub-steps, a purely vertical one a single exact step, and a ship far above
                    one step with no contact work
3. ``settle``       contact -> landed once the settle thresholds have held for ``settle_time``
                    with the centre of mass over the footprint
4. ``pinned``       landed, tipped and crashed ships turn with the body; liftoff; tipped ships'
                    pivot model (sim.pivot) and righting
5. ``burn``         fuel and mass
6. ``observe``      the tick's telemetry

A ship's numbers depend only on its own state, inputs and parameters: nothing is summed or compared
across ships, so a ship stepped alone or among thousands gives bit-identical results. Decisions
compare cosines and squared speeds, never angles.
"""
from __future__ import annotations

import math
from typing import NamedTuple, Sequence

import numpy as np

from sim.compiled import constructor, kernel, separate
from sim.constants import G0_MPS2
from sim.contact import lowest_foot_penetration
from sim.dynamics import FreeBody, contact_at, ground_at, ground_turn, with_engage
from sim.energy import mechanical, rotation, total, translation
from sim.enums import TRANSITION_EVENTS, HoldMode, SurfaceState
from sim.frames import (body_rotation, body_spin_in_body_frame, effective_gravity, inertia,
                        pin_pose, quat_z, rotate_z, surface_velocity, turned)
from sim.friction import coulomb, hold_footprint, seed, spread_over_step
from sim.contact import Ground, feet
from sim.integrators import advance
from sim.params import Params
from sim.pivot import pinned_motion, pivot_step, rate_from_momentum
from sim.state import (COMMAND_DTYPE, INPUTS_DTYPE, OUTPUTS_DTYPE, STATE_DTYPE, TRANSITION_DTYPE,
                       Event, Inputs, Outputs, State)
from sim.vec import add, cross, dot, fmax, fmin, mul, norm, quat_axis_z, quat_mul, \
    quat_normalize, quat_rotate_inv, scale, sub, unit

FLYING, CONTACT, LANDED, TIPPED, CRASHED = (int(s) for s in SurfaceState)
HOLD_OFF, HOLD_RADIAL = int(HoldMode.OFF), int(HoldMode.RADIAL)

#: Squared tilt (rad^2), spin ((rad/s)^2) and slip ((m/s)^2) below which a ship counts as purely
#: vertical. Feet a planet's radius from its centre are placed to ulp(|p|) (2e-10 m on the Moon, 1e-9 m
#: on Earth), which leaves an upright bounce turning at ~1e-10 rad/s: 1e-8 is rounding's level, and
#: what a tilt, spin or slip that small would do over a tick is far below the 1e-7 to which one
#: exact step and sub-steps of the full model agree (tests/test_models.py).
VERTICAL_TOL2 = 1e-16

#: A step that ends (or starts) exactly where the feet reach the ground leaves them within rounding
#: of it (ulp(|p|) ~ 2e-10 m on the Moon): the feet count as clear before that instant and as
#: pressing from it, within this margin, so that all of an upright ship's feet engage together.
ONSET_MARGIN_M = 1e-6

#: an empty list of commands (sim.state.COMMAND_DTYPE)
NO_COMMANDS = np.zeros(0, COMMAND_DTYPE)


class Ship(NamedTuple):
    """One ship's state inside the kernels (sim.state.STATE_DTYPE, as numbers and tuples)."""

    surface_state: int
    p: tuple  # centre of mass, inertial, m
    v: tuple  # m/s
    q: tuple  # body -> inertial
    w: tuple  # body-frame angular velocity, rad/s
    mass_kg: float
    fuel_kg: float
    absorbing: bool
    sliding: tuple  # each foot's friction regime
    settle_ticks: int
    pivot_rate_radps: float
    pin_pos_bf_m: tuple
    pin_quat_bf: tuple
    pin_pivot_bf_m: tuple


@kernel
def load(rec):
    """A ship's record as a :class:`Ship`."""
    return Ship(np.int64(rec.surface_state), (rec.pos_m[0], rec.pos_m[1], rec.pos_m[2]),
                (rec.vel_mps[0], rec.vel_mps[1], rec.vel_mps[2]),
                (rec.quat[0], rec.quat[1], rec.quat[2], rec.quat[3]),
                (rec.omega_body_radps[0], rec.omega_body_radps[1], rec.omega_body_radps[2]),
                rec.mass_kg, rec.fuel_kg, bool(rec.absorbing),
                (rec.sliding[0] != 0, rec.sliding[1] != 0, rec.sliding[2] != 0,
                 rec.sliding[3] != 0),
                np.int64(rec.settle_ticks), rec.pivot_rate_radps,
                (rec.pin_pos_bf_m[0], rec.pin_pos_bf_m[1], rec.pin_pos_bf_m[2]),
                (rec.pin_quat_bf[0], rec.pin_quat_bf[1], rec.pin_quat_bf[2], rec.pin_quat_bf[3]),
                (rec.pin_pivot_bf_m[0], rec.pin_pivot_bf_m[1], rec.pin_pivot_bf_m[2]))


@kernel
def store(s, rec):
    """Write a :class:`Ship` into its record."""
    rec.surface_state = s.surface_state
    for k in range(3):
        rec.pos_m[k] = s.p[k]
        rec.vel_mps[k] = s.v[k]
        rec.omega_body_radps[k] = s.w[k]
        rec.pin_pos_bf_m[k] = s.pin_pos_bf_m[k]
        rec.pin_pivot_bf_m[k] = s.pin_pivot_bf_m[k]
    for k in range(4):
        rec.quat[k] = s.q[k]
        rec.pin_quat_bf[k] = s.pin_quat_bf[k]
        rec.sliding[k] = 1 if s.sliding[k] else 0
    rec.mass_kg = s.mass_kg
    rec.fuel_kg = s.fuel_kg
    rec.absorbing = s.absorbing
    rec.settle_ticks = s.settle_ticks
    rec.pivot_rate_radps = s.pivot_rate_radps


@kernel
def emit(events, count, ship, from_state, to_state, v_radial_mps):
    """Append a transition to ``events``; ``count[0]`` is how many there are (those past the
    array's end are counted, not written)."""
    n = count[0]
    if n < events.shape[0]:
        e = events[n]
        e.ship = ship
        e.from_state = from_state
        e.to_state = to_state
        e.v_radial_mps = v_radial_mps
    count[0] = n + 1


# -- 1. commands ---------------------------------------------------------------------------------
class Commands(NamedTuple):
    throttle: float
    thrust_n: float
    rcs_torque_body_nm: tuple


@kernel
def commands(cfg, sp, s, inp):
    """Applied throttle and RCS torque. The hold-mode controller (flying and contact) is a PD law,
    tau = -I (w_c^2 err + 2 w_c omega_rel), saturated at max_rcs_torque; a non-zero manual RCS
    command on an axis overrides it there. No fuel, or a crashed ship: nothing fires."""
    live = s.fuel_kg > 0.0 and s.surface_state != CRASHED
    if not live:
        return Commands(0.0, 0.0 * sp.max_thrust_n, (0.0, 0.0, 0.0))
    throttle = fmin(fmax(inp.throttle, 0.0), 1.0)
    max_tau = sp.max_rcs_torque_nm
    auto = (0.0, 0.0, 0.0)
    hold = int(inp.hold)
    if hold != HOLD_OFF and (s.surface_state == FLYING or s.surface_state == CONTACT):
        bw = cfg.bandwidth_radps
        omega_rel = sub(s.w, body_spin_in_body_frame(cfg.omega_radps, s.q))
        up_b = quat_rotate_inv(s.q, unit(s.p))
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
    return Commands(throttle, throttle * sp.max_thrust_n, rcs)


# -- 2. free flight ------------------------------------------------------------------------------
@kernel
def near_ground(cfg, terrain, sp, s, cmd, cos0, sin0):
    """True for a ship that might touch the ground within this tick (conservative bound). On a
    slope the ground's plane is taken under the ship, rising by tan(slope) over every metre the
    feet and the tick's motion can reach sideways."""
    dt = cfg.dt_s
    reach_down = sp.com_height_m + sp.leg_radius_m
    speed = norm(s.v)
    accel = cfg.surface_gravity_mps2 + cmd.thrust_n / s.mass_kg
    reach = 2.0 * (speed * dt + accel * dt * dt) + 1.0
    plane = 0.0
    if cfg.slope_tan != 0.0:
        east = -sin0 * s.p[0] + cos0 * s.p[1]
        plane = (terrain.slope_east * east + terrain.slope_north * s.p[2]
                 + cfg.slope_tan * (reach_down + reach))
    clearance = norm(s.p) - cfg.body_radius_m - cfg.terrain_max_m - plane - reach_down
    return clearance < reach


@kernel
def purely_vertical(cfg, terrain, sp, s, cmd):
    """A ship whose motion this tick is along the local vertical only: upright, not turning, not
    slipping, no RCS torque, level ground under the whole footprint, a body that does not spin.
    For it every kick of the exponential method is zero, so its one step per tick is already
    exact and sub-steps would only repeat it (``sim.vertical_one_step``)."""
    if cfg.omega_radps != 0.0 or cfg.slope_tan != 0.0:
        return False
    r_hat = unit(s.p)
    tilt = cross(quat_axis_z(s.q), r_hat)
    v_rad = dot(s.v, r_hat)
    slip = sub(s.v, scale(r_hat, v_rad))
    rcs = cmd.rcs_torque_body_nm
    if not (dot(tilt, tilt) < VERTICAL_TOL2 and dot(s.w, s.w) < VERTICAL_TOL2
            and dot(slip, slip) < VERTICAL_TOL2 and rcs[0] == 0.0 and rcs[1] == 0.0
            and rcs[2] == 0.0):
        return False
    # the terrain's coordinates of a point are its body-fixed (y, z): (east, north) at the site
    for j in range(terrain.n_bumps):
        de = s.p[1] - terrain.bumps[j, 0]
        dn = s.p[2] - terrain.bumps[j, 1]
        clear = terrain.bumps[j, 2] + sp.leg_radius_m + 1.0
        if not de * de + dn * dn > clear * clear:
            return False
    return True


@constructor
def free_body(cfg, terrain, sp, s, cmd, touching, cos0, sin0):
    m = s.mass_kg
    two_omega_m = 2.0 * sp.contact_omega_radps * m  # c = 2 zeta sqrt(k m) = 2 zeta omega m
    return FreeBody(m, inertia((sp.inertia0_kgm2[0], sp.inertia0_kgm2[1], sp.inertia0_kgm2[2]),
                               sp.mass0_kg, m),
                    cmd.thrust_n, cmd.rcs_torque_body_nm, sp.leg_radius_m, sp.com_height_m,
                    sp.stiffness_per_kg * m, cfg.damping_ratio * two_omega_m,
                    cfg.absorb_damping_ratio * two_omega_m, sp.stiffness_per_kg, cfg.gm_m3ps2,
                    cfg.body_radius_m, cfg.omega_radps, terrain,
                    cfg.radial_normal, cos0, sin0, touching, 0.0, cfg.linear_model)


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
    return mechanical(fb.gm_m3ps2, fb.body_radius_m, fb.body_omega_radps, fb.stiffness_per_kg,
                      fb.leg_radius_m, fb.com_height_m, fb.mass_kg, fb.inertia_kgm2, p, v, q, w,
                      ground, fb.touching)


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
def passivity_guard(fb, ground, p, v, q, w, ref, passive, airborne):
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
    it removes is reported as ``energy_guard_j`` (``sim.energy_guard``)."""
    e = ship_energy(fb, ground, p, v, q, w)
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
        v_surf = surface_velocity(fb.body_omega_radps, p)
        v = add(v_surf, scale(sub(v, v_surf), f_v))
    if f_w != 1.0:
        spin_b = body_spin_in_body_frame(fb.body_omega_radps, q)
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
def align_at_touchdown(fb, ground, p, v, q, w):
    """The seed's Flying -> Contact rule: attitude snapped to local up and rotation stopped
    (relative to the surface); then the ship moves out along local up so that its deepest foot
    is no deeper than before the snap: turning must not bury the feet (MODEL-NOTES 11). The snap
    must not make energy either (MODEL-NOTES 24): a ship that it would raise (tilted past
    2 atan(a / h), 74 degrees for the default lander) pays for the lift out of its descent speed;
    a ship too slow to pay is not stood up and touches down as it is."""
    r_hat = unit(p)
    q1 = align_to_surface(q, r_hat)
    w1 = body_spin_in_body_frame(fb.body_omega_radps, q1)
    pen0 = lowest_foot_penetration(ground, p, q, fb.leg_radius_m, fb.com_height_m)
    pen1 = lowest_foot_penetration(ground, p, q1, fb.leg_radius_m, fb.com_height_m)
    p1 = add(p, scale(r_hat, fmax(pen1 - pen0, 0.0)))
    cost = total(ship_energy(fb, ground, p1, v, q1, w1)) - total(ship_energy(fb, ground, p, v, q, w))
    v_rad = dot(sub(v, surface_velocity(fb.body_omega_radps, p)), r_hat)
    spare = v_rad * v_rad - 2.0 * cost / fb.mass_kg
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


@separate
def substep(cfg, fb, bodies, h, p, v, q, w, ce_start, sliding, absorbing, t_start):
    """One step of the method (with ``bodies``, which may differ from ``fb`` in where its feet
    engage), then Coulomb friction (or the seed's) at the feet that pressed, spread over the
    step, and a held footprint kept where the ground carried it."""
    z4 = (False, False, False, False)
    res = advance(cfg.method, bodies, h, p, v, q, w, ce_start, absorbing, t_start)
    j = res.foot_impulse_ns
    pressed = j[0] != 0.0 or j[1] != 0.0 or j[2] != 0.0 or j[3] != 0.0
    if not fb.touching:
        return SubStep(res.p, res.v, res.q, res.w, sliding, 0.0, res.peak_penetration_m,
                       res.located, pressed)
    if not pressed:  # no foot pressed: no friction (nor any foot's regime) to keep
        return SubStep(res.p, res.v, res.q, res.w, z4, 0.0, res.peak_penetration_m, res.located,
                       pressed)
    ground_end = ground_at(fb, t_start + h)
    if cfg.seed_friction:
        j_n = j[0] + j[1] + j[2] + j[3]
        fr = seed(cfg.friction_static, cfg.friction_kinetic, fb.mass_kg, res.p, res.v, res.w,
                  j_n, ground_end)
        return SubStep(res.p, fr.vel_mps, res.q, res.w, fr.sliding, fr.impulse_ns / h,
                       res.peak_penetration_m, res.located, pressed)
    ft = feet(ground_end, res.p, res.q, fb.leg_radius_m, fb.com_height_m)
    fr = coulomb(cfg.friction_static, cfg.friction_kinetic, fb.mass_kg, fb.inertia_kgm2, res.p,
                 res.v, res.q, res.w, ft, j, sliding, ground_end)
    p2, q2 = spread_over_step(res.p, res.q, res.v, fr.vel_mps, res.w, fr.omega_body_radps, h)
    held = not (sliding[0] or sliding[1] or sliding[2] or sliding[3] or fr.sliding[0]
                or fr.sliding[1] or fr.sliding[2] or fr.sliding[3]) and fr.impulse_ns > 0.0
    if held:
        c_turn, s_turn = ground_turn(fb, h)
        ft2 = feet(ground_end, p2, q2, fb.leg_radius_m, fb.com_height_m)
        # the feet where the step began (what ce_start was evaluated on)
        ft0 = feet(ground_at(fb, t_start), p, q, fb.leg_radius_m, fb.com_height_m)
        p2 = hold_footprint(p2, ft0, ft2, j, c_turn, s_turn)
    return SubStep(p2, fr.vel_mps, q2, fr.omega_body_radps, fr.sliding, fr.impulse_ns / h,
                   res.peak_penetration_m, res.located, pressed)


@kernel
def _a_down(fb, p, q, r_hat):
    """Acceleration toward the ground along local up in free flight: g - T cos(tilt) / m."""
    return fb.gm_m3ps2 / dot(p, p) - fb.thrust_n * dot(quat_axis_z(q), r_hat) / fb.mass_kg


class Flight(NamedTuple):
    """A free ship after its tick of flight."""

    ship: Ship
    friction_n: float  # the last sub-step's friction force (the feet's sum)
    normal_n: float  # the normal force at the end
    peak_penetration_m: float  # the deepest penetration of any sub-step
    guard_j: float  # what the passivity guard removed


@separate
def free_flight(cfg, fb, s, n_sub, cos1, sin1, ship_index, events, count):
    """Advance a free ship by one tick in ``n_sub`` equal sub-steps; transitions are emitted in
    the order they happen."""
    dt = cfg.dt_s
    h = dt / n_sub
    touching = fb.touching
    om = fb.body_omega_radps
    p, v, q, w = s.p, s.v, s.q, s.w
    surf = s.surface_state
    absorbing = s.absorbing
    sliding = s.sliding
    settle = s.settle_ticks
    pin_p, pin_q, pin_pivot = s.pin_pos_bf_m, s.pin_quat_bf, s.pin_pivot_bf_m
    pivot_rate = s.pivot_rate_radps
    friction_n = 0.0
    peak = 0.0
    guard_j = 0.0
    ground0 = ground_at(fb, 0.0)
    ce = contact_at(fb, ground0, p, v, q, w, absorbing, fb.engage_m)
    v_rad = dot(v, unit(p))
    guard = cfg.energy_guard
    passive = (fb.thrust_n == 0.0 and fb.rcs_torque_body_nm[0] == 0.0
               and fb.rcs_torque_body_nm[1] == 0.0 and fb.rcs_torque_body_nm[2] == 0.0)
    e_ref = energy_ref(ship_energy(fb, ground0, p, v, q, w)) if guard else EnergyRef(0.0, 0.0, 0.0)

    for j in range(n_sub):
        t_off = j * h  # this sub-step's start, from the tick's start
        pen_before, v_rad_before = ce.max_penetration_m, v_rad
        crossing = False
        v_cross = 0.0
        tau = 0.0
        if touching:
            # Contact onset inside the sub-step: the damper's force jumps to c v at the surface,
            # so step exactly to the crossing (ballistic time of flight of the lowest foot,
            # tau = 2 z / (v + sqrt(v^2 + 2 a z))) and from there to the sub-step's end.
            z = -pen_before
            v_down = -v_rad
            a_dn = _a_down(fb, p, q, unit(p))
            disc = v_down * v_down + 2.0 * a_dn * (z if z > 0.0 else 0.0)
            denom = v_down + math.sqrt(fmax(disc, 0.0))
            tau = 2.0 * z / (denom if denom > 0.0 else 1.0)
            crossing = (surf == FLYING and z > 0.0 and v_down > 0.0 and disc >= 0.0
                        and denom > 0.0 and tau < h)
            v_cross = math.sqrt(fmax(disc, 0.0))  # speed of the lowest foot at the surface
        aligned = False
        if crossing:
            # Up to the crossing the motion is ballistic by construction. Its last stage ends with
            # the feet at the surface to within rounding, where some feet would press (with the
            # damper's full jump c v) and others not: a spurious torque. They must not press there.
            st1 = substep(cfg, fb, with_engage(fb, -ONSET_MARGIN_M), tau, p, v, q, w, ce, sliding,
                          absorbing, t_off)
            # At the crossing itself: an impact slower than bounce_speed is taken by the
            # absorbers from its first instant, and the seed's touchdown alignment happens here
            absorbing = v_cross < cfg.bounce_speed_mps
            t_cross = t_off + tau
            ground_x = ground_at(fb, t_cross)
            p1, v1, q1, w1 = st1.p, st1.v, st1.q, st1.w
            if cfg.align_on_touchdown:
                al = align_at_touchdown(fb, ground_x, p1, v1, q1, w1)
                p1, v1, q1, w1, aligned = al.p, al.v, al.q, al.w, al.aligned
            ce_mid = contact_at(fb, ground_x, p1, v1, q1, w1, absorbing, ONSET_MARGIN_M)
            st2 = substep(cfg, fb, fb, h - tau, p1, v1, q1, w1, ce_mid, st1.sliding, absorbing,
                          t_cross)
            touched = st1.pressed or st2.pressed
            inner_peak = fmax(st1.peak_penetration_m, st2.peak_penetration_m)
            located = st2.located
            p, v, q, w = st2.p, st2.v, st2.q, st2.w
            sliding = st2.sliding
            friction_n = st2.friction_n
        else:
            st = substep(cfg, fb, fb, h, p, v, q, w, ce, sliding, absorbing, t_off)
            touched = st.pressed
            inner_peak = st.peak_penetration_m
            located = st.located
            p, v, q, w = st.p, st.v, st.q, st.w
            sliding = st.sliding
            friction_n = st.friction_n
        t_end_off = (j + 1) * h
        ground = ground_at(fb, t_end_off)
        ce = contact_at(fb, ground, p, v, q, w, absorbing, fb.engage_m)
        if guard:
            # airborne: clear of the ground at both ends and nothing pressed between (a bilateral
            # absorber's pull passes no positive impulse, yet trades translation for rotation)
            airborne = not touched and pen_before < 0.0 and ce.max_penetration_m < 0.0
            gd = passivity_guard(fb, ground, p, v, q, w, e_ref, passive, airborne)
            v, w, e_ref = gd.v, gd.w, gd.ref
            guard_j = guard_j + gd.removed_j
            if gd.removed_j > 0.0:  # the dampers' forces follow the velocities it scaled
                ce = contact_at(fb, ground, p, v, q, w, absorbing, fb.engage_m)

        # in-flight transitions, decided on this sub-step's end state
        r_hat = unit(p)
        v_rad = dot(v, r_hat)
        pen = ce.max_penetration_m
        if touching:
            if located:
                step_peak = fmax(fmax(pen_before, pen), inner_peak)
            else:  # interpolate between the sub-step's ends
                step_peak = hermite_peak(pen_before, -v_rad_before, pen, -v_rad, h)
            peak = fmax(peak, step_peak)
        was = surf
        # a located crossing is a touchdown even if the ship is already rebounding at the end
        touch = was == FLYING and ((pen > 0.0 and v_rad < 0.0) or crossing)
        # Speeds at the surface crossing, from the ballistic motion on the clear side of it (the
        # damper acts from the first millimetre, so the sub-step's end speed is already lower):
        # v_cross^2 = v^2 + 2 a_down height, a_down = g - T cos(tilt) / m.
        a_down = _a_down(fb, p, q, r_hat)
        if crossing:
            impact = v_cross
        elif v_rad_before < 0.0:
            above_before = fmax(-pen_before, 0.0)
            impact = math.sqrt(fmax(v_rad_before * v_rad_before
                                    + 2.0 * a_down * above_before, 0.0))
        else:
            impact = -v_rad
        separation = math.sqrt(fmax(v_rad * v_rad + 2.0 * a_down * fmax(-pen, 0.0), 0.0))
        # in contact: descending faster than crash_speed at either end of the sub-step (the
        # damper may already have slowed it by the end)
        crash = (touch and impact > cfg.crash_speed_mps) or (
            was == CONTACT and fmin(v_rad, v_rad_before) < -cfg.crash_speed_mps)
        touch_ok = touch and not crash
        if touch_ok:
            absorbing = impact < cfg.bounce_speed_mps
            sliding = (False, False, False, False)
            settle = 0
            if cfg.align_on_touchdown and not crossing:  # a located crossing was aligned there
                al = align_at_touchdown(fb, ground, p, v, q, w)
                p, v, q, w = al.p, al.v, al.q, al.w
                aligned = aligned or al.aligned
                ce = contact_at(fb, ground, p, v, q, w, absorbing, fb.engage_m)
                if guard and al.aligned:  # the snap never adds energy; measure from after it
                    e_ref = energy_ref(ship_energy(fb, ground, p, v, q, w))
        cos_tilt = dot(quat_axis_z(q), r_hat)
        # all feet clear and moving away: a bounce or a thrust-off (the align of a touchdown can
        # lift a foot clear while the ship still descends; that is not a liftoff)
        lift = was == CONTACT and not crash and ce.max_penetration_m < 0.0 and v_rad > 0.0
        # past tipped_angle in contact; a touchdown already past it that was not stood up by the
        # alignment lies down at once (its hull, which the model does not have, is what touches)
        lying_down = touch and not aligned
        tip = (((was == CONTACT and not lift) or lying_down) and not crash
               and cos_tilt < cfg.cos_tipped)
        v_rel = sub(v, surface_velocity(om, p))
        tip_crash = tip and dot(v_rel, v_rel) > cfg.crash_speed2
        crash = crash or tip_crash
        tip = tip and not tip_crash
        if tip or crash:
            c, s_ = turned(fb.cos0, fb.sin0, om, t_end_off)
            pin_p, pin_q = pin_pose(p, q, c, s_)
            if tip:
                pin_pivot = rotate_z(ce.lowest_foot_w, c, -s_)
                pivot_rate = rate_from_momentum(om, fb.mass_kg, fb.inertia_kgm2, p, v, q, w,
                                                ce.lowest_foot_w)
        if touch_ok:
            surf = CONTACT
        if lift:
            surf = FLYING
        if tip:
            surf = TIPPED
        if crash:
            surf = CRASHED
        if touch_ok and tip:  # two transitions in one sub-step
            emit(events, count, ship_index, FLYING, CONTACT, -impact)
            was = CONTACT
        if surf != was:
            if was == FLYING:
                speed = -impact
            elif surf == FLYING:
                speed = separation
            else:
                speed = v_rad
            emit(events, count, ship_index, was, surf, speed)
        if tip or crash:
            break
    if surf == CRASHED or surf == TIPPED:
        # pinned during the tick: carried with the body to the tick's end, moving as pinned
        p = rotate_z(pin_p, cos1, sin1)
        q = quat_mul(quat_z(cos1, sin1), pin_q)
        v, w = pinned_motion(om, p, q, rotate_z(pin_pivot, cos1, sin1),
                             pivot_rate if surf == TIPPED else 0.0)
    out = Ship(surf, p, v, q, w, s.mass_kg, s.fuel_kg, absorbing, sliding, settle, pivot_rate,
               pin_p, pin_q, pin_pivot)
    return Flight(out, friction_n, abs(ce.normal_n), peak, guard_j)


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
def settle(cfg, sp, s, cos1, sin1, ship_index, events, count):
    """Contact -> landed once tilt, angular and linear speeds have stayed under their thresholds
    for ``settle_time`` (SEED-NOTES 3: the bottom of a bounce, where v_radial = 0, never lands),
    with the centre of mass over the footprint (the seed's "ship stable"; MODEL-NOTES 26)."""
    om = cfg.omega_radps
    r_hat = unit(s.p)
    v_rel = sub(s.v, surface_velocity(om, s.p))
    v_rad = dot(v_rel, r_hat)
    v_tan = sub(v_rel, scale(r_hat, v_rad))
    omega_rel = sub(s.w, body_spin_in_body_frame(om, s.q))
    ez = quat_axis_z(s.q)
    lin2 = cfg.settle_lin2
    ok = (s.surface_state == CONTACT and v_rad * v_rad < lin2 and dot(v_tan, v_tan) < lin2
          and dot(omega_rel, omega_rel) < cfg.settle_ang2 and dot(ez, r_hat) > cfg.cos_settle_tilt
          and over_footprint(cfg, sp, s.p, s.q))
    ticks = s.settle_ticks + 1 if ok else 0
    if not (ok and ticks > cfg.settle_need_ticks):
        return Ship(s.surface_state, s.p, s.v, s.q, s.w, s.mass_kg, s.fuel_kg, s.absorbing,
                    s.sliding, ticks, s.pivot_rate_radps, s.pin_pos_bf_m, s.pin_quat_bf,
                    s.pin_pivot_bf_m)
    pp, pq = pin_pose(s.p, s.q, cos1, sin1)
    emit(events, count, ship_index, CONTACT, LANDED, 0.0)
    return Ship(LANDED, s.p, surface_velocity(om, s.p), s.q, body_spin_in_body_frame(om, s.q),
                s.mass_kg, s.fuel_kg, s.absorbing, s.sliding, 0, s.pivot_rate_radps, pp, pq,
                s.pin_pivot_bf_m)


# -- 4. pinned -----------------------------------------------------------------------------------
@kernel
def pinned(cfg, sp, s, cmd, cos1, sin1, ship_index, events, count):
    """Landed, tipped and crashed ships: body-fixed poses mapped to the inertial frame at the
    tick's end; liftoff when the engine's push along local up beats the weight in the effective
    gravity (MODEL-NOTES 25); tipped ships turn about their pivot foot (sim.pivot.pivot_step),
    righted (back to contact) when tilt < tipped_angle while turning upright. Velocities are
    those of the pinned motion (a tipped ship's turn included)."""
    om = cfg.omega_radps
    surf = s.surface_state
    p_bf, q_bf, pivot = s.pin_pos_bf_m, s.pin_quat_bf, s.pin_pivot_bf_m
    rate = s.pivot_rate_radps
    m = s.mass_kg
    righted = False
    if surf == TIPPED:  # the pivot model (an upright ship has no axis to turn about)
        i_b = inertia((sp.inertia0_kgm2[0], sp.inertia0_kgm2[1], sp.inertia0_kgm2[2]),
                      sp.mass0_kg, m)
        ps = pivot_step(cfg.dt_s, cfg.gm_m3ps2, om, cfg.tipped_rest_rad, cfg.crash_speed_mps,
                        cfg.cos_tipped, p_bf, q_bf, pivot, m, i_b, rate, cmd.rcs_torque_body_nm)
        p_bf, q_bf, rate = ps.pos_bf_m, ps.quat_bf, ps.rate_radps
        righted = ps.righted
        if ps.hull_crash:
            surf = CRASHED
        elif ps.righted:
            surf = CONTACT
    up = unit(p_bf)
    ez = quat_axis_z(q_bf)
    weight = -m * dot(effective_gravity(cfg.gm_m3ps2, cfg.omega2, p_bf), up)
    lift = (surf == LANDED or surf == TIPPED) and cmd.thrust_n * dot(ez, up) > weight
    if lift:
        surf = FLYING
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
        emit(events, count, ship_index, s.surface_state, surf, v_rad)
    freed = righted or lift
    return Ship(surf, p, v, q, w, m, s.fuel_kg, True if freed else s.absorbing,
                (False, False, False, False) if freed else s.sliding,
                0 if freed else s.settle_ticks,
                0.0 if (freed or surf == CRASHED) else rate, p_bf, q_bf, pivot)


# -- 5. burn -------------------------------------------------------------------------------------
@kernel
def burn(cfg, sp, s, cmd):
    """Fuel used this tick: T / (Isp g0) for the engine, sum|tau| / (arm Isp_rcs g0) for the RCS."""
    rcs = cmd.rcs_torque_body_nm
    rcs_thrust = (abs(rcs[0]) + abs(rcs[1]) + abs(rcs[2])) / sp.rcs_arm_m
    flow = cmd.thrust_n / (sp.isp_s * G0_MPS2) + rcs_thrust / (sp.rcs_isp_s * G0_MPS2)
    used = fmin(flow * cfg.dt_s, s.fuel_kg)
    return Ship(s.surface_state, s.p, s.v, s.q, s.w, s.mass_kg - used, s.fuel_kg - used,
                s.absorbing, s.sliding, s.settle_ticks, s.pivot_rate_radps, s.pin_pos_bf_m,
                s.pin_quat_bf, s.pin_pivot_bf_m)


# -- 6. observe ----------------------------------------------------------------------------------
@kernel
def observe(cfg, terrain, sp, s, cmd, friction_n, normal_n, peak_pen_m, guard_j, cos1, sin1, out):
    """Telemetry at the end of the tick, into the ship's output record. Forces come from the
    free-flight phase (free ships) or are the weight (landed, tipped)."""
    om = cfg.omega_radps
    ground = Ground(cfg.body_radius_m, terrain, cos1, sin1, om, cfg.radial_normal)
    pen = lowest_foot_penetration(ground, s.p, s.q, sp.leg_radius_m, sp.com_height_m)
    r_hat = unit(s.p)
    v_rel = sub(s.v, surface_velocity(om, s.p))
    v_rad = dot(v_rel, r_hat)
    held = s.surface_state == LANDED or s.surface_state == TIPPED
    if held:
        normal = -s.mass_kg * dot(effective_gravity(cfg.gm_m3ps2, cfg.omega2, s.p), r_hat)
    elif s.surface_state == CRASHED:
        normal = 0.0
    else:
        normal = normal_n
    out.altitude_m = -pen
    out.penetration_m = fmax(pen, 0.0)
    out.peak_penetration_m = fmax(fmax(peak_pen_m, pen), 0.0)
    out.cos_tilt = dot(quat_axis_z(s.q), r_hat)
    out.v_radial_mps = v_rad
    out.v_tangential_mps = norm(sub(v_rel, scale(r_hat, v_rad)))
    out.normal_force_n = normal
    out.friction_force_n = 0.0 if held else friction_n
    out.throttle = cmd.throttle
    for k in range(3):
        out.rcs_torque_body_nm[k] = cmd.rcs_torque_body_nm[k]
    out.energy_guard_j = guard_j


# -- the step ------------------------------------------------------------------------------------
@kernel
def step_ship(cfg, terrain, sp, rec, inp, out, cos0, sin0, cos1, sin1, ship_index, events, count):
    """One ship's tick: the phases above, in order. ``rec`` is updated in place."""
    s = load(rec)
    cmd = commands(cfg, sp, s, inp)
    friction_n = normal_n = peak = guard_j = 0.0
    if s.surface_state == FLYING or s.surface_state == CONTACT:
        fine = s.surface_state == CONTACT or near_ground(cfg, terrain, sp, s, cmd, cos0, sin0)
        n_sub = 1
        if fine and not (cfg.vertical_one_step and cfg.linear_model
                         and purely_vertical(cfg, terrain, sp, s, cmd)):
            n_sub = sp.n_substeps
        fb = free_body(cfg, terrain, sp, s, cmd, fine, cos0, sin0)
        fl = free_flight(cfg, fb, s, n_sub, cos1, sin1, ship_index, events, count)
        s = fl.ship
        friction_n, normal_n, peak, guard_j = (fl.friction_n, fl.normal_n, fl.peak_penetration_m,
                                               fl.guard_j)
        if fine:
            s = settle(cfg, sp, s, cos1, sin1, ship_index, events, count)
    else:
        s = pinned(cfg, sp, s, cmd, cos1, sin1, ship_index, events, count)
    s = burn(cfg, sp, s, cmd)
    store(s, rec)
    observe(cfg, terrain, sp, s, cmd, friction_n, normal_n, peak, guard_j, cos1, sin1, out)


@separate
def step_ships(scene, terrain, ships, state, inputs, outputs, cos0, sin0, cos1, sin1, events,
               count):
    """Every ship's tick, one after another: ``state`` is updated in place, ``outputs`` written,
    and the transitions appended to ``events`` (``count[0]`` of them; sim.step.emit)."""
    cfg, ter = scene[0], terrain[0]
    for i in range(state.shape[0]):
        step_ship(cfg, ter, ships[i], state[i], inputs[i], outputs[i], cos0, sin0, cos1, sin1, i,
                  events, count)


@separate
def step_ticks(scene, terrain, ships, state, inputs, commands, next_command, rotations, states_out,
               outputs_out, inputs_out, events, event_ticks, count, first_tick, tick_capacity):
    """Ticks ``first_tick``, ``first_tick + 1``, ... one after another, up to ``len(states_out)``:
    before the step from each tick the commands for it (``commands``, sorted by tick, from index
    ``next_command``) are applied to ``inputs``; after it the state, the telemetry and the commands
    in force are row k of ``states_out``, ``outputs_out`` and ``inputs_out``. Transitions are
    appended to ``events`` (the tick each one led to in ``event_ticks``); the loop stops early
    when fewer than ``tick_capacity`` places are left. ``rotations[k]`` is the body's (cos, sin)
    at the k-th tick's start. Returns (ticks stepped, index of the next command)."""
    c = next_command
    for k in range(states_out.shape[0]):
        if events.shape[0] - count[0] < tick_capacity:
            return k, c
        tick = first_tick + k
        while c < commands.shape[0] and commands[c].tick <= tick:
            cmd = commands[c]
            rec = inputs[cmd.ship]
            rec.throttle = cmd.throttle
            for j in range(3):
                rec.rcs[j] = cmd.rcs[j]
            rec.hold = cmd.hold
            c += 1
        n0 = count[0]
        step_ships(scene, terrain, ships, state, inputs, outputs_out[k], rotations[k, 0],
                   rotations[k, 1], rotations[k + 1, 0], rotations[k + 1, 1], events, count)
        for e in range(n0, min(count[0], events.shape[0])):
            event_ticks[e] = tick + 1
        states_out[k, :] = state
        inputs_out[k, :] = inputs
    return states_out.shape[0], c


def tick_capacity(params: Params) -> int:
    """Transitions a batch can make in a tick: per ship, two in a sub-step (a touchdown already
    past tipped_angle), none after a tip or crash, and landing after that."""
    return int(np.sum(2 * params.ships.n_substeps + 2))


def rotations(params: Params, first_tick: int, n_ticks: int) -> np.ndarray:
    """(cos, sin) of the body's angle at the start of ticks first_tick .. first_tick + n_ticks
    (sim.frames.body_rotation: one libm call per tick, outside the kernels)."""
    om, dt = params.body.omega_radps, params.sim.dt_s
    out = np.empty((n_ticks + 1, 2))
    if om == 0.0:
        out[:, 0], out[:, 1] = 1.0, 0.0
        return out
    for k in range(n_ticks + 1):
        out[k] = body_rotation(om, (first_tick + k) * dt)
    return out


def step(params: Params, state: State, inputs: Inputs) -> tuple[State, Outputs, list[Event]]:
    """Advance the batch by one tick (pure: ``state`` and ``inputs`` are not changed)."""
    n = state.n
    states, outputs, ins = (np.empty((1, n), STATE_DTYPE), np.empty((1, n), OUTPUTS_DTYPE),
                            np.empty((1, n), INPUTS_DTYPE))
    cap = tick_capacity(params)
    events, event_ticks = np.empty(cap, TRANSITION_DTYPE), np.empty(cap, np.int64)
    count = np.zeros(1, np.int64)
    step_ticks(params.scene, params.terrain, params.ships.rows, state.rows.copy(), inputs.rows.copy(),
               NO_COMMANDS, 0, rotations(params, state.tick, 1), states, outputs, ins, events,
               event_ticks, count, state.tick, cap)
    tick = state.tick + 1
    return (State(rows=states[0], tick=tick), Outputs(rows=outputs[0]),
            transitions(events[:count[0]], event_ticks[:count[0]]))


def transitions(events: np.ndarray, ticks: np.ndarray, ship_ids: Sequence[str] = ()
                ) -> list[Event]:
    """The kernel's transitions as Events (by tick, then ship, each ship's in the order they
    happened), each named by its ship's id where ``ship_ids`` (the batch's, in order) are given."""
    out = []
    for e, tick in zip(events.tolist(), ticks.tolist()):
        ship, a, b, v = e
        kind = TRANSITION_EVENTS[(SurfaceState(a), SurfaceState(b))]
        out.append(Event(tick, ship, int(kind), a, b, v, ship_ids[ship] if ship_ids else ""))
    return out


@separate
def observe_ships(scene, terrain, ships, state, outputs, cos_t, sin_t):
    """The telemetry of a batch at rest in its state (no commands, no forces of a step): what a
    log records for the tick a run starts from."""
    cfg, ter = scene[0], terrain[0]
    idle = Commands(0.0, 0.0, (0.0, 0.0, 0.0))
    for i in range(state.shape[0]):
        observe(cfg, ter, ships[i], load(state[i]), idle, 0.0, 0.0, 0.0, 0.0, cos_t, sin_t,
                outputs[i])


def outputs_at(params: Params, state: State) -> Outputs:
    """:func:`observe_ships` of ``state`` at its tick."""
    c, s = body_rotation(params.body.omega_radps, state.tick * params.sim.dt_s)
    out = Outputs.zeros(state.n)
    observe_ships(params.scene, params.terrain, params.ships.rows, state.rows, out.rows, c, s)
    return out
