"""The tick: ``step(params, state, inputs) -> (state, outputs, events)``, a pure function.

Phases, in order (each a function below):

1. ``commands``     throttle and RCS torque actually applied (fuel, hold-mode controller)
2. ``free_flight``  flying and contact ships: integrate, friction at the feet, the passivity
                    guard, and the in-flight transitions (contact, crash, liftoff, tipped) at
                    every sub-step; ships near the ground take ``n_fine_substeps`` sub-steps,
                    ships far above take one and do no contact work
3. ``settle``       contact -> landed once the settle thresholds have held for ``settle_time``
                    with the centre of mass over the footprint
4. ``pinned``       landed, tipped and crashed ships turn with the body; liftoff; tipped ships'
                    pivot model (sim.pivot) and righting
5. ``burn``         fuel and mass
6. ``observe``      the tick's telemetry

A ship's numbers depend only on its own state, inputs and parameters: every operation is elementwise
over the batch (no reductions across ships, no BLAS), so a ship stepped alone or among thousands
gives bit-identical results. Decisions compare cosines and squared speeds, never angles.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from sim import contact, energy, friction, vec
from sim.constants import G0_MPS2
from sim.dynamics import FreeBodies, contact_at
from sim.frames import (body_rotation, body_spin_in_body_frame, effective_gravity, ground_at,
                        inertia, pin_pose, quat_z, rotate_z, surface_velocity)
from sim.enums import TRANSITION_EVENTS, HoldMode, SurfaceState
from sim.integrators import method
from sim.params import Params
from sim.pivot import pinned_motion, pivot_rate_from_momentum, pivot_step
from sim.stability import KICKS
from sim.state import Event, Inputs, Outputs, State

FLYING, CONTACT, LANDED, TIPPED, CRASHED = (int(s) for s in SurfaceState)
_Z = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class Commands:
    throttle: np.ndarray  # (N,)
    thrust_n: np.ndarray  # (N,)
    rcs_torque_body_nm: np.ndarray  # (N, 3)

    def take(self, idx: np.ndarray) -> "Commands":
        return Commands(self.throttle[idx], self.thrust_n[idx], self.rcs_torque_body_nm[idx])


# -- 1. commands ---------------------------------------------------------------------------------
def commands(params: Params, st: State, inputs: Inputs) -> Commands:
    """Applied throttle and RCS torque. The hold-mode controller (flying and contact) is a PD law,
    tau = -I (w_c^2 err + 2 w_c omega_rel), saturated at max_rcs_torque; a non-zero manual RCS
    command on an axis overrides it there. No fuel, or a crashed ship: nothing fires."""
    sh = params.ships
    live = (st.fuel_kg > 0.0) & (st.surface_state != CRASHED)
    throttle = np.where(live, np.clip(inputs.throttle, 0.0, 1.0), 0.0)
    max_tau = sh.max_rcs_torque_nm[:, None]
    manual = np.clip(inputs.rcs, -1.0, 1.0) * max_tau

    controlled = ((inputs.hold != HoldMode.OFF)
                  & ((st.surface_state == FLYING) | (st.surface_state == CONTACT)))
    auto = np.zeros_like(manual)
    ctl = np.flatnonzero(controlled)
    if ctl.size:  # elementwise on the controlled ships only: the same numbers, less work
        bw = params.controller.bandwidth_radps
        q = st.quat[ctl]
        omega_rel = st.omega_body_radps[ctl] - body_spin_in_body_frame(params, q)
        up_b = vec.quat_rotate_inv(q, vec.unit(st.pos_m[ctl]))
        ez_b = np.broadcast_to(_Z, up_b.shape)
        radial = (inputs.hold[ctl] == HoldMode.RADIAL)[:, None]
        err = np.where(radial, vec.cross(ez_b, up_b), 0.0)
        inertia_ctl = sh.inertia0_kgm2[ctl] * (st.mass_kg[ctl] / sh.mass0_kg[ctl])[:, None]
        tau = inertia_ctl * (bw * bw * err - 2.0 * bw * omega_rel)
        auto[ctl] = np.clip(tau, -max_tau[ctl], max_tau[ctl])
    rcs = np.where(manual != 0.0, manual, auto)
    rcs = np.where(live[:, None], rcs, 0.0)
    return Commands(throttle, throttle * sh.max_thrust_n, rcs)


# -- 2. free flight ------------------------------------------------------------------------------
def near_ground(params: Params, st: State, cmd: Commands) -> np.ndarray:
    """True for ships that might touch the ground within this tick (conservative bound)."""
    sh, body, dt = params.ships, params.body, params.sim.dt_s
    ter = body.terrain
    terrain_max = ter.base_height_m + sum(max(h, 0.0) for h in ter.bump_height_m)
    reach_down = sh.com_height_m + sh.leg_radius_m
    clearance = vec.norm(st.pos_m) - body.radius_m - terrain_max - reach_down
    speed = vec.norm(st.vel_mps)
    accel = body.surface_gravity_mps2 + cmd.thrust_n / st.mass_kg
    reach = 2.0 * (speed * dt + accel * dt * dt) + 1.0
    return clearance < reach


#: Squared tilt (rad^2), spin ((rad/s)^2) and slip ((m/s)^2) below which a ship counts as purely
#: vertical. Feet a planet's radius from its centre are placed to ulp(|p|) (2e-10 m on the Moon, 1e-9 m
#: on Earth), which leaves an upright bounce turning at ~1e-10 rad/s: 1e-8 is rounding's level, and
#: what a tilt, spin or slip that small would do over a tick is far below the 1e-7 to which one
#: exact step and sub-steps of the full model agree (tests/test_models.py).
VERTICAL_TOL2 = 1e-16


def purely_vertical(params: Params, st: State, cmd: Commands) -> np.ndarray:
    """Ships whose motion this tick is along the local vertical only: upright, not turning, not
    slipping, no RCS torque, level ground under the whole footprint, a body that does not spin.
    For them every kick of the exponential method is zero, so its one step per tick is already
    exact and sub-steps would only repeat it (``sim.vertical_one_step``)."""
    n = st.n
    if params.body.omega_radps != 0.0:
        return np.zeros(n, dtype=bool)
    r_hat = vec.unit(st.pos_m)
    tilt = vec.cross(vec.quat_axis_z(st.quat), r_hat)
    v_rad = vec.dot(st.vel_mps, r_hat)
    slip = st.vel_mps - vec.scale(r_hat, v_rad)
    w = st.omega_body_radps
    ok = ((vec.dot(tilt, tilt) < VERTICAL_TOL2) & (vec.dot(w, w) < VERTICAL_TOL2)
          & (vec.dot(slip, slip) < VERTICAL_TOL2)
          & (cmd.rcs_torque_body_nm[:, 0] == 0.0) & (cmd.rcs_torque_body_nm[:, 1] == 0.0)
          & (cmd.rcs_torque_body_nm[:, 2] == 0.0))
    ter = params.body.terrain
    # the terrain's coordinates of a point are its body-fixed (y, z): (east, north) at the site
    reach = params.ships.leg_radius_m
    for e0, n0, rad in zip(ter.bump_east_m, ter.bump_north_m, ter.bump_radius_m):
        de = st.pos_m[:, 1] - e0
        dn = st.pos_m[:, 2] - n0
        clear = rad + reach + 1.0
        ok &= de * de + dn * dn > clear * clear
    return ok


def _free_bodies(params: Params, st: State, cmd: Commands, touching: bool, t_tick_s: float
                 ) -> FreeBodies:
    cp = params.contact
    m = st.mass_kg
    k = cp.stiffness_per_kg * m
    two_omega_m = 2.0 * cp.omega_radps * m  # c = 2 zeta sqrt(k m) = 2 zeta omega m
    return FreeBodies(
        mass_kg=m, inertia_kgm2=inertia(params, st), thrust_n=cmd.thrust_n,
        rcs_torque_body_nm=cmd.rcs_torque_body_nm, leg_radius_m=params.ships.leg_radius_m,
        com_height_m=params.ships.com_height_m, k_npm=k, c_nspm=cp.damping_ratio * two_omega_m,
        c_absorb_nspm=cp.absorb_damping_ratio * two_omega_m, gm_m3ps2=params.body.gm_m3ps2,
        body_radius_m=params.body.radius_m, body_omega_radps=params.body.omega_radps,
        params=params, touching=touching, t_tick_s=t_tick_s,
        linear_model=params.sim.integrator in KICKS)


def align_to_surface(q: np.ndarray, r_hat: np.ndarray) -> np.ndarray:
    """Attitude turned by the smallest rotation that takes the body's long axis onto r_hat.

    Half-way quaternion: (1 + ez.r, ez x r) normalised (sqrt only)."""
    ez = vec.quat_axis_z(q)
    rot = np.empty((q.shape[0], 4))
    rot[:, 0] = 1.0 + vec.dot(ez, r_hat)
    rot[:, 1:] = vec.cross(ez, r_hat)
    degenerate = rot[:, 0] <= 0.0  # upside down: no unique smallest rotation; leave as is
    rot = np.where(degenerate[:, None], np.array([1.0, 0.0, 0.0, 0.0]), rot)
    return vec.quat_normalize(vec.quat_mul(vec.quat_normalize(rot), q))


Transition = tuple[int, int, int, float]  # (ship, from state, to state, v_radial m/s)

#: A step that ends (or starts) exactly where the feet reach the ground leaves them within rounding
#: of it (ulp(|p|) ~ 2e-10 m on the Moon): the feet count as clear before that instant and as
#: pressing from it, within this margin, so that all of an upright ship's feet engage together.
ONSET_MARGIN_M = 1e-6


def ship_energy(fb: FreeBodies, ground: contact.Ground, p, v, q, w) -> energy.Energy:
    """sim.energy of free ships at one instant."""
    par = fb.params
    return energy.mechanical(fb.gm_m3ps2, fb.body_radius_m, fb.body_omega_radps,
                             par.contact.stiffness_per_kg, par.ships.leg_radius_m,
                             par.ships.com_height_m, fb.mass_kg, fb.inertia_kgm2, p, v, q, w,
                             ground)


@dataclass(frozen=True)
class EnergyRef:
    """A passive ship's energy at the end of its last sub-step: the total, and its translational
    and rotational parts (conserved each on its own while nothing touches the ship)."""

    total_j: np.ndarray
    translation_j: np.ndarray
    rotation_j: np.ndarray

    @staticmethod
    def of(e: energy.Energy) -> "EnergyRef":
        return EnergyRef(e.total_j, e.translation_j, e.rotation_j)


def passivity_guard(params: Params, fb: FreeBodies, ground: contact.Ground, y, ref: EnergyRef,
                    passive: np.ndarray, airborne: np.ndarray):
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
    it removes is reported as ``energy_guard_j`` (``sim.energy_guard``). Returns the state, the
    new reference, and what was removed (J)."""
    p, v, q, w = y
    e = ship_energy(fb, ground, p, v, q, w)
    whole = passive & ~airborne
    split = passive & airborne
    ex_all = np.where(whole, e.total_j - ref.total_j, 0.0)
    ex_tr = np.where(split, e.translation_j - ref.translation_j, 0.0)
    ex_rot = np.where(split, e.rotation_j - ref.rotation_j, 0.0)
    if not ((ex_all > 0.0).any() or (ex_tr > 0.0).any() or (ex_rot > 0.0).any()):
        return y, EnergyRef.of(e), np.zeros(p.shape[0])

    def factor(excess, kinetic):
        f = np.sqrt(np.maximum(1.0 - excess / np.where(kinetic > 0.0, kinetic, 1.0), 0.0))
        return np.where(excess > 0.0, np.where(kinetic > 0.0, f, 0.0), 1.0)

    kin = e.translational_j + e.rotational_j
    f_all = factor(ex_all, kin)
    f_v = f_all * factor(ex_tr, e.translational_j)
    f_w = f_all * factor(ex_rot, e.rotational_j)
    v_surf = ground.surface_velocity(p)
    spin_b = body_spin_in_body_frame(params, q)
    # only where a correction is due: (v - v_surf) + v_surf is not v in floating point, and a
    # ship's bits must not depend on whether a neighbour needed the guard
    v = np.where((f_v != 1.0)[:, None], v_surf + (v - v_surf) * f_v[:, None], v)
    w = np.where((f_w != 1.0)[:, None], spin_b + (w - spin_b) * f_w[:, None], w)
    taken_tr = e.translational_j * (1.0 - f_v * f_v)
    taken_rot = e.rotational_j * (1.0 - f_w * f_w)
    removed = taken_tr + taken_rot
    new = EnergyRef(e.total_j - removed, e.translation_j - taken_tr, e.rotation_j - taken_rot)
    return (p, v, q, w), new, removed


