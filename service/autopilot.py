"""The landing autopilot (the seed's tick-engine ``maneuver_landing``): every tick, a throttle and a
hold mode for each ship it flies, until the ship has landed, tipped or crashed.

The live service (service.shard) asks :func:`autoland_commands` for the engaged ships at each tick
and gives each answer to ``World.command``: every autopilot action is an ordinary recorded command,
so a flight log of an autolanding replays exactly without this module.

The law (MODEL-NOTES 37), per ship, with ``h`` the lowest foot's height above the terrain under it
and ``v`` the descent speed relative to the surface:

    v_ref(h) = sqrt(v_td^2 + 2 a_b max(h - h_gate, 0))          the descent speed to fly at h
    a_b      = max(BRAKE_FRACTION (a_max cos(tilt) - g), MIN_BRAKE_MPS2)
    a_thrust = g + a_b max(v, 0) / v_ref [h > h_gate] + K (v - v_ref)
    throttle = clip(a_thrust / (a_max cos(tilt)), 0, 1), hold radial; 0 once the feet touch

a constant-deceleration ("suicide burn") profile planned at a fraction of the engine's margin over
the weight, ending at a gate ``h_gate`` above the ground at the touchdown speed ``v_td``, which it
holds down to the ground. Once the feet touch (contact) the engine is cut, so that the legs'
absorbers take the touchdown and the ship settles (a ship held up by its engine never lands).

Assumptions: point-mass gravity GM / r^2 less the centrifugal part along local up on a turning
body (Coriolis neglected); thrust along the long axis, which the RADIAL hold keeps along local up;
the horizontal velocity is not nulled (the service's commands leave the RCS at zero, so the ship
cannot be tilted on purpose): the legs' friction stops the slide, and the RADIAL hold, kept in
contact, keeps it from tripping over its leading feet (tested at 6 m/s sideways, the built-in
``trip``'s speed, which tips a ship without the hold). A ship that cannot land (thrust
below its weight, too little fuel, too fast too low) still gets full throttle whenever it needs
more than it has, and ends as the physics decides: CRASHED when it meets the ground faster than
``contact.crash_speed``.

Pure and deterministic: a function of the world's state, its parameters and its tick, computed
elementwise over the ships with numpy's +, -, *, /, sqrt, minimum, maximum and comparisons (each
correctly rounded, so the same bits on every machine and whatever other ships are engaged), and
the terrain's height from the step's own compiled function (sim.measure.terrain_height). No
libm: a turning body's angle, needed only for a terrain with bumps, comes from a series.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np

from touchdown.sim.enums import HoldMode, SurfaceState
from touchdown.sim.measure import terrain_height

if TYPE_CHECKING:
    from touchdown.sim.world import World

#: The descent speed the law aims to touch down at, m/s: well under the legs' absorber limit
#: (``contact.bounce_speed``, 10 m/s by default), so the touchdown is absorbed without a bounce.
TOUCHDOWN_SPEED_MPS = 1.5
#: Height of the lowest foot above the terrain below which the ship descends at the touchdown
#: speed, m: the braking profile ends here, so the last metres need no deceleration.
GATE_HEIGHT_M = 2.0
#: Fraction of the engine's margin over the weight (a_max cos(tilt) - g) the braking profile plans
#: to use: the rest is kept to catch up with the profile (a late start, mass, a tilt).
BRAKE_FRACTION = 0.6
#: Smallest braking deceleration planned, m/s^2: a ship whose engine cannot beat its weight still
#: gets a profile (a slow one, which makes it ask for full throttle: its best).
MIN_BRAKE_MPS2 = 0.1
#: Gain from the descent-speed error to the thrust acceleration, 1/s: a time constant of 0.5 s,
#: ten ticks of the default 0.05 s, well inside the discrete loop's stability (K dt < 2).
SPEED_GAIN_PER_S = 2.0
#: The engine fires only while the long axis is within 60 degrees of local up: tilted further, it
#: would mostly push sideways (the RADIAL hold first turns the ship up).
MIN_COS_TILT = 0.5

_FLYING, _CONTACT, _LANDED, _TIPPED, _CRASHED = (int(s) for s in SurfaceState)


class AutolandOutcome(enum.IntEnum):
    """Where an autolanding stands: still flying it, or how it ended."""

    FLYING = 0  # still at work (flying, or in contact and settling)
    LANDED = 1  # success: the ship reached SurfaceState.LANDED
    TIPPED = 2
    CRASHED = 3

    @property
    def label(self) -> str:
        """``flying``, ``landed``, ``tipped``, ``crashed``."""
        return self.name.lower()


#: the outcome of each surface state
_OUTCOME_OF = np.array([AutolandOutcome.FLYING, AutolandOutcome.FLYING, AutolandOutcome.LANDED,
                        AutolandOutcome.TIPPED, AutolandOutcome.CRASHED], dtype=np.int64)


@dataclass(frozen=True)
class AutolandCommand:
    """What to give ``world.command`` for one ship this tick (the RCS stays at zero)."""

    ship_id: str
    throttle: float
    hold: int


@dataclass(frozen=True)
class Guidance:
    """The law's numbers for a batch of ships (arrays, one entry per ship), SI units."""

    h_m: np.ndarray  # lowest foot above the terrain under it
    v_down_mps: np.ndarray  # descent speed relative to the surface (+ = down)
    g_mps2: np.ndarray  # effective gravity along local down
    a_max_mps2: np.ndarray  # full thrust / mass
    cos_tilt: np.ndarray  # long axis . local up
    v_ref_mps: np.ndarray  # the profile's descent speed at h
    throttle: np.ndarray  # 0..1


