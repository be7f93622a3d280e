"""Parameters: everything the step reads but never changes. Frozen; arrays are per ship, shape (N,...).
Their fields and records are derived from the settings (sim.settings), declared once there.

Kept apart from :mod:`sim.state` (what changes every tick), as in brax's ``base.py``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, make_dataclass
from functools import cached_property
from typing import Any, ClassVar, NamedTuple

import numpy as np

from touchdown.sim import trig
from touchdown.sim.settings import in_scene, landing_in, record_type
from touchdown.sim.state import Batch


def _section(cls_name: str, name: str, doc: str, base: type, extra: tuple = ()) -> type:
    """The frozen dataclass of one section of the parameters: a field per setting landing in it
    (sim.settings, its default the setting's), then ``extra`` fields, with ``base``'s derived
    properties."""
    fields_ = [(s.field, Any, field(default=s.param_default)) for s in landing_in(name)]
    return make_dataclass(cls_name, fields_ + list(extra), bases=(base,), frozen=True,
                          namespace={"__doc__": doc, "__module__": __name__})


def substeps(dt_s: float, step_s: float) -> int:
    """The equal sub-steps of at most ``step_s`` a tick of ``dt_s`` takes, ceil(dt / step)
    (a hair over a whole number counts as it); 0 where ``step_s`` is 0 (none)."""
    if step_s <= 0.0:
        return 0
    return max(1, int(math.ceil(dt_s / step_s - 1e-9)))


class _SimDerived:
    @cached_property
    def n_ticks(self) -> int:
        return int(math.ceil(self.duration_s / self.dt_s - 1e-9))

    @cached_property
    def n_fine_substeps(self) -> int:
        return substeps(self.dt_s, self.max_substep_s) or 1


class _ContactDerived:
    @cached_property
    def cos_settle_tilt(self) -> float:
        return trig.cos(math.radians(self.settle_tilt_deg))

    @cached_property
    def cos_tipped(self) -> float:
        return trig.cos(math.radians(self.tipped_angle_deg))

    @cached_property
    def cos_tipped_rest(self) -> float:
        return trig.cos(math.radians(self.tipped_rest_deg))

    @cached_property
    def omega_radps(self) -> float:
        """Natural frequency of the contact spring, sqrt(k/m), rad/s."""
        return math.sqrt(self.stiffness_per_kg)


SimParams = _section("SimParams", "sim", """How time advances (sim.settings: the ``sim`` keys and ``duration``).

    ``dt_s``: the tick. ``max_substep_s``: ships in or near contact are stepped in
    ``ceil(dt / max_substep)`` equal sub-steps (0 = never sub-step, the seed's behaviour); ships
    far from the ground take the whole tick in one step. ``integrator``: a name in
    :data:`sim.integrators.METHODS`.""", _SimDerived)
ContactParams = _section("ContactParams", "contact", """The seed's Configuration table (same names without
    ``contact_``, units in the names) plus the settings SEED-NOTES adds (sim.settings: the
    ``contact`` keys). Angles are also given as cosines for the step's exact comparisons.""",
                         _ContactDerived)


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
        from touchdown.sim.contact import TERRAIN_DTYPE
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
        """(dh/d(east), dh/d(north)) of the uniform slope: -tan(slope) (sin(az), cos(az))
        (sim.trig, once, when the scene is built)."""
        if self.slope_deg == 0.0:
            return 0.0, 0.0
        t = trig.tan(math.radians(self.slope_deg))
        cos_az, sin_az = trig.cos_sin(math.radians(self.slope_azimuth_deg))
        return -t * sin_az, -t * cos_az

    @property
    def flat(self) -> bool:
        """No bumps and no slope: the ground is the sphere of radius R + base_height."""
        return not self.bump_height_m and self.slope_deg == 0.0


class _BodyDerived:
    @cached_property
    def omega_radps(self) -> float:
        """Spin rate about +z; 0 when ``rotation_period_s`` is 0."""
        return 0.0 if self.rotation_period_s == 0.0 else 2.0 * math.pi / self.rotation_period_s

    @cached_property
    def surface_gravity_mps2(self) -> float:
        return self.gm_m3ps2 / (self.radius_m * self.radius_m)


BodyParams = _section("BodyParams", "body", """The planet or moon: a point mass rotating about the inertial +z
    axis (sim.settings: the ``body`` keys), and its terrain.""", _BodyDerived,
                      (("terrain", Terrain, field(default_factory=Terrain)),))


SHIP_DTYPE = np.dtype([record_type(s) for s in landing_in("ships")] + [
    ("contact_omega_radps", "f8"),  # sqrt(k / m): the contact's natural frequency
    ("n_substeps", "i8"),  # sub-steps a tick near the ground, from this ship's own modes
], align=True)
"""Per-ship constants: the ``ships`` settings that land in it (sim.settings, in its order), then
what the scenario derives per ship. Its bytes are a live service's checkpoints (service.redis_io):
the layout is kept (tests/test_settings.py)."""