def free_flight(params: Params, st: State, cmd: Commands, n_sub: int, touching: bool,
                t0_s: float) -> tuple[State, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                      list[Transition]]:
    """Advance free ships (a sub-batch) by one tick in ``n_sub`` equal sub-steps.

    Returns the new sub-batch, the last sub-step's friction force (N: the sum of the feet's), the
    normal force at the end (N), the deepest penetration of any sub-step (m), the energy the
    passivity guard removed (J), and the transitions as (local ship index, from, to, v_radial)
    in the order they happened."""
    cp, dt, sh = params.contact, params.sim.dt_s, params.ships
    h = dt / n_sub
    fb = _free_bodies(params, st, cmd, touching, t0_s)
    advance = method(params.sim.integrator)
    n = st.n
    p, v, q, w = st.pos_m, st.vel_mps, st.quat, st.omega_body_radps
    surf = st.surface_state.copy()
    absorbing = st.absorbing.copy()
    sliding = st.sliding.copy()
    settle = st.settle_ticks.copy()
    pin_p, pin_q, pin_pivot = st.pin_pos_bf_m.copy(), st.pin_quat_bf.copy(), st.pin_pivot_bf_m.copy()
    pivot_rate = st.pivot_rate_radps.copy()
    friction_n = np.zeros(n)
    active = np.ones(n, dtype=bool)
    transitions: list[Transition] = []
    peak = np.zeros(n)
    ce = contact_at(fb, fb.ground_at(0.0), p, v, q, w, absorbing)
    v_rad = vec.dot(v, vec.unit(p))
    guard = params.sim.energy_guard
    passive = ((cmd.thrust_n == 0.0) & (cmd.rcs_torque_body_nm[:, 0] == 0.0)
               & (cmd.rcs_torque_body_nm[:, 1] == 0.0) & (cmd.rcs_torque_body_nm[:, 2] == 0.0))
    guard_j = np.zeros(n)
    if guard:
        e_ref = EnergyRef.of(ship_energy(fb, fb.ground_at(0.0), p, v, q, w))

    def substep(h_step, y, ce_start, sliding_start, t_start, bodies=fb):
        """One integrator step plus the friction impulses; returns (y, sliding, friction N, the
        method's own peak penetration inside the step or None)."""
        res = advance(bodies, h_step, y, ce_start, absorbing, t_start)
        pressed = (((res.foot_impulse_ns[0] != 0.0) | (res.foot_impulse_ns[1] != 0.0))
                   | (res.foot_impulse_ns[2] != 0.0)) | (res.foot_impulse_ns[3] != 0.0)
        if not touching:
            return res.y, sliding_start, np.zeros(n), res.peak_penetration_m, pressed
        p1, v1, q1, w1 = res.y
        if not pressed.any():  # no foot pressed: no friction (nor any foot's regime) to keep
            return res.y, np.zeros_like(sliding_start), np.zeros(n), res.peak_penetration_m, pressed
        ground_end = fb.ground_at(t_start + h_step)
        if cp.friction_model == "seed":
            j_n = sum(res.foot_impulse_ns[1:], res.foot_impulse_ns[0])
            v2, sl, j_f = friction.seed(cp.friction_static, cp.friction_kinetic, fb.mass_kg, p1,
                                        v1, j_n, sliding_start, ground_end)
            return (p1, v2, q1, w1), sl, j_f / h_step, res.peak_penetration_m, pressed
        ft = contact.feet(p1, q1, sh.leg_radius_m, sh.com_height_m, ground_end)
        v2, w2, sl, j_f = friction.coulomb(cp.friction_static, cp.friction_kinetic, fb.mass_kg,
                                           fb.inertia_kgm2, p1, v1, q1, w1, ft,
                                           res.foot_impulse_ns, sliding_start, ground_end)
        p2, q2 = friction.spread_over_step(p1, q1, v1, v2, w1, w2, h_step)
        held = ~(sliding_start.any(axis=1) | sl.any(axis=1)) & (j_f > 0.0)
        if held.any():
            c_turn, s_turn = fb.ground_turn(h_step)
            ft2 = contact.feet(p2, q2, sh.leg_radius_m, sh.com_height_m, ground_end)
            p2 = friction.hold_footprint(p2, ce_start.feet, ft2, res.foot_impulse_ns, held,
                                         c_turn, s_turn)
        return (p2, v2, q2, w2), sl, j_f / h_step, res.peak_penetration_m, pressed

    for j in range(n_sub):
        t_off = j * h  # this sub-step's start, from the tick's start
        pen_before, v_rad_before = ce.max_penetration_m, v_rad
        h_first: float | np.ndarray = h
        crossing = np.zeros(n, dtype=bool)
        v_cross = np.zeros(n)
        tau = np.zeros(n)
        if touching:
            # Contact onset inside the sub-step: the damper's force jumps to c v at the surface,
            # so step exactly to the crossing (ballistic time of flight of the lowest foot,
            # tau = 2 z / (v + sqrt(v^2 + 2 a z))) and from there to the sub-step's end.
            z = -pen_before
            v_down = -v_rad
            a_dn = fb.gm_m3ps2 / vec.dot(p, p) - fb.thrust_n * vec.dot(
                vec.quat_axis_z(q), vec.unit(p)) / fb.mass_kg
            disc = v_down * v_down + 2.0 * a_dn * np.where(z > 0.0, z, 0.0)
            denom = v_down + np.sqrt(np.maximum(disc, 0.0))
            tau = 2.0 * z / np.where(denom > 0.0, denom, 1.0)
            crossing = (active & (surf == FLYING) & (z > 0.0) & (v_down > 0.0) & (disc >= 0.0)
                        & (denom > 0.0) & (tau < h))
            h_first = np.where(crossing, tau, h)
            v_cross = np.sqrt(np.maximum(disc, 0.0))  # speed of the lowest foot at the surface
        # Up to the crossing the motion is ballistic by construction. Its last stage ends with
        # the feet at the surface to within rounding, where some feet would press (with the
        # damper's full jump c v) and others not: a spurious torque. They must not press there.
        first = replace(fb, engage_m=np.where(crossing, -ONSET_MARGIN_M, 0.0)) if crossing.any() else fb
        y1, sliding1, fr, inner_peak, touched = substep(h_first, (p, v, q, w), ce, sliding, t_off,
                                                        first)
        aligned = np.zeros(n, dtype=bool)
        if crossing.any():
            # At the crossing itself: an impact slower than bounce_speed is taken by the
            # absorbers from its first instant, and the seed's touchdown alignment happens here
            absorbing = np.where(crossing, v_cross < cp.bounce_speed_mps, absorbing)
            t_cross = t_off + np.where(crossing, tau, h)
            ground_x = fb.ground_at(t_cross)
            if cp.align_on_touchdown:
                y1, aligned = _align_at_touchdown(params, fb, ground_x, y1, crossing)
            ce_mid = contact_at(fb, ground_x, *y1, absorbing, np.where(crossing, ONSET_MARGIN_M, 0.0))
            y2, sliding2, fr2, peak2, touched2 = substep(np.where(crossing, h - tau, h), y1,
                                                         ce_mid, sliding1, t_cross)
            touched = touched | (crossing & touched2)
            c3 = crossing[:, None]
            y1 = tuple(np.where(c3, b, a) for a, b in zip(y1, y2))
            sliding1 = np.where(c3, sliding2, sliding1)
            fr = np.where(crossing, fr2, fr)
            if inner_peak is not None:
                inner_peak = np.where(crossing, np.maximum(inner_peak, peak2), inner_peak)
        sliding = np.where(active[:, None], sliding1, sliding)
        keep = active[:, None]
        p, v, q, w = (np.where(keep, a1, a0) for a1, a0 in zip(y1, (p, v, q, w)))
        friction_n = np.where(active, fr, friction_n)
        t_end_off = (j + 1) * h
        ground = fb.ground_at(t_end_off)
        ce = contact_at(fb, ground, p, v, q, w, absorbing)
        if guard:
            # airborne: clear of the ground at both ends and nothing pressed between (a bilateral
            # absorber's pull passes no positive impulse, yet trades translation for rotation)
            airborne = ~touched & (pen_before < 0.0) & (ce.max_penetration_m < 0.0)
            (p, v, q, w), e_ref, took = passivity_guard(params, fb, ground, (p, v, q, w), e_ref,
                                                        passive & active, airborne)
            guard_j = guard_j + took
            if (took > 0.0).any():  # the dampers' forces follow the velocities it scaled
                ce = contact_at(fb, ground, p, v, q, w, absorbing)

        # in-flight transitions, decided on this sub-step's end state
        r_hat = vec.unit(p)
        v_rad = vec.dot(v, r_hat)
        pen = ce.max_penetration_m
        if touching:
            if inner_peak is None:  # interpolate between the sub-step's ends
                step_peak = _hermite_peak(pen_before, -v_rad_before, pen, -v_rad, h)
            else:  # the method located it
                step_peak = np.maximum(np.maximum(pen_before, pen), inner_peak)
            peak = np.where(active, np.maximum(peak, step_peak), peak)
        was = surf.copy()
        # a located crossing is a touchdown even if the ship is already rebounding at the end
        touch = active & (was == FLYING) & (((pen > 0.0) & (v_rad < 0.0)) | crossing)
        # Speeds at the surface crossing, from the ballistic motion on the clear side of it (the
        # damper acts from the first millimetre, so the sub-step's end speed is already lower):
        # v_cross^2 = v^2 + 2 a_down height, a_down = g - T cos(tilt) / m.
        a_down = fb.gm_m3ps2 / vec.dot(p, p) - fb.thrust_n * vec.dot(
            vec.quat_axis_z(q), r_hat) / fb.mass_kg
        above_before = np.maximum(-pen_before, 0.0)
        impact = np.where(v_rad_before < 0.0, np.sqrt(np.maximum(
            v_rad_before * v_rad_before + 2.0 * a_down * above_before, 0.0)), -v_rad)
        impact = np.where(crossing, v_cross, impact)
        separation = np.sqrt(np.maximum(v_rad * v_rad + 2.0 * a_down * np.maximum(-pen, 0.0), 0.0))
        # in contact: descending faster than crash_speed at either end of the sub-step (the
        # damper may already have slowed it by the end)
        crash = (touch & (impact > cp.crash_speed_mps)) | (
            active & (was == CONTACT) & (np.minimum(v_rad, v_rad_before) < -cp.crash_speed_mps))
        touch_ok = touch & ~crash
        if touch_ok.any():
            absorbing = np.where(touch_ok, impact < cp.bounce_speed_mps, absorbing)
            sliding = np.where(touch_ok[:, None], False, sliding)
            settle = np.where(touch_ok, 0, settle)
            snap = touch_ok & ~crossing  # a located crossing was aligned there
            if cp.align_on_touchdown and snap.any():
                (p, v, q, w), snapped = _align_at_touchdown(params, fb, ground, (p, v, q, w), snap)
                aligned |= snapped
                ce = contact_at(fb, ground, p, v, q, w, absorbing)
                if guard:  # the snap never adds energy; measure from where it left the ship
                    now = EnergyRef.of(ship_energy(fb, ground, p, v, q, w))
                    e_ref = EnergyRef(*(np.where(snapped, a_, b_) for a_, b_ in zip(
                        (now.total_j, now.translation_j, now.rotation_j),
                        (e_ref.total_j, e_ref.translation_j, e_ref.rotation_j))))
        cos_tilt = vec.dot(vec.quat_axis_z(q), r_hat)
        # all feet clear and moving away: a bounce or a thrust-off (the align of a touchdown can
        # lift a foot clear while the ship still descends; that is not a liftoff)
        lift = active & (was == CONTACT) & ~crash & (ce.max_penetration_m < 0.0) & (v_rad > 0.0)
        # past tipped_angle in contact; a touchdown already past it that was not stood up by the
        # alignment lies down at once (its hull, which the model does not have, is what touches)
        lying_down = touch & ~aligned
        tip = (active & (((was == CONTACT) & ~lift) | lying_down) & ~crash
               & (cos_tilt < cp.cos_tipped))
        v_rel = v - surface_velocity(params, p)
        tip_crash = tip & (vec.dot(v_rel, v_rel) > cp.crash_speed_mps ** 2)
        crash = crash | tip_crash
        tip = tip & ~tip_crash

        c, s = body_rotation(params, t0_s + t_end_off)
        if tip.any():
            pp, pq = pin_pose(p, q, c, s)
            pin_p = np.where(tip[:, None], pp, pin_p)
            pin_q = np.where(tip[:, None], pq, pin_q)
            pin_pivot = np.where(tip[:, None], rotate_z(ce.lowest_foot_w, c, -s), pin_pivot)
            rate = pivot_rate_from_momentum(params, fb.mass_kg, fb.inertia_kgm2, p, v, q, w,
                                            ce.lowest_foot_w)
            pivot_rate = np.where(tip, rate, pivot_rate)
        if crash.any():
            pp, pq = pin_pose(p, q, c, s)
            pin_p = np.where(crash[:, None], pp, pin_p)
            pin_q = np.where(crash[:, None], pq, pin_q)
        surf = np.where(touch_ok, CONTACT, surf)
        surf = np.where(lift, FLYING, surf)
        surf = np.where(tip, TIPPED, surf)
        surf = np.where(crash, CRASHED, surf)
        changed = surf != was
        touched_and_tipped = touch_ok & tip
        for i in np.flatnonzero(touched_and_tipped):  # two transitions in one sub-step
            transitions.append((int(i), FLYING, CONTACT, float(-impact[i])))
            was[i] = CONTACT
        for i in np.flatnonzero(changed):
            if was[i] == FLYING:
                speed = -impact[i]
            elif surf[i] == FLYING:
                speed = separation[i]
            else:
                speed = v_rad[i]
            transitions.append((int(i), int(was[i]), int(surf[i]), float(speed)))
        active = active & ~tip & ~crash
    crashed = surf == CRASHED
    tipped = surf == TIPPED
    if crashed.any() or tipped.any():
        # pinned during the tick: carried with the body to the tick's end, moving as pinned
        c, s = body_rotation(params, t0_s + dt)
        held = (crashed | tipped)[:, None]
        p = np.where(held, rotate_z(pin_p, c, s), p)
        q = np.where(held, vec.quat_mul(quat_z(c, s, n), pin_q), q)
        v_pin, w_pin = pinned_motion(params, p, q, rotate_z(pin_pivot, c, s),
                                     np.where(tipped, pivot_rate, 0.0))
        v = np.where(held, v_pin, v)
        w = np.where(held, w_pin, w)
    out = replace(st, surface_state=surf.astype(np.int8), pos_m=p, vel_mps=v, quat=q,
                  omega_body_radps=w, absorbing=absorbing, sliding=sliding, settle_ticks=settle,
                  pivot_rate_radps=pivot_rate, pin_pos_bf_m=pin_p, pin_quat_bf=pin_q,
                  pin_pivot_bf_m=pin_pivot)
    return out, friction_n, np.abs(ce.normal_n), peak, guard_j, transitions