def autoland_commands(world: "World", ship_ids: Sequence[str]
                      ) -> tuple[list[AutolandCommand], dict[str, AutolandOutcome]]:
    """For the engaged ships present in ``world`` (at ``world.tick``; ids not in the fleet are
    skipped): this tick's commands, in the order given, and the ships whose autolanding has just
    ended (outcome LANDED, TIPPED or CRASHED, from the ship's surface state), which the caller
    disengages.

    A flying ship gets the law's throttle with hold RADIAL; a ship in contact throttle 0, hold
    RADIAL (the legs settle it; the hold keeps it from rocking). A ship whose autolanding ended
    gets throttle 0, hold OFF: the autopilot hands back a quiet ship. A landed or tipped ship is
    pinned and no hold acts on it (sim.phases.commands), so a RADIAL hold there would only take
    effect after a later liftoff, which is the player's to command, and would spend RCS fuel on a
    righted ship the player has not asked to hold.
    """
    found = [(sid, world.row(sid)) for sid in dict.fromkeys(ship_ids)]
    ids = [sid for sid, i in found if i is not None]
    if not ids:
        return [], {}
    rows = np.array([i for _sid, i in found if i is not None], dtype=np.intp)
    guid = guidance(world, rows)
    states = world.state.rows["surface_state"][rows].astype(np.int64)
    outcome = _OUTCOME_OF[states]
    ended = outcome != int(AutolandOutcome.FLYING)
    hold = np.where(ended, int(HoldMode.OFF), int(HoldMode.RADIAL))
    throttle = np.where(ended, 0.0, guid.throttle)
    commands = [AutolandCommand(sid, float(throttle[k]), int(hold[k]))
                for k, sid in enumerate(ids)]
    outcomes = {sid: AutolandOutcome(int(outcome[k])) for k, sid in enumerate(ids) if ended[k]}
    return commands, outcomes


def guidance(world: "World", rows: np.ndarray) -> Guidance:
    """The law's numbers for the ships at ``rows`` (row numbers of the present fleet): their
    state gathered, measured (:func:`measure`) and put through :func:`throttle_law`. A ship not
    flying gets throttle 0."""
    st = world.state.rows[rows]
    sp = world.params.ships.rows[rows]
    h_m, v_down_mps, g_mps2, cos_tilt = measure(world, st, sp)
    a_max_mps2 = sp["max_thrust_n"] / st["mass_kg"]
    fuelled = st["fuel_kg"] > 0.0
    v_ref, throttle = throttle_law(h_m, v_down_mps, g_mps2, np.where(fuelled, a_max_mps2, 0.0),
                                   cos_tilt)
    throttle = np.where(st["surface_state"] == _FLYING, throttle, 0.0)
    return Guidance(h_m, v_down_mps, g_mps2, a_max_mps2, cos_tilt, v_ref, throttle)


