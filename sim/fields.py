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

from touchdown.sim.enums import HoldMode


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
    # -- the inputs (record "inputs"): what a command gives a ship (:data:`INPUTS`)
    limits: tuple[float, float] | None = None  # each number's range (lo, hi), bounds included
    choices: type | None = None  # an enum with ``label``/``from_label``: the record holds its value
    #: the names a Redis command carries its value under (service.kinds; SPEC.md section 5)
    wire: tuple[str, ...] = ()

    @property
    def in_log(self) -> str:
        return self.log_name or self.name

    @property
    def labels(self) -> tuple[str, ...]:
        """An input's choices, by label, in the order of their values."""
        return tuple(m.label for m in self.choices) if self.choices is not None else ()

    @property
    def default(self):
        """An input's value when a command leaves it out: zero (the first choice: hold off)."""
        if self.choices is not None:
            return int(next(iter(self.choices)))
        return 0.0 if self.per_ship == 1 else (0.0,) * self.per_ship

    def value(self, x):
        """An input's value as a Command holds it (a tuple for a vector, an int for a choice)
        from a record's, a proto's or a caller's."""
        if self.choices is not None:
            return int(x)
        return x if self.per_ship == 1 else tuple(x)


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
    Field("settle_for_s", "state", "f8", 1, "s",
          "how long the settle thresholds have held, from the instant they began to",
          keyframe_only=True),
    Field("settle_margin", "state", "f8", 1, "",
          "the settle thresholds' smallest margin at the tick's end (> 0: all hold)",
          keyframe_only=True),
    Field("hold_force_n", "state", "f8", 12, "N",
          "each holding foot's static friction over the last step, inertial (x, y, z per foot)",
          keyframe_only=True),
    Field("pivot_rate_radps", "state", "f8", 1, "rad/s",
          "tipped only: rate of turn about the pivot (+ = toppling)", keyframe_only=True),
    Field("pin_pos_bf_m", "state", "f8", 3, "m",
          "pinned ships: centre of mass, body-fixed frame", keyframe_only=True),
    Field("pin_quat_bf", "state", "f8", 4, "",
          "pinned ships: attitude relative to the body-fixed frame", keyframe_only=True),
    Field("pin_pivot_bf_m", "state", "f8", 3, "m",
          "tipped only: the pivot (lowest foot), body-fixed frame", keyframe_only=True),
    # the commands in force (applied in the step into the tick): the inputs, declared here once
    # (:data:`INPUTS`); a recorded command (sim.timeline.Command: its fields and checks), the
    # scenario's ``ships.inputs.*`` settings, the step's command records (sim.state.COMMAND_DTYPE,
    # sim.step.apply_commands), World.commands, the log's Command (proto/touchdown.proto: held to
    # this table by tests/test_command_table.py) and the service's commands (service.kinds) are
    # derived from these rows
    Field("throttle", "inputs", "f8", 1, "", "0..1 of max_thrust", log_name="input_throttle",
          limits=(0.0, 1.0), wire=("value",)),
    Field("rcs", "inputs", "f8", 3, "",
          "-1..1 of max_rcs_torque per body axis; 0 leaves the axis to the hold",
          log_name="input_rcs", limits=(-1.0, 1.0), wire=("x", "y", "z")),
    Field("hold", "inputs", "i1", 1, "", "HoldMode value", log_name="input_hold",
          choices=HoldMode, wire=("mode",)),
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

#: the inputs a command gives a ship, in the order a command (sim.timeline.Command) and
#: World.commands take them
INPUTS: tuple[Field, ...] = tuple(f for f in FIELDS if f.record == "inputs")

#: the quantities of the log's TickBatch by their field name there
BY_LOG_NAME: dict[str, Field] = {f.in_log: f for f in FIELDS}

# -- the log's formats ------------------------------------------------------------------------------
# THE RULE: a new per-tick field (a row above) bumps LOG_FORMAT, and its format's field lists are
# added below as literals, frozen from then on. Every older format stays readable: a log holds
# exactly its own format's fields, and a reader checks a tick against that format's lists, never
# against today's table (tests/test_log_format.py: one test per format, and one that today's lists
# are what the table derives). So does a header field that changes which ticks hold what (5: the
# keyframes' phase, logs.header), and a change to how a replay rebuilds what the log holds (6:
# an event's tilt, logs.header.tilt_deg).

#: the format today's logs are written in (logs.header)
LOG_FORMAT = 6

