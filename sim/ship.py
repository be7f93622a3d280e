"""One ship as the step holds it: its record loaded (:class:`Ship`: surface state, motion, mass,
fuel, :class:`Footing`, :class:`Pin`) and stored back, the commands actually applied
(:class:`Commands`), what a tick reports (:class:`Report`), and the transitions' log
(:class:`EventLog`, :func:`emit`). Shared by every phase (sim.phases, sim.flight, sim.rest)."""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from touchdown.sim.compiled import constructor, kernel
from touchdown.sim.contact import Ground
from touchdown.sim.dynamics import Motion
from touchdown.sim.enums import HoldMode, SurfaceState
from touchdown.sim.settings import LandedModel, SurfaceNormal, TippedModel
from touchdown.sim.state import COMMAND_DTYPE


#: as numpy integers: numba types a Python int global as a literal, and would compile a kernel
#: taking states (emit) once per pair of them
FLYING, CONTACT, LANDED, TIPPED, CRASHED = (np.int64(s) for s in SurfaceState)


HOLD_OFF, HOLD_RADIAL = int(HoldMode.OFF), int(HoldMode.RADIAL)


RADIAL_NORMAL = int(SurfaceNormal.RADIAL)


REST_LANDED = int(LandedModel.REST)


FULL_TIPPED = int(TippedModel.FULL)


#: no foot holds (sim.friction.coulomb's carried friction)
NO_HOLD = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))


#: every foot presses from the ground down (sim.contact.evaluate's engage_m)
ENGAGE_AT_GROUND = (0.0, 0.0, 0.0, 0.0)


#: an empty list of commands (sim.state.COMMAND_DTYPE)
NO_COMMANDS = np.zeros(0, COMMAND_DTYPE)


class Footing(NamedTuple):
    """What a ship's contact with the ground carries from step to step."""

    absorbing: bool  # the contact began slower than bounce_speed (SEED-NOTES 1)
    sliding: tuple  # each foot's friction regime
    settle_ticks: int
    settle_for_s: float  # how long the settle thresholds have held (sim.fields)
    settle_margin: float
    hold_w: tuple  # each holding foot's static friction over the last step (sim.fields)


class Pin(NamedTuple):
    """A landed, tipped or crashed ship's pose in the body-fixed frame, and a tipped ship's turn."""

    pos_bf_m: tuple
    quat_bf: tuple
    pivot_bf_m: tuple  # tipped only: the pivot (lowest foot)
    rate_radps: float  # tipped only: rate of turn about the pivot (+ = toppling)


class Ship(NamedTuple):
    """One ship's state inside the kernels (sim.state.STATE_DTYPE, as numbers and tuples, in
    groups: a phase that changes one group passes the others on)."""

    surface_state: int
    motion: Motion
    mass_kg: float
    fuel_kg: float
    footing: Footing
    pin: Pin


#: no foot slides (each foot's regime)
NO_SLIP = (False, False, False, False)


@kernel
def fresh_footing(absorbing):
    """A contact's footing as it begins (a touchdown, a righting) or ends (a liftoff): no foot
    sliding or holding, the settle thresholds not yet held."""
    return Footing(absorbing, NO_SLIP, 0, 0.0, -1.0, NO_HOLD)


@kernel
def with_motion(s, surface_state, motion):
    """``s`` in ``surface_state`` with ``motion``, its other groups passed on."""
    return Ship(surface_state, motion, s.mass_kg, s.fuel_kg, s.footing, s.pin)


# A phase changes a Ship through these, one group each (the others passed on): none spells out a
# whole Ship but :func:`load`.
@kernel
def with_state(s, surface_state):
    """``s`` in ``surface_state``."""
    return Ship(surface_state, s.motion, s.mass_kg, s.fuel_kg, s.footing, s.pin)


@kernel
def with_footing(s, footing):
    """``s`` with ``footing``."""
    return Ship(s.surface_state, s.motion, s.mass_kg, s.fuel_kg, footing, s.pin)


@kernel
def with_pin(s, pin):
    """``s`` with ``pin``."""
    return Ship(s.surface_state, s.motion, s.mass_kg, s.fuel_kg, s.footing, pin)


@kernel
def with_mass(s, mass_kg, fuel_kg):
    """``s`` with its mass and the fuel in it."""
    return Ship(s.surface_state, s.motion, mass_kg, fuel_kg, s.footing, s.pin)


@kernel
def with_friction(ft, sliding, hold_w):
    """The footing ``ft`` with each foot's friction regime and the holding feet's friction."""
    return Footing(ft.absorbing, sliding, ft.settle_ticks, ft.settle_for_s, ft.settle_margin,
                   hold_w)


@kernel
def with_settle(ft, settle_ticks, settle_for_s, settle_margin):
    """The footing ``ft`` with the settle thresholds' run (sim.fields)."""
    return Footing(ft.absorbing, ft.sliding, settle_ticks, settle_for_s, settle_margin,
                   ft.hold_w)