def throttle_law(h_m: np.ndarray, v_down_mps: np.ndarray, g_mps2: np.ndarray,
                 a_max_mps2: np.ndarray, cos_tilt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(v_ref, throttle) of the module's law, elementwise:

        a_b      = max(BRAKE_FRACTION (a_max c - g), MIN_BRAKE_MPS2),  c = cos(tilt)
        v_ref    = sqrt(v_td^2 + 2 a_b max(h - h_gate, 0))
        a_thrust = g + [h > h_gate] a_b max(v, 0) / v_ref + K (v - v_ref)
        throttle = clip(a_thrust / (a_max c), 0, 1), 0 if c < MIN_COS_TILT

    The feed-forward term is the profile's own deceleration, d v_ref / dt = -a_b v / v_ref at h;
    below the gate v_ref is constant. ``a_max`` 0 (no fuel, no engine): full throttle whenever
    thrust is wanted (it has no effect; the ship falls as it must)."""
    vertical = a_max_mps2 * cos_tilt
    a_brake = np.maximum(BRAKE_FRACTION * (vertical - g_mps2), MIN_BRAKE_MPS2)
    above_gate = np.maximum(h_m - GATE_HEIGHT_M, 0.0)
    v_ref = np.sqrt(TOUCHDOWN_SPEED_MPS * TOUCHDOWN_SPEED_MPS + 2.0 * a_brake * above_gate)
    feed_forward = np.where(h_m > GATE_HEIGHT_M,
                            a_brake * np.maximum(v_down_mps, 0.0) / v_ref, 0.0)
    a_thrust = g_mps2 + feed_forward + SPEED_GAIN_PER_S * (v_down_mps - v_ref)
    # a_thrust / vertical clipped to 0..1 without dividing by zero: min(max(a, 0), d) / d
    can = vertical > 0.0
    denom = np.where(can, vertical, 1.0)
    throttle = np.where(can, np.minimum(np.maximum(a_thrust, 0.0), denom) / denom,
                        np.where(a_thrust > 0.0, 1.0, 0.0))
    throttle = np.where(cos_tilt < MIN_COS_TILT, 0.0, throttle)
    return v_ref, throttle


def measure(world: "World", st: np.ndarray, sp: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(h_m, v_down_mps, g_mps2, cos_tilt) of ships with state records ``st`` and ship records
    ``sp`` at the world's tick:

    - h: the lowest of the four feet above the terrain under it, |foot| - R - terrain(foot), the
      feet at body (+-a, 0, -h_com), (0, +-a, -h_com) (sim.contact.feet; the telemetry's
      ``altitude_m``);
    - v_down: -(v - Omega z x p) . r_hat, the descent speed relative to the turning surface;
    - g: GM / r^2 - Omega^2 (x^2 + y^2) / r, gravity less the centrifugal acceleration along up;
    - cos_tilt: the long axis (body z) . r_hat.
    """
    body = world.params.body
    om = body.omega_radps
    p, v, q = st["pos_m"], st["vel_mps"], st["quat"]
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    r = np.sqrt(x * x + y * y + z * z)
    ux, uy, uz = x / r, y / r, z / r
    vx, vy, vz = v[:, 0] + om * y, v[:, 1] - om * x, v[:, 2]  # relative to the surface
    v_down = -(vx * ux + vy * uy + vz * uz)
    g = body.gm_m3ps2 / (r * r) - om * om * (x * x + y * y) / r
    ex, ey, ez = _body_axes(q)
    cos_tilt = ez[0] * ux + ez[1] * uy + ez[2] * uz
    a, hc = sp["leg_radius_m"], sp["com_height_m"]
    cos_t, sin_t = _body_angle(om, world.tick * world.params.sim.dt_s) if not body.terrain.flat \
        else (1.0, 0.0)
    lowest = None
    for axis, sign in ((ex, 1.0), (ey, 1.0), (ex, -1.0), (ey, -1.0)):
        fx = x + (axis[0] * (sign * a) - ez[0] * hc)
        fy = y + (axis[1] * (sign * a) - ez[1] * hc)
        fz = z + (axis[2] * (sign * a) - ez[2] * hc)
        height = np.sqrt(fx * fx + fy * fy + fz * fz) - body.radius_m - _terrain(
            body, cos_t, sin_t, fx, fy, fz)
        lowest = height if lowest is None else np.minimum(lowest, height)
    return lowest, v_down, g, cos_tilt


def _body_axes(q: np.ndarray) -> tuple[tuple[np.ndarray, ...], ...]:
    """The body x, y, z axes in the inertial frame (sim.vec.body_axes), from (N, 4) quaternions."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    ex = (1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y))
    ey = (2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x))
    ez = (2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y))
    return ex, ey, ez


def _terrain(body, cos_t: float, sin_t: float, fx: np.ndarray, fy: np.ndarray, fz: np.ndarray
             ) -> np.ndarray | float:
    """The terrain's height under inertial points, m: at their body-fixed (y, z) = (east, north),
    the body turned by the angle (cos_t, sin_t)."""
    ter = body.terrain
    if ter.flat:
        return ter.base_height_m
    east = fy if (cos_t == 1.0 and sin_t == 0.0) else cos_t * fy - sin_t * fx
    return terrain_height(ter, np.asarray(east, float), np.asarray(fz, float))


#: Taylor coefficients of cos y and sin(y) / y in y^2, to y^16: |y| <= pi/4 leaves an error under
#: 1e-18.
_COS_SERIES = tuple((-1.0) ** k / math.factorial(2 * k) for k in range(9))
_SINC_SERIES = tuple((-1.0) ** k / math.factorial(2 * k + 1) for k in range(9))
_TWO_PI = 2.0 * math.pi


def _body_angle(omega_radps: float, t_s: float) -> tuple[float, float]:
    """(cos, sin) of the body's angle Omega t with +, *, / only: the angle reduced to one turn
    (fmod is exact), halved until under pi/4, the series, doubled back (sim.vec.cos_sinc's way).
    Agrees with the step's libm angle to ~1e-15 rad: a tenth of a nanometre at 1000 km."""
    theta = math.fmod(omega_radps * t_s, _TWO_PI)
    if theta == 0.0:
        return 1.0, 0.0
    y, halvings = theta, 0
    while abs(y) > 0.785:
        y, halvings = y * 0.5, halvings + 1
    y2 = y * y
    c, s = _COS_SERIES[-1], _SINC_SERIES[-1]
    for k in range(len(_COS_SERIES) - 2, -1, -1):
        c, s = c * y2 + _COS_SERIES[k], s * y2 + _SINC_SERIES[k]
    s = s * y
    for _ in range(halvings):
        c, s = c * c - s * s, 2.0 * s * c
    return c, s
