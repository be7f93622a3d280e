"""Every scenario key, declared once: its kind, default, unit, range, and where it lands in the
parameters. Pure Python (no numba): the scenario's checks (sim.scenario), the parameter dataclasses,
the per-ship record and the scene record the step reads (sim.params) are all derived from
:data:`SETTINGS`.

A new setting is one row here (and the kernel that reads it): with ``dest`` it becomes a field of
its parameters (``"contact.friction_static"``: ``ContactParams.friction_static``;
``"ships.mass0_kg"``: a field of ``SHIP_DTYPE``), with ``scene`` a field of ``SCENE_DTYPE``
copied as it is. A setting that is computed before the step reads it (a cosine, a square) is
derived in ``Params.scene`` from its parameter.

Model choices are enums (:class:`FrictionModel`, :class:`SurfaceNormal`, :class:`Integrator`)
whose lower-case names are the scenario's strings; the step compares their values.
"""
from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from typing import Any

from touchdown.sim import constants as C
from touchdown.sim.fields import INPUTS as _INPUTS


class _Labelled(IntEnum):
    """An enum whose scenario string is its name in lower case. Values live in records: never
    renumber."""

    @property
    def label(self) -> str:
        return self.name.lower()

    @classmethod
    def from_label(cls, label: str):
        return cls[label.upper()]

    @classmethod
    def labels(cls) -> tuple[str, ...]:
        return tuple(m.label for m in cls)


class FrictionModel(_Labelled):
    """``contact.friction_model``: Coulomb's law at each foot (MODEL-NOTES 38), or the seed's
    velocity reset at the centre of mass (sim.friction.seed)."""

    COULOMB = 0
    SEED = 1


class SurfaceNormal(_Labelled):
    """``contact.surface_normal``: the terrain's normal under each foot, or the seed's local
    radial whatever the slope."""

    TERRAIN = 0
    RADIAL = 1


class LandedModel(_Labelled):
    """``contact.landed``: what landed means. ``rest`` (MODEL-NOTES 45): a ship lands only at rest
    in a stable equilibrium (the settle thresholds, the centre of mass over the footprint, and too
    little energy to pass the lowest edge of its footprint), with neither engine nor RCS firing;
    it is pinned while it stays so, and is back in contact (the physics decides) as soon as the
    player's thrust or RCS acts. ``attached``: the seed's "stable on surface, attached" as 0.7 had
    it: the settle thresholds and the footprint alone, pinned until the engine lifts it off."""

    REST = 0
    ATTACHED = 1


class TippedModel(_Labelled):
    """``contact.tipped_model``: how a tipped ship moves. ``full``: the full model on its feet, as
    any ship in contact (MODEL-NOTES 48), until its hull meets the ground at ``tipped_rest_deg``,
    where it rests, pinned, until the RCS fires; ``pivot``: 0.7's pivot model, a rotation about
    the pivot foot that keeps only the torque's part along its axis (sim.pivot)."""

    FULL = 0
    PIVOT = 1


class Integrator(_Labelled):
    """``sim.integrator``: the method, by its code inside the kernels (sim.integrators)."""

    EXPLICIT_EULER = 0
    SEMI_IMPLICIT_EULER = 1
    VELOCITY_VERLET = 2
    RK4 = 3
    EXPONENTIAL = 4
    HYBRID = 5


class OnUnstable(_Labelled):
    """``sim.on_unstable``: what a scene whose method and sub-step are unstable for a ship gets."""

    SUBSTEP = 0
    ERROR = 1
    ALLOW = 2


#: a key that must be given (no default)
REQUIRED = object()


