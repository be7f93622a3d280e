"""What changes every tick: the batch's state, the commands applied, and what a tick reports.

Frames: positions and velocities are inertial, centred on the body (the body's own motion is a
uniform translation, so this frame is inertial too). ``quat`` rotates body-frame vectors into it.
Pinned ships (landed, tipped, crashed) also keep their pose in the body-fixed frame, so that they
turn with a rotating body without drift.
"""
from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np


@dataclass(frozen=True)
class State:
    tick: int
    surface_state: np.ndarray  # (N,) int8, SurfaceState values
    pos_m: np.ndarray  # (N, 3) centre of mass, inertial
    vel_mps: np.ndarray  # (N, 3) inertial
    quat: np.ndarray  # (N, 4) (w, x, y, z), body -> inertial
    omega_body_radps: np.ndarray  # (N, 3) angular velocity in the body frame (inertial rate)
    mass_kg: np.ndarray  # (N,) wet mass
    fuel_kg: np.ndarray  # (N,)
    absorbing: np.ndarray  # (N,) bool: this contact began slower than bounce_speed (SEED-NOTES 1)
    sliding: np.ndarray  # (N, 4) bool: each foot's friction regime (kinetic) at the last sub-step's end
    settle_ticks: np.ndarray  # (N,) int64: consecutive ticks the settle thresholds have held
    pivot_rate_radps: np.ndarray  # (N,) tipped only: rate of turn about the pivot (+ = toppling)
    pin_pos_bf_m: np.ndarray  # (N, 3) pinned ships: centre of mass, body-fixed frame
    pin_quat_bf: np.ndarray  # (N, 4) pinned ships: attitude relative to the body-fixed frame
    pin_pivot_bf_m: np.ndarray  # (N, 3) tipped only: the pivot (lowest foot), body-fixed frame

    @property
    def n(self) -> int:
        return int(self.surface_state.shape[0])

    def take(self, idx: np.ndarray) -> "State":
        """The ships at ``idx`` as a batch of their own."""
        return replace(self, **{f.name: getattr(self, f.name)[idx] for f in fields(self)
                                if f.name != "tick"})

    def put(self, parts: "list[tuple[np.ndarray, State]]") -> "State":
        """A copy of self with the ships at each ``idx`` replaced by its ``part`` (one copy of
        each array, whatever the number of parts)."""
        out = {}
        for f in fields(self):
            if f.name == "tick":
                continue
            arr = getattr(self, f.name).copy()
            for idx, part in parts:
                arr[idx] = getattr(part, f.name)
            out[f.name] = arr
        return replace(self, **out)

    def arrays(self) -> dict[str, np.ndarray]:
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name != "tick"}


#: State fields in a fixed order (for logs and comparisons).
STATE_ARRAY_FIELDS: tuple[str, ...] = tuple(f.name for f in fields(State) if f.name != "tick")


@dataclass(frozen=True)
class Inputs:
    """The players' commands for one tick (what the scenario's ``[[ships.inputs]]`` hold at that tick)."""

    throttle: np.ndarray  # (N,) 0..1 of max_thrust
    rcs: np.ndarray  # (N, 3) -1..1 of max_rcs_torque per body axis; 0 leaves the axis to the hold mode
    hold: np.ndarray  # (N,) int8, HoldMode values

    def take(self, idx: np.ndarray) -> "Inputs":
        return Inputs(self.throttle[idx], self.rcs[idx], self.hold[idx])


@dataclass(frozen=True)
class Outputs:
    """What one tick reports per ship, at the end of the tick (forces: last sub-step's)."""

    altitude_m: np.ndarray  # (N,) lowest foot above the terrain under it (negative = penetrating)
    penetration_m: np.ndarray  # (N,) max(0, -altitude)
    peak_penetration_m: np.ndarray  # (N,) deepest penetration at any sub-step of the tick (>= 0)
    cos_tilt: np.ndarray  # (N,) cosine of the long axis' angle from local up
    v_radial_mps: np.ndarray  # (N,) + = up, relative to the surface
    v_tangential_mps: np.ndarray  # (N,) speed along the surface, relative to it
    normal_force_n: np.ndarray  # (N,)
    friction_force_n: np.ndarray  # (N,)
    throttle: np.ndarray  # (N,) applied (0 without fuel)
    rcs_torque_body_nm: np.ndarray  # (N, 3) applied
    energy_guard_j: np.ndarray  # (N,) energy the passivity guard removed this tick (sim.step)


@dataclass(frozen=True)
class Event:
    """One state transition. ``ship`` indexes the batch; ``tick`` is the tick whose step made it."""

    tick: int
    ship: int
    kind: int  # EventKind
    from_state: int  # SurfaceState
    to_state: int  # SurfaceState
    #: radial speed (+ up, relative to the surface) at the sub-step of the transition: the impact
    #: speed of a contact, the separation speed of a liftoff
    v_radial_mps: float = 0.0