@kernel
def load(rec):
    """A ship's record as a :class:`Ship` (the one place a record is read)."""
    motion = Motion((rec.pos_m[0], rec.pos_m[1], rec.pos_m[2]),
                    (rec.vel_mps[0], rec.vel_mps[1], rec.vel_mps[2]),
                    (rec.quat[0], rec.quat[1], rec.quat[2], rec.quat[3]),
                    (rec.omega_body_radps[0], rec.omega_body_radps[1], rec.omega_body_radps[2]))
    hf = rec.hold_force_n
    footing = Footing(bool(rec.absorbing),
                      (rec.sliding[0] != 0, rec.sliding[1] != 0, rec.sliding[2] != 0,
                       rec.sliding[3] != 0),
                      np.int64(rec.settle_ticks), rec.settle_for_s, rec.settle_margin,
                      ((hf[0], hf[1], hf[2]), (hf[3], hf[4], hf[5]), (hf[6], hf[7], hf[8]),
                       (hf[9], hf[10], hf[11])))
    pin = Pin((rec.pin_pos_bf_m[0], rec.pin_pos_bf_m[1], rec.pin_pos_bf_m[2]),
              (rec.pin_quat_bf[0], rec.pin_quat_bf[1], rec.pin_quat_bf[2], rec.pin_quat_bf[3]),
              (rec.pin_pivot_bf_m[0], rec.pin_pivot_bf_m[1], rec.pin_pivot_bf_m[2]),
              rec.pivot_rate_radps)
    return Ship(np.int64(rec.surface_state), motion, rec.mass_kg, rec.fuel_kg, footing, pin)


@kernel
def store(s, rec):
    """Write a :class:`Ship` into its record, in place (the one place a record is written)."""
    m, ft, pin = s.motion, s.footing, s.pin
    rec.surface_state = s.surface_state
    for k in range(3):
        rec.pos_m[k] = m.p[k]
        rec.vel_mps[k] = m.v[k]
        rec.omega_body_radps[k] = m.w[k]
        rec.pin_pos_bf_m[k] = pin.pos_bf_m[k]
        rec.pin_pivot_bf_m[k] = pin.pivot_bf_m[k]
    for k in range(4):
        rec.quat[k] = m.q[k]
        rec.pin_quat_bf[k] = pin.quat_bf[k]
        rec.sliding[k] = 1 if ft.sliding[k] else 0
    rec.mass_kg = s.mass_kg
    rec.fuel_kg = s.fuel_kg
    rec.absorbing = ft.absorbing
    rec.settle_ticks = ft.settle_ticks
    rec.settle_for_s = ft.settle_for_s
    rec.settle_margin = ft.settle_margin
    for i in range(4):
        for k in range(3):
            rec.hold_force_n[3 * i + k] = ft.hold_w[i][k]
    rec.pivot_rate_radps = pin.rate_radps


class EventLog(NamedTuple):
    """Where a ship's transitions go: ``events`` (sim.state.TRANSITION_DTYPE), ``count[0]`` of
    them so far, and the ship's index in its batch."""

    events: np.ndarray
    count: np.ndarray
    ship: int


@kernel
def emit(log, from_state, to_state, v_radial_mps, t_offset_s):
    """Append a transition to the log, ``t_offset_s`` after the tick's start (those past the
    array's end are counted, not written)."""
    n = log.count[0]
    if n < log.events.shape[0]:
        e = log.events[n]
        e.ship = log.ship
        e.from_state = from_state
        e.to_state = to_state
        e.v_radial_mps = v_radial_mps
        e.t_offset_s = t_offset_s
    log.count[0] = n + 1


@constructor
def scene_ground(cfg, terrain, cos_theta, sin_theta):
    """The ground of the scene record ``cfg`` with the body turned to (cos, sin)."""
    return Ground(cfg.body_radius_m, terrain, cos_theta, sin_theta, cfg.omega_radps,
                  cfg.surface_normal == RADIAL_NORMAL)


# -- 1. commands ---------------------------------------------------------------------------------
class Commands(NamedTuple):
    throttle: float
    thrust_n: float
    rcs_torque_body_nm: tuple
    driven: bool  # the player's engine or RCS acts (not the hold's torque alone)


class Report(NamedTuple):
    """What a free ship's tick of flight reports (sim.phases.observe)."""

    friction_n: float  # the last sub-step's friction force (the feet's sum)
    normal_n: float  # the normal force at the end
    peak_penetration_m: float  # the deepest penetration of any sub-step
    guard_j: float  # what the passivity guard removed
    #: the deepest foot's penetration at the tick's end, from the contact evaluated there on the
    #: ground at the tick's end angle (sim.contact.lowest_foot_penetration's bits); NaN: none was
    lowest_m: float


#: a tick without flight (pinned ships; a state at rest)
NO_REPORT = Report(0.0, 0.0, 0.0, 0.0, math.nan)


class Turn(NamedTuple):
    """The body's angle at the tick's start (cos0, sin0) and end (cos1, sin1)."""

    cos0: float
    sin0: float
    cos1: float
    sin1: float


class Here(NamedTuple):
    """The scene and this ship, this tick: what every phase reads besides the ship's own state.
    ``cfg``: the scene's constants (a record of sim.params.SCENE_DTYPE), ``terrain``: its
    terrain's record, ``sp``: the ship's constants (a record of SHIP_DTYPE), ``turn``: the body's
    angle at the tick's start and end (a :class:`Turn`)."""

    cfg: object
    terrain: object
    sp: object
    turn: Turn