@dataclass(frozen=True)
class Setting:
    """One scenario key.

    ``key``: its dotted path (``ships.`` for each ship's table, ``ships.initial.``,
    ``ships.inputs.`` for each entry, ``body.terrain.bumps.`` for each bump). ``kind``: ``float``,
    ``float?`` (a number or none), ``str``, ``bool``, ``vec3``, ``table``, ``list``. ``default``:
    its value when left out (:data:`REQUIRED`: it must be given; ``None``: resolved by the scenario
    from others, ``fallback`` then being the parameter's default). ``lo``/``hi``: its range
    (``lo_open``/``hi_open``: the bound itself excluded); ``choices``: the strings it may be (an
    enum: converted to it in the parameters). ``dest``: the parameter it lands in (``section.field``;
    ``ships.field`` is SHIP_DTYPE's), ``scene``: the SCENE_DTYPE field the step reads it from."""

    key: str
    kind: str
    default: Any
    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    choices: type[_Labelled] | tuple[str, ...] | None = None
    dest: str = ""
    scene: str = ""
    fallback: Any = None
    doc: str = ""

    @property
    def table(self) -> str:
        """The key's table: ``""`` (top level), ``sim``, ``ships``, ``ships.initial``, ..."""
        return self.key.rpartition(".")[0]

    @property
    def name(self) -> str:
        return self.key.rpartition(".")[2]

    @property
    def section(self) -> str:
        return self.dest.partition(".")[0]

    @property
    def field(self) -> str:
        return self.dest.partition(".")[2]

    @property
    def enum(self) -> type[_Labelled] | None:
        return self.choices if isinstance(self.choices, type) else None

    @property
    def param_default(self) -> Any:
        """The parameter's default (the key's, converted; or ``fallback``)."""
        if self.default is REQUIRED or self.default is None:
            return self.fallback
        return self.to_param(self.default)

    def to_param(self, value: Any) -> Any:
        """The key's checked value as its parameter holds it (an enum's member for its string)."""
        enum = self.enum
        return enum.from_label(value) if enum is not None and isinstance(value, str) else value

    def check(self, x: Any) -> str | None:
        """What is wrong with one checked number or string ``x`` (None: nothing)."""
        if self.choices is not None:
            opts = sorted(self.enum.labels() if self.enum else self.choices)
            return None if x in opts else f"must be one of {', '.join(opts)}; got {x!r}"
        lo, hi = self.lo, self.hi
        if lo is not None and (x < lo or (self.lo_open and x == lo)):
            return f"must be {'>' if self.lo_open else '>='} {lo:g}, got {x:g}"
        if hi is not None and (x > hi or (self.hi_open and x == hi)):
            return f"must be {'<' if self.hi_open else '<='} {hi:g}, got {x:g}"
        return None

    @property
    def checked(self) -> bool:
        return self.choices is not None or self.lo is not None or self.hi is not None


S = Setting


def _input_setting(f) -> Setting:
    """``ships.inputs.NAME``: an input of sim.fields.INPUTS as a scenario gives it (a number, a
    vector or a choice's label), with its range or choices; zero (the first choice) when left
    out."""
    key = f"ships.inputs.{f.name}"
    if f.choices is not None:
        return Setting(key, "str", f.labels[0], choices=f.labels)
    kind = {1: "float", 3: "vec3"}[f.per_ship]
    default = f.default if f.per_ship == 1 else list(f.default)
    return Setting(key, kind, default, f.unit, *f.limits)


