"""Parameters: everything the step reads but never changes. Frozen; arrays are per ship, shape (N,...).

Kept apart from :mod:`sim.state` (what changes every tick), as in brax's ``base.py``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import ClassVar

import numpy as np

from sim.constants import CONTACT_STIFFNESS_PER_KG, STICK_SPEED_MPS
from sim.state import Batch


@dataclass(frozen=True)
class SimParams:
    """How time advances.

    ``dt_s``: the tick. ``max_substep_s``: ships in or near contact are stepped in
    ``ceil(dt / max_substep)`` equal sub-steps (0 = never sub-step, the seed's behaviour); ships
    far from the ground take the whole tick in one step. ``integrator``: a name in
    :data:`sim.integrators.METHODS`.
    """

    dt_s: float = 0.05
    integrator: str = "hybrid"
    max_substep_s: float = 0.025
    #: a ship that is not purely vertical takes sub-steps of at most this while it strikes the
    #: ground or rebounds (sim.step.striking): friction's turns between holding and sliding,
    #: first order in the sub-step, happen there (0 = max_substep everywhere; max_substep = 0, the seed's plain step, turns it
    #: off too)
    impact_substep_s: float = 0.005
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
    #: a foot slipping slower than this is held by static friction (the seed's 0.01 m/s)
    stick_speed_mps: float = STICK_SPEED_MPS
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

    h(e, n) = base_height - tan(slope) (e sin(az) + n cos(az))
              + sum_j height_j * (1 - d_j^2 / radius_j^2)^2 for d_j < radius_j,

    where d_j is the distance from bump j's centre (east_j, north_j) in the site's tangent plane,
    and the uniform slope falls by tan(slope) per metre toward the azimuth az (the downhill
    direction, from north toward east; SPEC.md section 6). The biweight bump is smooth (C1) and
    needs only +, *, so heights are bit-identical everywhere.
    Coordinates: the site is the body-fixed +x axis; east is body-fixed +y, north +z.
    """

    base_height_m: float = 0.0
    slope_deg: float = 0.0
    slope_azimuth_deg: float = 0.0
    bump_east_m: tuple[float, ...] = ()
    bump_north_m: tuple[float, ...] = ()
    bump_radius_m: tuple[float, ...] = ()
    bump_height_m: tuple[float, ...] = ()

    def record(self) -> np.ndarray:
        """One record of sim.contact.TERRAIN_DTYPE: what sim.contact.Ground reads."""
        from sim.contact import TERRAIN_DTYPE
        rec = np.zeros(1, TERRAIN_DTYPE)
        n = len(self.bump_height_m)
        rec[0]["base_height_m"] = self.base_height_m
        rec[0]["slope_east"], rec[0]["slope_north"] = self.gradient
        rec[0]["level"] = self.flat
        rec[0]["n_bumps"] = n
        rec[0]["bumps"][:n] = np.array([self.bump_east_m, self.bump_north_m, self.bump_radius_m,
                                       self.bump_height_m], dtype=float).T.reshape(-1, 4)
        return rec

    @property
    def gradient(self) -> tuple[float, float]:
        """(dh/d(east), dh/d(north)) of the uniform slope: -tan(slope) (sin(az), cos(az)) (libm,
        once, when the scene is built)."""
        if self.slope_deg == 0.0:
            return 0.0, 0.0
        t = math.tan(math.radians(self.slope_deg))
        az = math.radians(self.slope_azimuth_deg)
        return -t * math.sin(az), -t * math.cos(az)

    @property
    def flat(self) -> bool:
        """No bumps and no slope: the ground is the sphere of radius R + base_height."""
        return not self.bump_height_m and self.slope_deg == 0.0


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


SHIP_DTYPE = np.dtype([
    ("mass0_kg", "f8"),  # wet mass at t = 0
    ("fuel0_kg", "f8"),
    ("com_height_m", "f8"),  # centre of mass above the feet plane
    ("leg_radius_m", "f8"),  # radius of the landing-leg footprint
    ("inertia0_kgm2", "f8", (3,)),  # principal moments at t = 0, body frame (z = long axis)
    ("max_thrust_n", "f8"),  # main engine, along body +z
    ("max_rcs_torque_nm", "f8"),  # per body axis
    ("isp_s", "f8"),  # main engine specific impulse
    ("rcs_isp_s", "f8"),
    ("rcs_arm_m", "f8"),  # lever arm of the RCS thrusters (torque / arm = thrust)
    ("stiffness_per_kg", "f8"),  # the contact spring's k / m, 1/s^2 (the seed's 100)
    ("contact_omega_radps", "f8"),  # sqrt(k / m): the contact's natural frequency
    ("n_substeps", "i8"),  # sub-steps a tick near the ground, from this ship's own modes
], align=True)


@dataclass(frozen=True, eq=False)
class ShipParams(Batch):
    """Per-ship constants: a record per ship (:data:`SHIP_DTYPE`), and the ships' names."""

    ship_id: tuple[str, ...] = ()
    player_id: tuple[str, ...] = ()
    DTYPE: ClassVar[np.dtype] = SHIP_DTYPE
    LABELS: ClassVar[tuple[str, ...]] = ("ship_id", "player_id")


@dataclass(frozen=True)
class ControllerParams:
    """Attitude hold: a critically damped PD law per body axis, saturated at ``max_rcs_torque``.

    tau = -I (bandwidth^2 err + 2 bandwidth omega_rel).
    """

    bandwidth_radps: float = 1.0


SCENE_DTYPE = np.dtype([
    ("dt_s", "f8"), ("method", "i8"), ("vertical_one_step", "?"), ("energy_guard", "?"),
    ("impact_substeps", "i8"),
    ("linear_model", "?"),
    ("crash_speed_mps", "f8"), ("crash_speed2", "f8"), ("bounce_speed_mps", "f8"),
    ("settle_lin2", "f8"), ("settle_ang2", "f8"), ("cos_settle_tilt", "f8"), ("cos_tipped", "f8"),
    ("tipped_rest_rad", "f8"), ("damping_ratio", "f8"), ("absorb_damping_ratio", "f8"),
    ("friction_static", "f8"), ("friction_kinetic", "f8"), ("stick_speed_mps", "f8"),
    ("align_on_touchdown", "?"),
    ("settle_time_s", "f8"), ("seed_friction", "?"), ("radial_normal", "?"),
    ("body_radius_m", "f8"), ("gm_m3ps2", "f8"), ("omega_radps", "f8"), ("omega2", "f8"),
    ("surface_gravity_mps2", "f8"), ("base_height_m", "f8"), ("terrain_max_m", "f8"),
    ("slope_tan", "f8"),
    ("bandwidth_radps", "f8"),
], align=True)
"""The scene's constants as the compiled step reads them (one record; derived from Params)."""


@dataclass(frozen=True)
class Params:
    sim: SimParams
    contact: ContactParams
    body: BodyParams
    ships: ShipParams
    controller: ControllerParams = field(default_factory=ControllerParams)

    def take(self, idx) -> "Params":
        return self.with_ships(self.ships.take(idx))

    def with_ships(self, ships: ShipParams) -> "Params":
        """The same scene with another fleet (the scene's derived records carried over)."""
        out = Params(self.sim, self.contact, self.body, ships, self.controller)
        for name in ("scene", "terrain"):  # cached, and the same for any fleet
            if name in self.__dict__:
                out.__dict__[name] = self.__dict__[name]
        return out

    @cached_property
    def scene(self) -> np.ndarray:
        """One record of :data:`SCENE_DTYPE`: every scene-wide number the step reads, the
        angles as the cosines its comparisons use."""
        from sim.integrators import METHODS
        from sim.stability import KICKS

        sim, cp, body = self.sim, self.contact, self.body
        ter = body.terrain
        rec = np.zeros(1, SCENE_DTYPE)
        r = rec[0]
        r["dt_s"] = sim.dt_s
        # max_substep = 0 is the seed's plain step: no sub-steps at all, striking or not
        r["impact_substeps"] = (0 if sim.impact_substep_s <= 0.0 or sim.max_substep_s <= 0.0
                                else max(1, int(math.ceil(sim.dt_s / sim.impact_substep_s - 1e-9))))
        r["method"] = METHODS[sim.integrator]
        r["vertical_one_step"] = sim.vertical_one_step
        r["energy_guard"] = sim.energy_guard
        r["linear_model"] = sim.integrator in KICKS
        r["crash_speed_mps"] = cp.crash_speed_mps
        r["crash_speed2"] = cp.crash_speed_mps ** 2
        r["bounce_speed_mps"] = cp.bounce_speed_mps
        r["settle_lin2"] = cp.settle_linear_vel_mps ** 2
        r["settle_ang2"] = cp.settle_angular_vel_radps ** 2
        r["cos_settle_tilt"] = cp.cos_settle_tilt
        r["cos_tipped"] = cp.cos_tipped
        r["tipped_rest_rad"] = math.radians(cp.tipped_rest_deg)
        r["damping_ratio"] = cp.damping_ratio
        r["absorb_damping_ratio"] = cp.absorb_damping_ratio
        r["friction_static"] = cp.friction_static
        r["friction_kinetic"] = cp.friction_kinetic
        r["stick_speed_mps"] = cp.stick_speed_mps
        r["align_on_touchdown"] = cp.align_on_touchdown
        # settle_time = 0 is the seed's instantaneous rule: the first tick they hold
        r["settle_time_s"] = cp.settle_time_s
        r["seed_friction"] = cp.friction_model == "seed"
        r["radial_normal"] = cp.surface_normal == "radial"
        r["body_radius_m"] = body.radius_m
        r["gm_m3ps2"] = body.gm_m3ps2
        r["omega_radps"] = body.omega_radps
        r["omega2"] = body.omega_radps ** 2
        r["surface_gravity_mps2"] = body.surface_gravity_mps2
        r["base_height_m"] = ter.base_height_m
        # the highest the bumps raise the ground; a slope adds its plane's height under the ship
        # (sim.step.near_ground)
        r["terrain_max_m"] = ter.base_height_m + sum(max(h, 0.0) for h in ter.bump_height_m)
        r["slope_tan"] = math.hypot(*ter.gradient)
        r["bandwidth_radps"] = self.controller.bandwidth_radps
        return rec

    @cached_property
    def terrain(self) -> np.ndarray:
        """The terrain as the step reads it: one record of sim.contact.TERRAIN_DTYPE."""
        return self.body.terrain.record()