@dataclass(frozen=True, eq=False)
class ShipParams(Batch):
    """Per-ship constants: a record per ship (:data:`SHIP_DTYPE`), and the ships' names."""

    ship_id: tuple[str, ...] = ()
    player_id: tuple[str, ...] = ()
    DTYPE: ClassVar[np.dtype] = SHIP_DTYPE
    LABELS: ClassVar[tuple[str, ...]] = ("ship_id", "player_id")


ControllerParams = _section("ControllerParams", "controller", """Attitude hold: a critically damped PD law per
    body axis, saturated at ``max_rcs_torque`` (sim.settings: the ``controller`` keys).

    tau = -I (bandwidth^2 err + 2 bandwidth omega_rel).""", object)


#: What Params.scene derives from the parameters (the rest of SCENE_DTYPE is the settings the
#: step reads as they are: sim.settings.in_scene).
_SCENE_DERIVED = [
    ("method", "i8"), ("impact_substeps", "i8"), ("coarse_substeps", "i8"), ("crash_speed2", "f8"),
    ("settle_lin2", "f8"), ("settle_ang2", "f8"), ("cos_settle_tilt", "f8"), ("cos_tipped", "f8"),
    ("tipped_rest_rad", "f8"), ("cos_tipped_rest", "f8"), ("omega_radps", "f8"), ("omega2", "f8"),
    ("surface_gravity_mps2", "f8"), ("terrain_max_m", "f8"), ("slope_tan", "f8"),
]
SCENE_DTYPE = np.dtype([record_type(s) for s in in_scene()] + _SCENE_DERIVED, align=True)
"""The scene's constants as the compiled step reads them (one record; derived from Params)."""


class Records(NamedTuple):
    """A scene's parameters as the compiled step reads them (Params.records, sim.step.step_ticks)."""

    scene: np.ndarray  # one record of SCENE_DTYPE
    terrain: np.ndarray  # one record of sim.contact.TERRAIN_DTYPE
    ships: np.ndarray  # a record of SHIP_DTYPE per ship


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
        from touchdown.sim.integrators import METHODS

        sim, cp, body = self.sim, self.contact, self.body
        ter = body.terrain
        rec = np.zeros(1, SCENE_DTYPE)
        r = rec[0]
        sections = {"sim": sim, "contact": cp, "body": body, "terrain": ter,
                    "controller": self.controller}
        for s in in_scene():
            r[s.scene] = getattr(sections[s.section], s.field)
        r["method"] = METHODS[sim.integrator]
        # max_substep = 0 is the seed's plain step: no sub-steps at all, striking or not
        r["impact_substeps"] = (0 if sim.max_substep_s <= 0.0
                                else substeps(sim.dt_s, sim.impact_substep_s))
        # sim.coarse_substep: the sub-steps a quiet contact tick takes (0: max_substep's always)
        r["coarse_substeps"] = (0 if sim.max_substep_s <= 0.0
                                else substeps(sim.dt_s, sim.coarse_substep_s))
        r["crash_speed2"] = cp.crash_speed_mps * cp.crash_speed_mps
        r["settle_lin2"] = cp.settle_linear_vel_mps * cp.settle_linear_vel_mps
        r["settle_ang2"] = cp.settle_angular_vel_radps * cp.settle_angular_vel_radps
        r["cos_settle_tilt"] = cp.cos_settle_tilt
        r["cos_tipped"] = cp.cos_tipped
        r["tipped_rest_rad"] = math.radians(cp.tipped_rest_deg)
        r["cos_tipped_rest"] = cp.cos_tipped_rest
        r["omega_radps"] = body.omega_radps
        r["omega2"] = body.omega_radps * body.omega_radps
        r["surface_gravity_mps2"] = body.surface_gravity_mps2
        # the highest the bumps raise the ground; a slope adds its plane's height under the ship
        # (sim.phases.near_ground)
        r["terrain_max_m"] = ter.base_height_m + sum(max(h, 0.0) for h in ter.bump_height_m)
        gx, gy = ter.gradient
        r["slope_tan"] = math.sqrt(gx * gx + gy * gy)
        return rec

    @cached_property
    def terrain(self) -> np.ndarray:
        """The terrain as the step reads it: one record of sim.contact.TERRAIN_DTYPE."""
        return self.body.terrain.record()

    @property
    def records(self) -> "Records":
        """The scene, the terrain and the ships as the compiled step reads them."""
        return Records(self.scene, self.terrain, self.ships.rows)