def _align_at_touchdown(params: Params, fb: FreeBodies, ground: contact.Ground, y,
                        mask: np.ndarray):
    """The seed's Flying -> Contact rule for the ships in ``mask``: attitude snapped to local up
    and rotation stopped (relative to the surface); then the ship moves out along local up so
    that its deepest foot is no deeper than before the snap: turning must not bury the feet
    (MODEL-NOTES 11). The snap must not make energy either (MODEL-NOTES 24): a ship that it would
    raise (tilted past 2 atan(a / h), 74 degrees for the default lander) pays for the lift out of
    its descent speed; a ship too slow to pay is not stood up and touches down as it is.
    Returns the new state and the ships actually aligned."""
    p, v, q, w = y
    sh, cp = params.ships, params.contact
    r_hat = vec.unit(p)
    q1 = np.where(mask[:, None], align_to_surface(q, r_hat), q)
    w1 = np.where(mask[:, None], body_spin_in_body_frame(params, q1), w)
    pen0 = contact.lowest_foot_penetration(p, q, sh.leg_radius_m, sh.com_height_m, ground)
    pen1 = contact.lowest_foot_penetration(p, q1, sh.leg_radius_m, sh.com_height_m, ground)
    p1 = p + vec.scale(r_hat, np.where(mask, np.maximum(pen1 - pen0, 0.0), 0.0))

    def energy_of(pp, qq, ww):
        return energy.mechanical(
            fb.gm_m3ps2, fb.body_radius_m, fb.body_omega_radps, cp.stiffness_per_kg,
            sh.leg_radius_m, sh.com_height_m, fb.mass_kg, fb.inertia_kgm2, pp, v, qq, ww,
            ground).total_j

    cost = energy_of(p1, q1, w1) - energy_of(p, q, w)
    v_rad = vec.dot(v - ground.surface_velocity(p), r_hat)
    spare = v_rad * v_rad - 2.0 * cost / fb.mass_kg
    pays = (cost > 0.0) & (v_rad < 0.0) & (spare >= 0.0)
    aligned = mask & ((cost <= 0.0) | pays)
    v1 = v + vec.scale(r_hat, np.where(aligned & pays, -np.sqrt(np.maximum(spare, 0.0)) - v_rad,
                                       0.0))
    a3 = aligned[:, None]
    return (np.where(a3, p1, p), np.where(a3, v1, v), np.where(a3, q1, q),
            np.where(a3, w1, w)), aligned