#: Every scenario key. Every number has a physically meaningful range (MODEL-NOTES 27, issue 13):
#: a value outside it cannot describe a ship, a body or a run, and is refused before anything is
#: computed with it.
SETTINGS: tuple[Setting, ...] = (
    # -- the top level
    S("name", "str", REQUIRED, doc="the scenario's name"),
    S("duration", "float", REQUIRED, "s", 0.0, 1e7, lo_open=True, dest="sim.duration_s",
      fallback=30.0, doc="how long the run lasts"),
    S("description", "str", "", doc="one line, shown by `touchdown scenarios`"),
    # -- sim: how time advances
    S("sim.dt", "float", 0.05, "s", 1e-4, 1.0, dest="sim.dt_s", scene="dt_s", doc="the tick"),
    S("sim.integrator", "str", "hybrid", choices=Integrator.labels(), dest="sim.integrator",
      doc="the method (sim.settings.Integrator): the parameters keep its name (the log records "
          "it), the scene its code (Params.scene's method)"),
    S("sim.max_substep", "float", 0.025, "s", 0.0, 1.0, dest="sim.max_substep_s",
      doc="ships in or near contact are stepped in ceil(dt / max_substep) equal sub-steps (0: "
          "never sub-step, the seed's behaviour); ships far from the ground take the whole tick"),
    S("sim.impact_substep", "float", 0.005, "s", 0.0, 1.0, dest="sim.impact_substep_s",
      doc="a ship that is not purely vertical takes sub-steps of at most this while it strikes "
          "the ground or rebounds (sim.phases.striking; 0: max_substep everywhere)"),
    S("sim.coarse_substep", "float", 0.05, "s", 0.0, 1.0, dest="sim.coarse_substep_s",
      doc="a ship in contact, not striking, takes sub-steps of at most this (ceil(dt / "
          "coarse_substep) a tick) instead of max_substep's where nothing the finer ones resolve "
          "can happen within them: no foot near starting or stopping to press, no sliding foot "
          "near its stop, not near rest, its rocking mode's w h under 0.5 (sim.flight.coarse_tick; "
          "rk4 and Coulomb's law only; 0: max_substep's always, 0.8's; MODEL-NOTES 57)"),
    S("sim.stiff_substep", "float", 0.001, "s", 0.0, 1.0, dest="sim.stiff_substep_s",
      scene="stiff_substep_s",
      doc="a ship is stepped in pieces no longer than the time a sliding foot's friction would "
          "take to stop it, and no shorter than this, while that friction is stiff (it could "
          "stop the foot within the sub-step while the ship's turning keeps it slipping: "
          "sim.flight.stiff_feet; outside an impact's sub-steps only for feet it would take "
          "this or longer to stop; 0: the sub-step whole, 0.8's behaviour)"),
    S("sim.on_unstable", "str", "substep", choices=OnUnstable,
      doc="an unstable method and step: sub-step further, refuse, or run as asked"),
    S("sim.vertical_one_step", "bool", True, dest="sim.vertical_one_step",
      scene="vertical_one_step",
      doc="with a method exact on the spring, purely vertical ships take one step per tick"),
    S("sim.vertical_path", "bool", True, dest="sim.vertical_path", scene="vertical_path",
      doc="a purely vertical ship near the ground (one exact step a tick) takes a path of its "
          "own: the spring-damper's exact flow, the feet's onset the root of the ballistic "
          "flow, no friction solve (sim.flight.vertical_flight); false: free_flight's general "
          "pieces and friction, the session-16 main's, bit for bit (MODEL-NOTES 65)"),
    S("sim.flow_release", "bool", True, dest="sim.flow_release", scene="flow_release",
      doc="with the exponential method, an absorbed foot's release located inside a step "
          "(sim.flight.to_event) is the spring-damper flow's own: the trials keep no pull on past "
          "it; false: the pull kept on through them as rk4's stages need, which the flow's "
          "closing kick took as a damper's pull after the release (a liftoff under thrust 25% "
          "slow), the session-17 main's bits (MODEL-NOTES 66)"),
    S("sim.coarse_release", "bool", True, dest="sim.coarse_release", scene="coarse_release",
      doc="a quiet contact tick's coarse sub-step (sim.coarse_substep) is not refused for a "
          "pressing foot near its release whose force still pushes, where another pressing "
          "foot is far from its own: the release is located inside the sub-step (sim.flight."
          "to_event), as in the finer ones; a clear foot near its onset still refuses it; "
          "false: every pressing foot's gap over (|x'| + 0.2 m/s) h, the session-18 main's "
          "bits (MODEL-NOTES 68)"),
    S("sim.coarse_held", "float", 0.1, "s", 0.0, 1e3, dest="sim.coarse_held_s",
      scene="coarse_held_s",
      doc="a ship in contact whose settle thresholds have held for this long at the tick's "
          "start (its run of samples begun: the instant they began to hold is found), and "
          "hold there by over a quarter of each (sim.flight.COARSE_HELD_MARGIN), takes the "
          "coarse sub-step (sim.coarse_substep) though it is near rest, where the rest of "
          "sim.flight.coarse_tick allows it; 0: never, main's bits before it (the session-19 "
          "main's; MODEL-NOTES 69)"),
    S("sim.coarse_when_clear", "bool", True, dest="sim.coarse_when_clear",
      scene="coarse_when_clear",
      doc="in a tick of impact sub-steps, a flying ship whose feet cannot reach the ground "
          "within a max_substep takes it whole (sim.flight.clear_within; on a plane slope); "
          "false: every sub-step of the tick at impact_substep, 0.8's (MODEL-NOTES 54)"),
    S("sim.tight_reach", "bool", True, dest="sim.tight_reach", scene="tight_reach",
      doc="a flying ship is out of its feet's reach of the ground this tick (one step, no contact "
          "work: sim.phases.near_ground) by its feet's distance from its centre of mass, "
          "sqrt(com_height^2 + leg_radius^2), at any attitude; false: com_height + leg_radius, "
          "0.8's looser bound (MODEL-NOTES 54)"),
    S("sim.clear_tick", "bool", True, dest="sim.clear_tick", scene="clear_tick",
      doc="a flying ship near the ground whose feet cannot reach it within the tick (a bound on "
          "their speed and acceleration: sim.flight.feet_clear; on a plane slope) flies the tick "
          "in one step, as a ship far above does; false: free_flight's sub-steps and contact "
          "evaluations wherever sim.phases.near_ground holds, 0.8's (MODEL-NOTES 63)"),
    S("sim.flying_strike_by_centre", "bool", False, dest="sim.flying_strike_by_centre",
      scene="flying_strike_by_centre",
      doc="a flying ship takes the impact's sub-steps when its centre of mass moves along local "
          "up faster than 1 m/s, as a ship in contact does (0.8's); false: only where a foot can "
          "meet the ground within the tick (sim.phases.striking, MODEL-NOTES 60)"),
    S("sim.carried_try_pairs", "bool", True, dest="sim.carried_try_pairs",
      scene="carried_try_pairs",
      doc="the feet's friction solve, where Gauss-Seidel gives up, tries Newton's iterations "
          "from the impulses carried in (sim.friction._from_carried) for two or three feet, to "
          "its last iteration; false: for three or four feet, given up where its residual grows "
          "tenfold in one (MODEL-NOTES 62's; MODEL-NOTES 64)"),
    S("sim.energy_guard", "bool", True, dest="sim.energy_guard", scene="energy_guard",
      doc="a passive ship's energy never rises over a sub-step (sim.flight.passivity_guard)"),
    # -- contact: the seed's Configuration table, and what SEED-NOTES adds
    S("contact.crash_speed", "float", 50.0, "m/s", 0.0, 1e4, lo_open=True,
      dest="contact.crash_speed_mps", scene="crash_speed_mps"),
    S("contact.bounce_speed", "float", 10.0, "m/s", 0.0, 1e4, dest="contact.bounce_speed_mps",
      scene="bounce_speed_mps", doc="SEED-NOTES 1: slower impacts are taken by the absorbers"),
    S("contact.settle_tilt_deg", "float", 5.0, "deg", 0.0, 90.0, lo_open=True, hi_open=True,
      dest="contact.settle_tilt_deg"),
    S("contact.settle_angular_vel", "float", 0.01, "rad/s", 0.0, 100.0, lo_open=True,
      dest="contact.settle_angular_vel_radps"),
    S("contact.settle_linear_vel", "float", 0.5, "m/s", 0.0, 1e3, lo_open=True,
      dest="contact.settle_linear_vel_mps"),
    S("contact.tipped_angle_deg", "float", 80.0, "deg", 0.0, 180.0, lo_open=True, hi_open=True,
      dest="contact.tipped_angle_deg"),
    S("contact.damping_ratio", "float", 0.3, "", 0.0, 100.0, dest="contact.damping_ratio",
      scene="damping_ratio"),
    S("contact.friction_static", "float", 0.8, "", 0.0, 10.0, dest="contact.friction_static",
      scene="friction_static"),
    S("contact.friction_kinetic", "float", 0.5, "", 0.0, 10.0, dest="contact.friction_kinetic",
      scene="friction_kinetic"),
    S("contact.stick_speed", "float", C.STICK_SPEED_MPS, "m/s", 0.0, 10.0,
      dest="contact.stick_speed_mps", scene="stick_speed_mps",
      doc="a foot slipping slower than this is held by static friction (MODEL-NOTES 39)"),
    S("contact.align_on_touchdown", "bool", True, dest="contact.align_on_touchdown",
      scene="align_on_touchdown"),
    S("contact.settle_time", "float", 0.5, "s", 0.0, 1e4, dest="contact.settle_time_s",
      scene="settle_time_s", doc="SEED-NOTES 3: how long the settle thresholds must hold"),
    S("contact.absorb_damping_ratio", "float", 1.0, "", 0.0, 100.0,
      dest="contact.absorb_damping_ratio", scene="absorb_damping_ratio",
      doc="SEED-NOTES 1: the leg absorbers' damping ratio"),
    S("contact.friction_model", "str", "coulomb", choices=FrictionModel,
      dest="contact.friction_model", scene="friction_model", doc="SEED-NOTES 4"),
    S("contact.tipped_model", "str", "full", choices=TippedModel, dest="contact.tipped_model",
      scene="tipped_model",
      doc="a tipped ship on its feet by the full model (MODEL-NOTES 48), or 0.7's pivot model"),
    S("contact.tipped_rest_deg", "float", 90.0, "deg", 0.0, 180.0, lo_open=True,
      dest="contact.tipped_rest_deg", doc="tilt at which a tipped ship lies on its hull"),
    S("contact.stiffness_per_kg", "float", C.CONTACT_STIFFNESS_PER_KG, "1/s^2", 1e-2, 1e6,
      dest="contact.stiffness_per_kg", doc="the seed's k / m (each ship's default)"),
    S("contact.landed", "str", "rest", choices=LandedModel, dest="contact.landed",
      scene="landed_model",
      doc="landed is a state of rest (MODEL-NOTES 45), or the seed's attached state (0.7's)"),
    S("contact.surface_normal", "str", "terrain", choices=SurfaceNormal,
      dest="contact.surface_normal", scene="surface_normal",
      doc="each foot pushed along the terrain's normal, or radially (the seed's)"),
    # -- body: the planet or moon, a point mass turning about the inertial +z axis
    S("body.name", "str", "Luna", dest="body.name"),
    S("body.radius", "float", C.MOON_RADIUS_M, "m", 10.0, 1e9, dest="body.radius_m",
      scene="body_radius_m"),
    S("body.gm", "float", None, "m^3/s^2", 0.0, 1e22, lo_open=True, dest="body.gm_m3ps2",
      scene="gm_m3ps2", fallback=C.MOON_GM_M3PS2,
      doc="give this or body.surface_gravity (neither: the Moon's)"),
    S("body.surface_gravity", "float", None, "m/s^2", 1e-6, 1e4,
      doc="resolved into body.gm at body.radius"),
    S("body.rotation_period", "float", 0.0, "s", -1e12, 1e12, dest="body.rotation_period_s",
      doc="0: not turning"),
    S("body.terrain", "table", None),
    S("body.terrain.base_height", "float", 0.0, "m", -1e4, 1e4, dest="terrain.base_height_m"),
    S("body.terrain.bumps", "list", [], doc="each lands in the terrain's bump_* fields"),
    S("body.terrain.slope_deg", "float", 0.0, "deg", 0.0, 60.0, dest="terrain.slope_deg",
      doc="a uniform slope through the site (SPEC.md 6)"),
    S("body.terrain.slope_azimuth_deg", "float", 0.0, "deg", -360.0, 360.0,
      dest="terrain.slope_azimuth_deg", doc="the downhill direction, from north toward east"),
    S("body.terrain.bumps.east", "float", 0.0, "m", -1e6, 1e6, dest="terrain.bump_east_m"),
    S("body.terrain.bumps.north", "float", 0.0, "m", -1e6, 1e6, dest="terrain.bump_north_m"),
    S("body.terrain.bumps.radius", "float", REQUIRED, "m", 1e-2, 1e6,
      dest="terrain.bump_radius_m"),
    S("body.terrain.bumps.height", "float", REQUIRED, "m", -1e4, 1e4,
      dest="terrain.bump_height_m"),
    # -- controller: attitude hold
    S("controller.bandwidth", "float", 1.0, "rad/s", 0.0, 100.0, lo_open=True,
      dest="controller.bandwidth_radps", scene="bandwidth_radps"),
    # -- ships: each ship's table (its record: SHIP_DTYPE, in this order)
    S("ships.id", "str", REQUIRED),
    S("ships.player_id", "str", None, doc="default: player-<id>"),
    S("ships.mass", "float", 10000.0, "kg", 1.0, 1e9, dest="ships.mass0_kg",
      doc="wet mass at t = 0"),
    S("ships.fuel_mass", "float", 2000.0, "kg", 0.0, 1e9, dest="ships.fuel0_kg"),
    S("ships.com_height", "float", 3.0, "m", 1e-2, 1e3, dest="ships.com_height_m",
      doc="centre of mass above the feet plane"),
    S("ships.leg_radius", "float", 2.26, "m", 0.0, 1e3, dest="ships.leg_radius_m",
      doc="radius of the landing-leg footprint"),
    S("ships.inertia", "vec3", None, "kg m^2", 1e-6, 1e15, dest="ships.inertia0_kgm2",
      doc="principal moments at t = 0, body frame (z = long axis); default: a uniform cylinder"),
    S("ships.max_thrust", "float", 60000.0, "N", 0.0, 1e10, dest="ships.max_thrust_n",
      doc="main engine, along body +z"),
    S("ships.max_rcs_torque", "float", 20000.0, "N m", 0.0, 1e10, dest="ships.max_rcs_torque_nm",
      doc="per body axis"),
    S("ships.isp", "float", C.DEFAULT_ISP_S, "s", 1.0, 1e5, dest="ships.isp_s"),
    S("ships.rcs_isp", "float", C.DEFAULT_RCS_ISP_S, "s", 1.0, 1e5, dest="ships.rcs_isp_s"),
    S("ships.rcs_arm", "float", 2.0, "m", 1e-3, 1e3, dest="ships.rcs_arm_m",
      doc="lever arm of the RCS thrusters (torque / arm = thrust)"),
    S("ships.stiffness_per_kg", "float", None, "1/s^2", 1e-2, 1e6, dest="ships.stiffness_per_kg",
      doc="the contact spring's k / m (default: contact.stiffness_per_kg; MODEL-NOTES 33)"),
    S("ships.spawn_t", "float", 0.0, "s", 0.0, 1e7, doc="joins the scene (sim.timeline)"),
    S("ships.retire_t", "float?", None, "s", 0.0, 1e7, lo_open=True,
      doc="leaves it (none: never)"),
    S("ships.initial", "table", None),
    S("ships.inputs", "list", []),
    # -- ships.initial: where a ship starts (MODEL-NOTES 27)
    S("ships.initial.state", "str", "flying", choices=("flying", "contact", "landed", "tipped")),
    S("ships.initial.altitude", "float", None, "m", -100.0, 1e7, doc="default: 10 flying, else 0"),
    S("ships.initial.vertical_speed", "float", 0.0, "m/s", -1e4, 1e4),
    S("ships.initial.horizontal_speed", "float", 0.0, "m/s", -1e4, 1e4),
    S("ships.initial.heading_deg", "float", 0.0, "deg", -360.0, 360.0),
    S("ships.initial.yaw_deg", "float", 0.0, "deg", -360.0, 360.0),
    S("ships.initial.tilt_deg", "float", 0.0, "deg", 0.0, 180.0),
    S("ships.initial.angular_velocity", "vec3", [0.0, 0.0, 0.0], "rad/s", -100.0, 100.0),
    S("ships.initial.east", "float", 0.0, "m", -1e6, 1e6),
    S("ships.initial.north", "float", 0.0, "m", -1e6, 1e6),
    # -- ships.inputs: each command of a ship's schedule
    S("ships.inputs.t", "float", REQUIRED, "s", 0.0, 1e7),
    # then the inputs, each as sim.fields.INPUTS declares it (:func:`_input_setting`)
    *(_input_setting(f) for f in _INPUTS),
)
del S

BY_KEY: dict[str, Setting] = {s.key: s for s in SETTINGS}


def in_table(table: str) -> tuple[Setting, ...]:
    """The keys of one table (``""``, ``sim``, ``ships.initial``, ...), in declaration order."""
    return tuple(s for s in SETTINGS if s.table == table)


def landing_in(section: str) -> tuple[Setting, ...]:
    """The settings whose parameter is in ``section`` (``sim``, ``contact``, ``body``,
    ``controller``, ``terrain``, ``ships``), in declaration order."""
    return tuple(s for s in SETTINGS if s.section == section)


def in_scene() -> tuple[Setting, ...]:
    """The settings the step reads as they are, from the scene record."""
    return tuple(s for s in SETTINGS if s.scene)


def record_type(s: Setting) -> tuple:
    """A setting's numpy type in a record: f8 (3 of them for a vector), ? for a flag, i8 for an
    enum's value."""
    if s.enum is not None:
        return (s.scene or s.field, "i8")
    if s.kind == "bool":
        return (s.scene or s.field, "?")
    if s.kind == "vec3":
        return (s.scene or s.field, "f8", (3,))
    return (s.scene or s.field, "f8")
