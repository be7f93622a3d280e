"""Parameters: everything the step reads but never changes. Frozen; arrays are per ship, shape (N,...).

Kept apart from :mod:`sim.state` (what changes every tick), as in brax's ``base.py``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from sim.constants import CONTACT_STIFFNESS_PER_KG


@dataclass(frozen=True)
class SimParams:
    """How time advances.

    ``dt_s``: the tick. ``max_substep_s``: ships in or near contact are stepped in
    ``ceil(dt / max_substep)`` equal sub-steps (0 = never sub-step, the seed's behaviour); ships
    far from the ground take the whole tick in one step. ``integrator``: a name in
    :data:`sim.integrators.METHODS`.
    """

    dt_s: float = 0.05
    integrator: str = "exponential"
    max_substep_s: float = 0.025
    duration_s: float = 30.0
    #: with a method exact on the spring, purely vertical ships take one step per tick
    #: (sim.step.purely_vertical); False sub-steps them like every other ship near the ground
    vertical_one_step: bool = True
    #: a passive ship's energy never rises over a sub-step (sim.step.passivity_guard)
    energy_guard: bool = True

    @cached_property
    def n_ticks(self) -> int:
        return int(math.ceil(self.duration_s / self.dt_s - 1e-9))

    @cached_property
    def n_fine_substeps(self) -> int:
        if self.max_substep_s <= 0.0:
            return 1
        return max(1, int(math.ceil(self.dt_s / self.max_substep_s - 1e-9)))


@dataclass(frozen=True)
class ContactParams:
    """The seed's Configuration table (same names without ``contact_``, units in the names) plus
    the settings SEED-NOTES adds. Angles are stored as cosines for the step's exact comparisons."""

    crash_speed_mps: float = 50.0
    bounce_speed_mps: float = 10.0
    settle_tilt_deg: float = 5.0
    settle_angular_vel_radps: float = 0.01
    settle_linear_vel_mps: float = 0.5
    tipped_angle_deg: float = 80.0
    damping_ratio: float = 0.3
    friction_static: float = 0.8
    friction_kinetic: float = 0.5
    align_on_touchdown: bool = True
    #: SEED-NOTES 3: the settle thresholds must hold this long before contact -> landed.
    settle_time_s: float = 0.5
    #: SEED-NOTES 1: damping ratio of the leg absorbers that take an impact slower than
    #: ``bounce_speed``; such a contact is bilateral while the legs are compressed, so it cannot rebound.
    absorb_damping_ratio: float = 1.0
    #: SEED-NOTES 4: "coulomb" (a bounded force that holds exactly at rest) or "seed" (velocity reset).
    friction_model: str = "coulomb"
    #: Tilt at which a tipped ship lies on its side, degrees.
    tipped_rest_deg: float = 90.0
    stiffness_per_kg: float = CONTACT_STIFFNESS_PER_KG
    #: "terrain": each foot is pushed along the terrain's normal under it, friction in the tangent
    #: plane there; "radial": the seed's (surface normal = local radial, whatever the slope)
    surface_normal: str = "terrain"

    @cached_property
    def cos_settle_tilt(self) -> float:
        return math.cos(math.radians(self.settle_tilt_deg))

    @cached_property
    def cos_tipped(self) -> float:
        return math.cos(math.radians(self.tipped_angle_deg))

    @cached_property
    def cos_tipped_rest(self) -> float:
        return math.cos(math.radians(self.tipped_rest_deg))

    @cached_property
    def omega_radps(self) -> float:
        """Natural frequency of the contact spring, sqrt(k/m), rad/s."""
        return math.sqrt(self.stiffness_per_kg)


@dataclass(frozen=True)
class Terrain:
    """A deterministic height field over the landing site, m.

    h(e, n) = base_height + sum_j height_j * (1 - d_j^2 / radius_j^2)^2 for d_j < radius_j, where d_j
    is the distance from bump j's centre (east_j, north_j) in the site's tangent plane. The biweight
    bump is smooth (C1) and needs only +, *, so heights are bit-identical everywhere.
    Coordinates: the site is the body-fixed +x axis; east is body-fixed +y, north +z.
    """

    base_height_m: float = 0.0
    bump_east_m: tuple[float, ...] = ()
    bump_north_m: tuple[float, ...] = ()
    bump_radius_m: tuple[float, ...] = ()
    bump_height_m: tuple[float, ...] = ()

    def height_m(self, east_m: np.ndarray, north_m: np.ndarray) -> np.ndarray:
        return self.height_and_slope(east_m, north_m)[0]

    def height_and_slope(self, east_m: np.ndarray, north_m: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(h, dh/de, dh/dn): the height and its gradient, analytically,
        dh/de = -4 height (1 - s) de / radius^2 inside each bump (likewise north)."""
        h = np.full(np.shape(east_m), self.base_height_m)
        dh_de = np.zeros(np.shape(east_m))
        dh_dn = np.zeros(np.shape(east_m))
        for e0, n0, rad, hgt in zip(self.bump_east_m, self.bump_north_m, self.bump_radius_m,
                                    self.bump_height_m):
            de = east_m - e0
            dn = north_m - n0
            inv_r2 = 1.0 / (rad * rad)
            s = (de * de + dn * dn) * inv_r2
            w = 1.0 - s
            inside = s < 1.0
            h = h + np.where(inside, hgt * w * w, 0.0)
            slope = np.where(inside, -4.0 * hgt * w * inv_r2, 0.0)
            dh_de = dh_de + slope * de
            dh_dn = dh_dn + slope * dn
        return h, dh_de, dh_dn

    @property
    def flat(self) -> bool:
        return not self.bump_height_m


@dataclass(frozen=True)
class BodyParams:
    """The planet or moon: a point mass rotating about the inertial +z axis."""

    name: str = "Luna"
    radius_m: float = 1737400.0
    gm_m3ps2: float = 4.9048695e12
    rotation_period_s: float = 0.0
    terrain: Terrain = field(default_factory=Terrain)

    @cached_property
    def omega_radps(self) -> float:
        """Spin rate about +z; 0 when ``rotation_period_s`` is 0."""
        return 0.0 if self.rotation_period_s == 0.0 else 2.0 * math.pi / self.rotation_period_s

    @cached_property
    def surface_gravity_mps2(self) -> float:
        return self.gm_m3ps2 / (self.radius_m * self.radius_m)


@dataclass(frozen=True)
class ShipParams:
    """Per-ship constants, each an array over the batch (N,) unless noted."""

    ship_id: tuple[str, ...]
    player_id: tuple[str, ...]
    mass0_kg: np.ndarray  # (N,) wet mass at t = 0
    fuel0_kg: np.ndarray  # (N,)
    com_height_m: np.ndarray  # (N,) centre of mass above the feet plane
    leg_radius_m: np.ndarray  # (N,) radius of the landing-leg footprint
    inertia0_kgm2: np.ndarray  # (N, 3) principal moments at t = 0, body frame (z = long axis)
    max_thrust_n: np.ndarray  # (N,) main engine, along body +z
    max_rcs_torque_nm: np.ndarray  # (N,) per body axis
    isp_s: np.ndarray  # (N,) main engine specific impulse
    rcs_isp_s: np.ndarray  # (N,)
    rcs_arm_m: np.ndarray  # (N,) lever arm of the RCS thrusters (torque / arm = thrust)

    @property
    def n(self) -> int:
        return int(self.mass0_kg.shape[0])

    def take(self, idx: np.ndarray, with_ids: bool = False) -> "ShipParams":
        """The ships at ``idx``, as a batch of their own (ids only if asked: the step never
        reads them, and building them costs more than the arrays for large batches)."""
        ids = [int(i) for i in idx] if with_ids else []
        return ShipParams(
            ship_id=tuple(self.ship_id[i] for i in ids),
            player_id=tuple(self.player_id[i] for i in ids),
            **{f: getattr(self, f)[idx] for f in _ARRAY_FIELDS},
        )


_ARRAY_FIELDS = ("mass0_kg", "fuel0_kg", "com_height_m", "leg_radius_m", "inertia0_kgm2",
                 "max_thrust_n", "max_rcs_torque_nm", "isp_s", "rcs_isp_s", "rcs_arm_m")


@dataclass(frozen=True)
class ControllerParams:
    """Attitude hold: a critically damped PD law per body axis, saturated at ``max_rcs_torque``.

    tau = -I (bandwidth^2 err + 2 bandwidth omega_rel).
    """

    bandwidth_radps: float = 1.0


@dataclass(frozen=True)
class Params:
    sim: SimParams
    contact: ContactParams
    body: BodyParams
    ships: ShipParams
    controller: ControllerParams = field(default_factory=ControllerParams)

    def take(self, idx: np.ndarray, with_ids: bool = False) -> "Params":
        return Params(self.sim, self.contact, self.body, self.ships.take(idx, with_ids),
                      self.controller)