def _hermite_peak(x0, xd0, x1, xd1, h: float) -> np.ndarray:
    """Largest value over a sub-step of the cubic Hermite interpolant through (x0, x0') and
    (x1, x1'): the deepest penetration between sub-step ends, to O(h^4). Telemetry only."""
    a = 6.0 * (x0 - x1) + 3.0 * h * (xd0 + xd1)
    b = 6.0 * (x1 - x0) - h * (4.0 * xd0 + 2.0 * xd1)
    c = h * xd0
    best = np.maximum(x0, x1)
    disc = b * b - 4.0 * a * c
    root = np.sqrt(np.maximum(disc, 0.0))
    safe_a = np.where(a != 0.0, a, 1.0)
    for sgn in (-1.0, 1.0):
        s = np.where(a != 0.0, (-b + sgn * root) / (2.0 * safe_a),
                     np.where(b != 0.0, -c / np.where(b != 0.0, b, 1.0), 0.0))
        ok = (disc >= 0.0) & (s > 0.0) & (s < 1.0) & np.isfinite(x0) & np.isfinite(x1)
        s2, s3 = s * s, s * s * s
        xs = ((2 * s3 - 3 * s2 + 1) * x0 + (s3 - 2 * s2 + s) * h * xd0
              + (-2 * s3 + 3 * s2) * x1 + (s3 - s2) * h * xd1)
        best = np.where(ok, np.maximum(best, xs), best)
    return best


