"""Every per-ship quantity a tick holds, declared once: its name, unit, numbers per ship, the record
it lives in, whether the log writes it only on keyframes, its TickBatch field and its name in
``export``.

The step's record dtypes (sim.state: STATE_DTYPE, OUTPUTS_DTYPE, INPUTS_DTYPE) are built from this
table, in its order; the log's codec, its checks, verify's report, export, the view and the tests
derive what they need from it (:data:`BY_LOG_NAME`, :func:`keyframe_only`, ...). The TickBatch
message in ``proto/touchdown.proto`` is the log's schema, written schema-first: a test holds it
and this table to each other, field by field.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Field:
    name: str  # in its record (sim.state)
    record: str  # "state", "outputs", "inputs"
    dtype: str  # numpy type of one number in the record
    per_ship: int  # numbers per ship (1, 3 for vectors, 4 for quaternions and per-foot flags)
    unit: str  # SI, "" for pure numbers, flags and enums
    doc: str
    keyframe_only: bool = False  # the log writes it only on keyframe ticks
    log_name: str = ""  # its TickBatch field ("" = the same as name)
    export: str = ""  # its key in ``export``'s rows ("" = not exported as it is)

    @property
    def in_log(self) -> str:
        return self.log_name or self.name


FIELDS: tuple[Field, ...] = (
    # the state (what the step carries from tick to tick)
    Field("surface_state", "state", "i1", 1, "", "SurfaceState value", export="state"),
    Field("pos_m", "state", "f8", 3, "m", "centre of mass, inertial, body-centred"),
    Field("vel_mps", "state", "f8", 3, "m/s", "velocity, inertial"),
    Field("quat", "state", "f8", 4, "", "attitude (w, x, y, z), body -> inertial"),
    Field("omega_body_radps", "state", "f8", 3, "rad/s",
          "angular velocity in the body frame (inertial rate)"),
    Field("mass_kg", "state", "f8", 1, "kg", "wet mass", export="mass"),
    Field("fuel_kg", "state", "f8", 1, "kg", "fuel left", export="fuel_mass"),
    Field("absorbing", "state", "?", 1, "",
          "this contact began slower than bounce_speed (SEED-NOTES 1)", keyframe_only=True),
    Field("sliding", "state", "u1", 4, "",
          "1 where a foot's friction was kinetic at the last sub-step's end", keyframe_only=True),
    Field("settle_ticks", "state", "i8", 1, "",
          "consecutive ticks the settle thresholds have held", keyframe_only=True),
    Field("pivot_rate_radps", "state", "f8", 1, "rad/s",
          "tipped only: rate of turn about the pivot (+ = toppling)", keyframe_only=True),
    Field("pin_pos_bf_m", "state", "f8", 3, "m",
          "pinned ships: centre of mass, body-fixed frame", keyframe_only=True),
    Field("pin_quat_bf", "state", "f8", 4, "",
          "pinned ships: attitude relative to the body-fixed frame", keyframe_only=True),
    Field("pin_pivot_bf_m", "state", "f8", 3, "m",
          "tipped only: the pivot (lowest foot), body-fixed frame", keyframe_only=True),
    # the commands in force (applied in the step into the tick)
    Field("throttle", "inputs", "f8", 1, "", "0..1 of max_thrust", log_name="input_throttle"),
    Field("rcs", "inputs", "f8", 3, "",
          "-1..1 of max_rcs_torque per body axis; 0 leaves the axis to the hold",
          log_name="input_rcs"),
    Field("hold", "inputs", "i1", 1, "", "HoldMode value", log_name="input_hold"),
    # what a tick reports
    Field("altitude_m", "outputs", "f8", 1, "m",
          "lowest foot above the terrain under it (negative = penetrating)", export="altitude"),
    Field("penetration_m", "outputs", "f8", 1, "m", "max(0, -altitude)", export="penetration"),
    Field("peak_penetration_m", "outputs", "f8", 1, "m",
          "deepest penetration at any sub-step of the tick (>= 0)", export="peak_penetration"),
    Field("cos_tilt", "outputs", "f8", 1, "", "cosine of the long axis' angle from local up"),
    Field("v_radial_mps", "outputs", "f8", 1, "m/s", "+ = up, relative to the surface",
          export="v_radial"),
    Field("v_tangential_mps", "outputs", "f8", 1, "m/s", "speed along the surface, relative to it",
          export="v_tangential"),
    Field("normal_force_n", "outputs", "f8", 1, "N", "the ground's push, magnitude",
          export="normal_force"),
    Field("friction_force_n", "outputs", "f8", 1, "N", "friction, magnitude",
          export="friction_force"),
    Field("throttle", "outputs", "f8", 1, "", "applied (0 without fuel)", log_name="throttle",
          export="throttle"),
    Field("rcs_torque_body_nm", "outputs", "f8", 3, "N m", "applied, body frame"),
    Field("energy_guard_j", "outputs", "f8", 1, "J",
          "energy the passivity guard removed this tick (sim.step)", export="energy_guard_j"),
)

#: the quantities of the log's TickBatch by their field name there
BY_LOG_NAME: dict[str, Field] = {f.in_log: f for f in FIELDS}


def of_record(record: str) -> tuple[Field, ...]:
    return tuple(f for f in FIELDS if f.record == record)


def record_dtype(record: str):
    """The numpy record dtype of ``record`` ("state", "outputs", "inputs"): its fields in this
    table's order, aligned (the compiled step reads them by name)."""
    import numpy as np
    return np.dtype([(f.name, f.dtype) if f.per_ship == 1 else (f.name, f.dtype, (f.per_ship,))
                     for f in of_record(record)], align=True)


def keyframe_only() -> tuple[str, ...]:
    """The log fields written only on keyframe ticks."""
    return tuple(f.in_log for f in FIELDS if f.keyframe_only)


def per_ship(log_name: str) -> int:
    """Numbers per ship of a TickBatch field (the ships' keys: one)."""
    f = BY_LOG_NAME.get(log_name)
    return 1 if f is None else f.per_ship