#: the fields on every tick of a log, by format
EVERY_TICK_BY_FORMAT: dict[int, tuple[str, ...]] = {
    # touchdown 0.2: velocities on keyframes only; no energy_guard_j
    1: ("surface_state", "pos_m", "quat", "mass_kg", "fuel_kg", "altitude_m", "penetration_m",
        "peak_penetration_m", "cos_tilt", "v_radial_mps", "v_tangential_mps", "normal_force_n",
        "friction_force_n", "throttle", "rcs_torque_body_nm", "input_throttle", "input_rcs",
        "input_hold"),
    # touchdown 0.3: velocities and the guard's energy on every tick; sliding per foot
    2: ("surface_state", "pos_m", "vel_mps", "quat", "omega_body_radps", "mass_kg", "fuel_kg",
        "input_throttle", "input_rcs", "input_hold", "altitude_m", "penetration_m",
        "peak_penetration_m", "cos_tilt", "v_radial_mps", "v_tangential_mps", "normal_force_n",
        "friction_force_n", "throttle", "rcs_torque_body_nm", "energy_guard_j"),
    # touchdown 0.5: ships named by key (they join and leave)
    3: ("surface_state", "pos_m", "vel_mps", "quat", "omega_body_radps", "mass_kg", "fuel_kg",
        "input_throttle", "input_rcs", "input_hold", "altitude_m", "penetration_m",
        "peak_penetration_m", "cos_tilt", "v_radial_mps", "v_tangential_mps", "normal_force_n",
        "friction_force_n", "throttle", "rcs_torque_body_nm", "energy_guard_j", "ship_key"),
    # touchdown 0.6: as 3 (its new fields are on keyframes)
    4: ("surface_state", "pos_m", "vel_mps", "quat", "omega_body_radps", "mass_kg", "fuel_kg",
        "input_throttle", "input_rcs", "input_hold", "altitude_m", "penetration_m",
        "peak_penetration_m", "cos_tilt", "v_radial_mps", "v_tangential_mps", "normal_force_n",
        "friction_force_n", "throttle", "rcs_torque_body_nm", "energy_guard_j", "ship_key"),
    # touchdown 0.7: as 4 (the header's keyframe_phase moves the keyframes, not the fields)
    5: ("surface_state", "pos_m", "vel_mps", "quat", "omega_body_radps", "mass_kg", "fuel_kg",
        "input_throttle", "input_rcs", "input_hold", "altitude_m", "penetration_m",
        "peak_penetration_m", "cos_tilt", "v_radial_mps", "v_tangential_mps", "normal_force_n",
        "friction_force_n", "throttle", "rcs_torque_body_nm", "energy_guard_j", "ship_key"),
    # touchdown 0.8: as 5 (an event's tilt_deg the same bits on every machine: logs.header)
    6: ("surface_state", "pos_m", "vel_mps", "quat", "omega_body_radps", "mass_kg", "fuel_kg",
        "input_throttle", "input_rcs", "input_hold", "altitude_m", "penetration_m",
        "peak_penetration_m", "cos_tilt", "v_radial_mps", "v_tangential_mps", "normal_force_n",
        "friction_force_n", "throttle", "rcs_torque_body_nm", "energy_guard_j", "ship_key"),
}

#: the fields on keyframe ticks only, by format (all of them or none on a tick)
KEYFRAME_BY_FORMAT: dict[int, tuple[str, ...]] = {
    1: ("absorbing", "sliding", "settle_ticks", "pivot_rate_radps", "pin_pos_bf_m", "pin_quat_bf",
        "pin_pivot_bf_m"),
    2: ("absorbing", "sliding", "settle_ticks", "pivot_rate_radps", "pin_pos_bf_m", "pin_quat_bf",
        "pin_pivot_bf_m"),
    3: ("absorbing", "sliding", "settle_ticks", "pivot_rate_radps", "pin_pos_bf_m", "pin_quat_bf",
        "pin_pivot_bf_m"),
    # touchdown 0.6: how long the settle thresholds have held, and their margin (the landing's
    # instant inside its tick); the holding feet's friction (carried into the next step)
    4: ("absorbing", "sliding", "settle_ticks", "settle_for_s", "settle_margin", "hold_force_n",
        "pivot_rate_radps", "pin_pos_bf_m", "pin_quat_bf", "pin_pivot_bf_m"),
    5: ("absorbing", "sliding", "settle_ticks", "settle_for_s", "settle_margin", "hold_force_n",
        "pivot_rate_radps", "pin_pos_bf_m", "pin_quat_bf", "pin_pivot_bf_m"),
    6: ("absorbing", "sliding", "settle_ticks", "settle_for_s", "settle_margin", "hold_force_n",
        "pivot_rate_radps", "pin_pos_bf_m", "pin_quat_bf", "pin_pivot_bf_m"),
}


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