# -- 3. settle -----------------------------------------------------------------------------------
def over_footprint(params: Params, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The centre of mass is over the footprint: the line through it along the effective gravity
    meets the feet's plane inside the square the four feet span. With u the effective "up" in the
    body frame, the line meets the plane at -h (u_x, u_y) / u_z, inside |x| + |y| < a when

        h (|u_x| + |u_y|) < a u_z,

    an exact comparison (toward a foot: tilt < atan(a / h), 37 degrees for the default lander;
    toward the edge between two: atan(a / (sqrt(2) h)), 28 degrees). With leg_radius = 0 nothing is
    over the footprint: the seed's inverted pendulum, which no tilt makes stable."""
    u = vec.quat_rotate_inv(q, -effective_gravity(params, p))
    sh = params.ships
    return sh.com_height_m * (np.abs(u[:, 0]) + np.abs(u[:, 1])) < sh.leg_radius_m * u[:, 2]


def settle(params: Params, st: State, t_end_s: float) -> tuple[State, np.ndarray]:
    """Contact -> landed once tilt, angular and linear speeds have stayed under their thresholds
    for ``settle_time`` (SEED-NOTES 3: the bottom of a bounce, where v_radial = 0, never lands),
    with the centre of mass over the footprint (the seed's "ship stable"; MODEL-NOTES 26).
    Returns the new state and the mask of ships that landed."""
    cp = params.contact
    in_contact = st.surface_state == CONTACT
    r_hat = vec.unit(st.pos_m)
    v_rel = st.vel_mps - surface_velocity(params, st.pos_m)
    v_rad = vec.dot(v_rel, r_hat)
    v_tan = v_rel - vec.scale(r_hat, v_rad)
    omega_rel = st.omega_body_radps - body_spin_in_body_frame(params, st.quat)
    ez = vec.quat_axis_z(st.quat)
    lin2 = cp.settle_linear_vel_mps ** 2
    ok = (in_contact & (v_rad * v_rad < lin2) & (vec.dot(v_tan, v_tan) < lin2)
          & (vec.dot(omega_rel, omega_rel) < cp.settle_angular_vel_radps ** 2)
          & (vec.dot(ez, r_hat) > cp.cos_settle_tilt))
    ok &= over_footprint(params, st.pos_m, st.quat)
    ticks = np.where(ok, st.settle_ticks + 1, 0)
    # samples at n consecutive tick ends span (n - 1) dt: landing needs them to span settle_time
    # (settle_time = 0, the seed's instantaneous rule: the first tick the thresholds hold)
    need = int(math.ceil(cp.settle_time_s / params.sim.dt_s - 1e-9))
    landed = ok & (ticks > need)
    if not landed.any():
        return replace(st, settle_ticks=ticks), landed
    c, s = body_rotation(params, t_end_s)
    pp, pq = pin_pose(st.pos_m, st.quat, c, s)
    m3 = landed[:, None]
    return replace(
        st, settle_ticks=np.where(landed, 0, ticks),
        surface_state=np.where(landed, LANDED, st.surface_state).astype(np.int8),
        vel_mps=np.where(m3, surface_velocity(params, st.pos_m), st.vel_mps),
        omega_body_radps=np.where(m3, body_spin_in_body_frame(params, st.quat),
                                  st.omega_body_radps),
        pin_pos_bf_m=np.where(m3, pp, st.pin_pos_bf_m), pin_quat_bf=np.where(m3, pq, st.pin_quat_bf),
    ), landed


# -- 4. pinned -----------------------------------------------------------------------------------
def pinned(params: Params, st: State, cmd: Commands, t_end_s: float
           ) -> tuple[State, list[Transition]]:
    """Landed, tipped and crashed ships (all of ``st``): body-fixed poses mapped to the inertial
    frame at the tick's end; liftoff when the engine's push along local up beats the weight in
    the effective gravity (MODEL-NOTES 25); tipped ships turn about their pivot foot
    (:func:`pivot_step`), righted (back to contact) when tilt < tipped_angle while turning
    upright. Velocities are those of the pinned motion (a tipped ship's turn included)."""
    n = st.n
    surf = st.surface_state.copy()
    p_bf, q_bf, pivot = st.pin_pos_bf_m, st.pin_quat_bf, st.pin_pivot_bf_m
    rate = st.pivot_rate_radps.copy()
    m = st.mass_kg
    transitions: list[Transition] = []

    tipped = surf == TIPPED
    righted = np.zeros(n, dtype=bool)
    if tipped.any():  # the pivot model on the tipped ships alone (an upright one has no axis)
        idx = np.flatnonzero(tipped)
        ps = pivot_step(params.take(idx), st.take(idx), cmd.rcs_torque_body_nm[idx])
        p_bf, q_bf = p_bf.copy(), q_bf.copy()
        p_bf[idx], q_bf[idx], rate[idx] = ps.pos_bf_m, ps.quat_bf, ps.rate_radps
        righted[idx] = ps.righted
        surf[idx] = np.where(ps.hull_crash, CRASHED, np.where(ps.righted, CONTACT, surf[idx]))

    up = vec.unit(p_bf)
    ez = vec.quat_axis_z(q_bf)
    weight = -m * vec.dot(effective_gravity(params, p_bf), up)
    liftable = (surf == LANDED) | (surf == TIPPED)
    lift = liftable & (cmd.thrust_n * vec.dot(ez, up) > weight)
    surf = np.where(lift, FLYING, surf)

    if params.body.omega_radps == 0.0:  # the body-fixed frame is the inertial one
        c, s = 1.0, 0.0
        p, q = p_bf, q_bf
    else:
        c, s = body_rotation(params, t_end_s)
        p = rotate_z(p_bf, c, s)
        q = vec.quat_mul(quat_z(c, s, n), q_bf)
    turning = (surf == TIPPED) | righted
    v, w = pinned_motion(params, p, q, rotate_z(pivot, c, s), np.where(turning, rate, 0.0))
    v_rad = vec.dot(v - surface_velocity(params, p), vec.unit(p))
    for i in np.flatnonzero(surf != st.surface_state):
        transitions.append((int(i), int(st.surface_state[i]), int(surf[i]), float(v_rad[i])))
    freed = righted | lift
    out = replace(
        st, surface_state=surf.astype(np.int8), pos_m=p, vel_mps=v, quat=q, omega_body_radps=w,
        pivot_rate_radps=np.where(freed | (surf == CRASHED), 0.0, rate), pin_pos_bf_m=p_bf,
        pin_quat_bf=q_bf, absorbing=np.where(freed, True, st.absorbing),
        sliding=np.where(freed[:, None], False, st.sliding),
        settle_ticks=np.where(freed, 0, st.settle_ticks))
    return out, transitions


# -- 5. burn -------------------------------------------------------------------------------------
def burn(params: Params, st: State, cmd: Commands) -> State:
    """Fuel used this tick: T / (Isp g0) for the engine, sum|tau| / (arm Isp_rcs g0) for the RCS."""
    sh = params.ships
    rcs_thrust = (np.abs(cmd.rcs_torque_body_nm[:, 0]) + np.abs(cmd.rcs_torque_body_nm[:, 1])
                  + np.abs(cmd.rcs_torque_body_nm[:, 2])) / sh.rcs_arm_m
    flow = cmd.thrust_n / (sh.isp_s * G0_MPS2) + rcs_thrust / (sh.rcs_isp_s * G0_MPS2)
    used = np.minimum(flow * params.sim.dt_s, st.fuel_kg)
    return replace(st, fuel_kg=st.fuel_kg - used, mass_kg=st.mass_kg - used)


# -- 6. observe ----------------------------------------------------------------------------------
def observe(params: Params, st: State, cmd: Commands, friction_n: np.ndarray,
            normal_n: np.ndarray, peak_pen_m: np.ndarray, t_s: float,
            energy_guard_j: np.ndarray | None = None) -> Outputs:
    """Telemetry at the end of the tick. Forces come from the free-flight phase (free ships) or
    are the weight (landed, tipped); only the feet's geometry is computed here."""
    pen = contact.lowest_foot_penetration(st.pos_m, st.quat, params.ships.leg_radius_m,
                                          params.ships.com_height_m, ground_at(params, t_s))
    r_hat = vec.unit(st.pos_m)
    v_rel = st.vel_mps - surface_velocity(params, st.pos_m)
    v_rad = vec.dot(v_rel, r_hat)
    v_tan = vec.norm(v_rel - vec.scale(r_hat, v_rad))
    surf = st.surface_state
    weight = -st.mass_kg * vec.dot(effective_gravity(params, st.pos_m), r_hat)
    held = (surf == LANDED) | (surf == TIPPED)
    normal = np.where(held, weight, np.where(surf == CRASHED, 0.0, normal_n))
    return Outputs(
        altitude_m=-pen, penetration_m=np.maximum(pen, 0.0),
        peak_penetration_m=np.maximum(peak_pen_m, pen).clip(0.0),
        cos_tilt=vec.dot(vec.quat_axis_z(st.quat), r_hat), v_radial_mps=v_rad,
        v_tangential_mps=v_tan, normal_force_n=normal,
        friction_force_n=np.where(held, 0.0, friction_n),
        throttle=cmd.throttle, rcs_torque_body_nm=cmd.rcs_torque_body_nm,
        energy_guard_j=np.zeros(st.n) if energy_guard_j is None else energy_guard_j)


# -- the step ------------------------------------------------------------------------------------
def step(params: Params, state: State, inputs: Inputs) -> tuple[State, Outputs, list[Event]]:
    """Advance the batch by one tick: the phases above, in order. Each phase works on the ships
    it concerns only (index groups), so idle ships cost little."""
    dt = params.sim.dt_s
    t0 = state.tick * dt
    t1 = (state.tick + 1) * dt
    n = state.n
    cmd = commands(params, state, inputs)
    surf0 = state.surface_state
    free = (surf0 == FLYING) | (surf0 == CONTACT)
    fine = free & ((surf0 == CONTACT) | near_ground(params, state, cmd))
    one_step = np.zeros(n, dtype=bool)
    if params.sim.vertical_one_step and params.sim.integrator in KICKS and fine.any():
        one_step = fine & purely_vertical(params, state, cmd)
    friction_n = np.zeros(n)
    normal_n = np.zeros(n)
    peak_pen = np.zeros(n)
    guard_j = np.zeros(n)
    found: list[tuple[int, int, int, int, float]] = []  # (ship, order, from, to, v_radial)
    parts: list[tuple[np.ndarray, State]] = []
    groups = ((np.flatnonzero(fine & ~one_step), params.sim.n_fine_substeps, True),
              (np.flatnonzero(one_step), 1, True),
              (np.flatnonzero(free & ~fine), 1, False))
    for idx, n_sub, touching in groups:
        if idx.size == 0:
            continue
        sub_params = params.take(idx)
        part, fr, nf, peak, took, trans = free_flight(sub_params, state.take(idx), cmd.take(idx),
                                                      n_sub, touching, t0)
        if touching:
            part, landed = settle(sub_params, part, t1)
            trans = trans + [(int(i), CONTACT, LANDED, 0.0) for i in np.flatnonzero(landed)]
        parts.append((idx, part))
        friction_n[idx] = fr
        normal_n[idx] = nf
        peak_pen[idx] = peak
        guard_j[idx] = took
        found += [(int(idx[i]), k, a, b, vr) for k, (i, a, b, vr) in enumerate(trans)]
    held = np.flatnonzero(~free)
    if held.size:
        part, trans = pinned(params.take(held), state.take(held), cmd.take(held), t1)
        parts.append((held, part))
        found += [(int(held[i]), k, a, b, vr) for k, (i, a, b, vr) in enumerate(trans)]
    st = state.put(parts)
    st = burn(params, st, cmd)
    st = replace(st, tick=state.tick + 1)
    out = observe(params, st, cmd, friction_n, normal_n, peak_pen, t1, guard_j)
    found.sort(key=lambda e: (e[0], e[1]))
    events = [Event(st.tick, ship, int(TRANSITION_EVENTS[(SurfaceState(a), SurfaceState(b))]), a, b,
                    vr) for ship, _, a, b, vr in found]
    return st, out, events
