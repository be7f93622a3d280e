"""Scenarios: a TOML document (SPEC.md section 3) checked key by key and resolved into parameters,
the initial state and the input schedule. Parsing only: reading files is the caller's job.

Every key has a default except ``name``, ``duration``, ``ships`` and each ship's ``id``. Unknown
keys, wrong types, non-finite or out-of-range values raise :class:`ScenarioError`, whose message
names the file and the key (``bounce.toml: ships[0].initial.tilt_deg: ...``).
"""
from __future__ import annotations

import dataclasses
import json
import math
import tomllib
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Callable

from touchdown.sim import constants as C
from touchdown.sim import trig
from touchdown.sim.constants import MAX_BUMPS
from touchdown.sim.errors import TouchdownError
from touchdown.sim.params import (BodyParams, ContactParams, ControllerParams, Params, ShipParams,
    SimParams, Terrain)
from touchdown.sim.settings import REQUIRED, in_table, landing_in
from touchdown.sim.state import Inputs, State
from touchdown.sim.fields import INPUTS as INPUT_FIELDS
from touchdown.sim.timeline import Retire, Spawn, Timeline, command_of


class ScenarioError(TouchdownError, ValueError):
    """A scenario that cannot be run; ``str()`` is one line naming the source and the key."""

    def __init__(self, source: str, key: str, problem: str):
        self.source, self.key, self.problem = source, key, problem
        super().__init__(f"{source}: {key}: {problem}")


# -- key tables: name -> (kind, default, check), one per table of the document -------------------
Check = Callable[[Any], str | None]


def _spec(table: str) -> dict:
    """The keys of one table as the reader checks them (sim.settings, declared once there)."""
    return {s.name: (s.kind, s.default, s.check if s.checked else None) for s in in_table(table)}


TOP = _spec("")
SIM = _spec("sim")
CONTACT = _spec("contact")
BODY = _spec("body")
TERRAIN = _spec("body.terrain")
BUMP = _spec("body.terrain.bumps")
CONTROLLER = _spec("controller")
SHIP = _spec("ships")
INITIAL = _spec("ships.initial")
INPUT = _spec("ships.inputs")


class _Reader:
    def __init__(self, source: str):
        self.source = source

    def fail(self, key: str, problem: str):
        raise ScenarioError(self.source, key, problem)

    def table(self, raw: Any, spec: dict, prefix: str) -> dict:
        """Checks ``raw`` against ``spec``; returns every key, defaults filled in."""
        if not isinstance(raw, dict):
            self.fail(prefix.rstrip(".") or "(top level)", "must be a table")
        for key in sorted(raw):
            if key not in spec:
                self.fail(prefix + key, f"unknown key (known: {', '.join(sorted(spec))})")
        out = {}
        for key, (kind, default, check) in spec.items():
            full = prefix + key
            if key not in raw:
                if default is REQUIRED:
                    self.fail(full, "required key is missing")
                out[key] = default
                continue
            val = self.value(raw[key], kind, full)
            if check is not None and val is not None:
                for x in (val if kind == "vec3" else [val]):
                    problem = check(x)
                    if problem:
                        self.fail(full, problem)
            out[key] = val
        return out

    def value(self, x: Any, kind: str, key: str):
        if kind == "float?":  # a number, or None (JSON's null: a resolved "never")
            return None if x is None else self.value(x, "float", key)
        if kind == "float":
            if isinstance(x, bool) or not isinstance(x, (int, float)):
                self.fail(key, f"must be a number, got {type(x).__name__}")
            try:
                value = float(x)
            except OverflowError:  # an integer past any double
                self.fail(key, "must be a number a double can hold, got an integer of "
                               f"{x.bit_length()} bits")
            if not math.isfinite(value):
                self.fail(key, f"must be finite, got {x}")
            return value
        if kind == "str":
            if not isinstance(x, str):
                self.fail(key, f"must be a string, got {type(x).__name__}")
            return x
        if kind == "bool":
            if not isinstance(x, bool):
                self.fail(key, f"must be true or false, got {type(x).__name__}")
            return x
        if kind == "vec3":
            if not isinstance(x, list) or len(x) != 3:
                self.fail(key, "must be a list of 3 numbers")
            return [self.value(e, "float", f"{key}[{i}]") for i, e in enumerate(x)]
        if kind == "table":
            if not isinstance(x, dict):
                self.fail(key, "must be a table")
            return x
        if kind == "list":
            if not isinstance(x, list):
                self.fail(key, "must be an array of tables")
            return x
        raise AssertionError(kind)


#: the keys of a ship's table that place it in time rather than describe it (Scene.ship drops them)
TIMING_KEYS = ("spawn_t", "retire_t", "inputs")


@dataclass(frozen=True)
class Scene:
    """Everything of a scenario but its ships (``doc``: the resolved document without ``ships``),
    with which a ship's table becomes that ship's parameters and start."""

    doc: dict
    source: str
    #: a ship's table (without its id and player) -> what it parsed to: a live service's
    #: spawns of one class re-parse nothing (bounded: emptied past SHIP_CACHE entries)
    _ships: dict = field(default_factory=dict, compare=False, repr=False)

    def ship(self, spec: dict) -> tuple[ShipParams, State]:
        """One ship's parameters and its state at tick 0 (sim.world turns it to the tick it joins
        at), by the same rules, checks and messages as a scenario's ``[[ships]]`` table."""
        return self._ship(spec, True)

    def ship_params(self, spec: dict) -> ShipParams:
        """One ship's parameters as :meth:`ship` gives them, the ship not placed
        (:func:`parse_params`)."""
        return self._ship(spec, False)[0]

    def _ship(self, spec: dict, place: bool) -> tuple[ShipParams, State | None]:
        table = {k: v for k, v in spec.items() if k not in TIMING_KEYS}
        sid, pid = table.get("id"), table.get("player_id")

        def parsed() -> tuple[ShipParams, State | None]:
            doc = {**self.doc, "ships": [table]}
            if not place:
                return parse_params(doc, self.source).ships, None
            scn = parse(doc, self.source)
            return scn.params.ships, scn.initial

        if not isinstance(sid, str) or not (pid is None or isinstance(pid, str)):
            return parsed()  # its message
        try:
            key = json.dumps({k: v for k, v in table.items() if k not in ("id", "player_id")},
                             sort_keys=True, allow_nan=False)
        except (TypeError, ValueError, RecursionError):
            key = None
        hit = self._ships.get(key) if key is not None else None
        if hit is None or (place and hit[1] is None):
            hit = parsed()
            if key is not None:
                if len(self._ships) >= SHIP_CACHE:
                    self._ships.clear()
                self._ships[key] = hit
        ships, initial = hit
        ships = dataclasses.replace(ships, ship_id=(sid,),
                                    player_id=(pid if pid is not None else "player-" + sid,))
        if initial is None:
            return ships, None
        return ships, State(rows=initial.rows.copy(), tick=initial.tick)


@dataclass(frozen=True)
class Scenario:
    """A resolved scenario: ``resolved`` is the document with every default filled in (what logs
    store, and what re-parses to the same scenario). ``params`` and ``initial`` hold the ships
    present at tick 0; ``timeline`` those that join later, those that leave, and every ship's
    commands."""

    name: str
    description: str
    resolved: dict
    params: Params
    initial: State
    timeline: Timeline

    @cached_property
    def scene(self) -> Scene:
        return Scene({k: v for k, v in self.resolved.items() if k != "ships"},
                     self.resolved.get("name", ""))

    def inputs_at(self, tick: int) -> Inputs:
        """The commands in force during ``tick`` for the ships of tick 0 (a fold of their
        commands up to it)."""
        index = {sid: i for i, sid in enumerate(self.params.ships.ship_id)}
        rows = Inputs.zeros(self.initial.n).rows
        for c in self.timeline.commands:
            if c.tick > tick:
                break
            if c.ship_id in index:
                rows[index[c.ship_id]] = (c.throttle, c.rcs, c.hold)
        return Inputs(rows=rows)


def parse_text(text: str, source: str, overrides: dict[str, Any] | None = None) -> Scenario:
    return parse(load_toml(text, source), source, overrides)


def load_toml(text: str, source: str, key: str = "(syntax)") -> dict:
    """``tomllib.loads`` with every way it can fail on hostile text as a ScenarioError: bad
    syntax, an integer past Python's digit limit (ValueError), nesting past the recursion limit."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(source, key, str(exc)) from None
    except RecursionError:
        raise ScenarioError(source, key, "arrays or tables nested too deeply") from None
    except ValueError as exc:  # "Exceeds the limit (4300 digits) for integer string conversion"
        raise ScenarioError(source, key, str(exc).split(";")[0]) from None


def apply_overrides(doc: dict, overrides: dict[str, Any], source: str) -> dict:
    """``{"sim.dt": 0.02, "ships.0.mass": 9000}``: set keys by dotted path (lists by index)."""
    import copy
    doc = copy.deepcopy(doc)
    for path, value in overrides.items():
        parts = path.split(".")
        node: Any = doc
        for i, part in enumerate(parts[:-1]):
            if isinstance(node, list):
                if not part.isdigit() or int(part) >= len(node):
                    raise ScenarioError(source, path, f"no list element {part!r}")
                node = node[int(part)]
            else:
                if part not in node:
                    node[part] = {}
                node = node[part]
                if not isinstance(node, (dict, list)):
                    raise ScenarioError(source, path, f"{'.'.join(parts[:i + 1])} is not a table")
        last = parts[-1]
        if isinstance(node, list):
            if not last.isdigit() or int(last) >= len(node):
                raise ScenarioError(source, path, f"no list element {last!r}")
            node[int(last)] = value
        else:
            node[last] = value
    return doc


def parse(doc: dict, source: str, overrides: dict[str, Any] | None = None) -> Scenario:
    """Check and resolve a scenario document (a dict as ``tomllib`` or ``json`` gives it)."""
    try:
        return _build(*_checked(doc, source, overrides))
    except RecursionError:  # a document nested past Python's limit (copying or walking it)
        raise ScenarioError(source, "(structure)", "arrays or tables nested too deeply") from None


def resolve(doc: dict, source: str) -> dict:
    """``parse(doc, source).resolved`` (every key checked, every default filled in) without
    building the scenario (its parameters, initial states and timeline): a log's header
    resolves the tables of every ship present, a quarter of parse's time (12,500 ships: 0.3 s
    against 1.2 s)."""
    try:
        return _checked(doc, source, None)[0]
    except RecursionError:
        raise ScenarioError(source, "(structure)", "arrays or tables nested too deeply") from None


def parse_params(doc: dict, source: str, overrides: dict[str, Any] | None = None) -> Params:
    """The parameters :func:`parse` gives (its ships of tick 0), by the same checks and messages,
    without placing the ships: the placing is compiled (sim.placement), and a tool that reads a
    log's numbers with its scenario's parameters (``touchdown export``) then loads no compiled
    code at all."""
    try:
        res, n_substeps = _checked(doc, source, overrides)
    except RecursionError:
        raise ScenarioError(source, "(structure)", "arrays or tables nested too deeply") from None
    params = _params(res, n_substeps)
    at_start = _at_start(res["ships"], params.sim.dt_s)
    return params if len(at_start) == len(res["ships"]) else params.take(at_start)


def _checked(doc: dict, source: str, overrides: dict[str, Any] | None
             ) -> tuple[dict, list[int]]:
    """The resolved document (every key checked, every default filled in) and each ship's
    sub-steps a tick."""
    if overrides:
        doc = apply_overrides(doc, overrides, source)
    rd = _Reader(source)
    top_spec = {**TOP, "sim": ("table", {}, None), "contact": ("table", {}, None),
                "body": ("table", {}, None), "controller": ("table", {}, None),
                "ships": ("list", REQUIRED, None)}
    top = rd.table(doc, top_spec, "")
    sim = rd.table(top["sim"], SIM, "sim.")
    con = rd.table(top["contact"], CONTACT, "contact.")
    body = rd.table(top["body"], BODY, "body.")
    ctl = rd.table(top["controller"], CONTROLLER, "controller.")
    if con["bounce_speed"] > con["crash_speed"]:
        rd.fail("contact.bounce_speed", "must not exceed contact.crash_speed")
    if con["friction_kinetic"] > con["friction_static"]:
        rd.fail("contact.friction_kinetic", "must not exceed contact.friction_static")
    if con["tipped_angle_deg"] <= con["settle_tilt_deg"]:
        rd.fail("contact.tipped_angle_deg", "must exceed contact.settle_tilt_deg")
    if con["tipped_rest_deg"] < con["tipped_angle_deg"]:
        rd.fail("contact.tipped_rest_deg", "must be at least contact.tipped_angle_deg")
    if (body["gm"] is None) == (body["surface_gravity"] is None):
        if body["gm"] is None:
            body["gm"] = C.MOON_GM_M3PS2
        else:
            rd.fail("body.gm", "give exactly one of body.gm and body.surface_gravity")
    r2 = body["radius"] * body["radius"]  # (x ** 2 is libm's pow: sim.trig)
    if body["gm"] is None:
        body["gm"] = body["surface_gravity"] * r2
    elif not 1e-6 <= body["gm"] / r2 <= 1e4:
        rd.fail("body.gm", f"gives a surface gravity of {body['gm'] / r2:.3g} "
                           f"m/s^2 at body.radius; it must be 1e-06 to 1e+04")
    if math.ceil(top["duration"] / sim["dt"] - 1e-9) > MAX_TICKS:
        rd.fail("duration", f"{top['duration']:g} s is more than {MAX_TICKS:,} ticks of "
                            f"{sim['dt']:g} s")
    for key in ("max_substep", "impact_substep", "coarse_substep"):
        if sim[key] > 0.0 and sim["dt"] / sim[key] > MAX_SUBSTEPS_PER_TICK:
            rd.fail(f"sim.{key}", f"{sim[key]:g} s makes more than "
                                  f"{MAX_SUBSTEPS_PER_TICK} sub-steps a tick of {sim['dt']:g} s")
    body["surface_gravity"] = None
    del body["surface_gravity"]
    if 0.0 < abs(body["rotation_period"]) < 1.0:
        rd.fail("body.rotation_period", f"must be 0 (not turning) or at least 1 s either way, "
                                        f"got {body['rotation_period']:g}")
    if body["rotation_period"] != 0.0:
        spin = 2.0 * math.pi / body["rotation_period"]
        fling, pull = spin * spin * body["radius"], body["gm"] / r2
        if fling >= pull:
            rd.fail("body.rotation_period", f"{body['rotation_period']:g} s spins the body so "
                                            f"fast that its equator flings ships off "
                                            f"(centrifugal {fling:.4g} m/s^2 >= gravity "
                                            f"{pull:.4g} m/s^2)")
    terrain = rd.table(body["terrain"] or {}, TERRAIN, "body.terrain.")
    if len(terrain["bumps"]) > MAX_BUMPS:
        rd.fail("body.terrain.bumps", f"{len(terrain['bumps'])} bumps (at most {MAX_BUMPS})")
    terrain["bumps"] = [rd.table(b, BUMP, f"body.terrain.bumps[{i}].")
                        for i, b in enumerate(terrain["bumps"])]
    body["terrain"] = terrain
    if not top["ships"]:
        rd.fail("ships", "at least one ship is required")
    if len(top["ships"]) > MAX_SHIPS:
        rd.fail("ships", f"{len(top['ships']):,} ships (at most {MAX_SHIPS:,})")
    ships = []
    seen: set[str] = set()
    for i, raw in enumerate(top["ships"]):
        pre = f"ships[{i}]."
        sh = rd.table(raw, SHIP, pre)
        if sh["id"] in seen:
            rd.fail(pre + "id", f"duplicate ship id {sh['id']!r}")
        seen.add(sh["id"])
        if sh["player_id"] is None:
            sh["player_id"] = "player-" + sh["id"]
        if sh["stiffness_per_kg"] is None:
            sh["stiffness_per_kg"] = con["stiffness_per_kg"]
        if sh["fuel_mass"] >= sh["mass"]:
            rd.fail(pre + "fuel_mass", "must be less than mass")
        if sh["inertia"] is not None:
            a_, b_, c_ = sorted(sh["inertia"])
            if a_ + b_ < c_ * (1.0 - 1e-12):
                rd.fail(pre + "inertia", "no rigid body has these principal moments: the two "
                                         "smaller must add up to at least the largest")
        if sh["inertia"] is None:
            # uniform solid cylinder of radius leg_radius and length 2 com_height
            r, length, m = max(sh["leg_radius"], 0.5), 2.0 * sh["com_height"], sh["mass"]
            ixx = m * (3.0 * r * r + length * length) / 12.0
            sh["inertia"] = [ixx, ixx, 0.5 * m * r * r]
        sh["initial"] = rd.table(sh["initial"] or {}, INITIAL, pre + "initial.")
        if sh["initial"]["altitude"] is None:
            sh["initial"]["altitude"] = 10.0 if sh["initial"]["state"] == "flying" else 0.0
        if len(sh["inputs"]) > MAX_INPUTS:
            rd.fail(pre + "inputs", f"{len(sh['inputs'])} entries (at most {MAX_INPUTS:,})")
        sh["inputs"] = [rd.table(x, INPUT, f"{pre}inputs[{j}].") for j, x in enumerate(sh["inputs"])]
        ts = [x["t"] for x in sh["inputs"]]
        if ts != sorted(ts):
            rd.fail(pre + "inputs", "entries must be in order of t")
        if sh["retire_t"] is not None and (_tick_of(sh["retire_t"], sim["dt"])
                                           <= _tick_of(sh["spawn_t"], sim["dt"])):
            rd.fail(pre + "retire_t", f"must be at least a tick after spawn_t "
                                      f"({sh['spawn_t']:g} s)")
        for j, x in enumerate(sh["inputs"]):
            if x["t"] < sh["spawn_t"]:
                rd.fail(f"{pre}inputs[{j}].t", f"{x['t']:g} s is before the ship joins "
                                               f"(spawn_t {sh['spawn_t']:g} s)")
            if sh["retire_t"] is not None and x["t"] >= sh["retire_t"]:
                rd.fail(f"{pre}inputs[{j}].t", f"{x['t']:g} s is after the ship leaves "
                                               f"(retire_t {sh['retire_t']:g} s)")
        _check_initial(rd, sh, con, pre + "initial.")
        ships.append(sh)
    resolved = {**top, "sim": sim, "contact": con, "body": body, "controller": ctl, "ships": ships}
    return resolved, _substeps(rd, sim, con, ships)


#: Bounds on the work a scenario may ask for: a run does bounded work per tick.
MAX_SUBSTEPS_PER_TICK = 1000
MAX_TICKS = 1_000_000_000
MAX_SHIPS = 1_000_000
SHIP_CACHE = 4096  # ship classes Scene.ship keeps parsed
MAX_INPUTS = 1_000_000
#: a method whose stable w h is below this is unstable at any step a run could take
PRACTICAL_BOUND_WH = 1e-3

#: the sub-step is kept within this fraction of a method's stability limit when it is chosen for you:
#: near the limit a stable method still cancels most of the contact's physical damping
STABILITY_MARGIN = 0.5


def contact_omega(sh: dict) -> float:
    """A ship's fastest contact mode, rad/s: the four-foot bounce w = sqrt(k/m), or one foot
    alone rocking the ship, w^2 = (k/4)(1/m + a^2 / I_transverse) (a normal force at a foot has
    lever arm leg_radius about the transverse axes); k/m the ship's ``stiffness_per_kg``."""
    kpm = sh["stiffness_per_kg"]
    i_t = min(sh["inertia"][0], sh["inertia"][1])
    a = sh["leg_radius"]
    return math.sqrt(max(kpm, 0.25 * kpm * (1.0 + sh["mass"] * (a * a) / i_t)))


def rocking_omega(sh: dict) -> float:
    """A ship's fastest rocking mode, rad/s: turning about a transverse axis on the feet's springs
    alone (its centre of mass held), w^2 = (k/2) a^2 / I_transverse (the two feet off that axis,
    each k/4 at lever arm leg_radius). The load's destabilising moment (m g com_height) only slows
    it, so this bounds it from above."""
    i_t = min(sh["inertia"][0], sh["inertia"][1])
    a = sh["leg_radius"]
    return math.sqrt(0.5 * sh["stiffness_per_kg"] * sh["mass"] * (a * a) / i_t)


def _substeps(rd: _Reader, sim: dict, con: dict, ships: list[dict]) -> list[int]:
    """Each ship's sub-steps a tick near the ground: the scene's (``ceil(dt / max_substep)``), or
    more where that ship's own stiffest contact mode needs them to be stable (SEED-NOTES 8;
    sim.stability explains the bounds), so that no ship's numbers depend on another's class.
    ``on_unstable``: ``substep`` (default) sub-steps further, ``error`` refuses naming the ship,
    ``allow`` runs it anyway. A method that solves the spring exactly is limited by its kicks on
    the rocking modes only."""
    from touchdown.sim.stability import KICKS, largest_stable_wh
    n_scene = 1 if sim["max_substep"] <= 0.0 else max(1, math.ceil(sim["dt"] / sim["max_substep"]
                                                                   - 1e-9))
    h = sim["dt"] / n_scene
    kicks = sim["integrator"] in KICKS
    # hybrid: the ships its sub-steps carry are stepped by rk4 (its vertical ships' one exact step
    # is stable at any tick)
    limiting = KICKS[sim["integrator"]] if kicks else (
        "rk4" if sim["integrator"] == "hybrid" else sim["integrator"])
    bound = min(largest_stable_wh(limiting, z)
                for z in (con["damping_ratio"], con["absorb_damping_ratio"]))
    out = []
    for i, sh in enumerate(ships):
        w = rocking_omega(sh) if kicks else contact_omega(sh)
        if w * h < bound * STABILITY_MARGIN or sim["on_unstable"] == "allow":
            out.append(n_scene)
            continue
        if bound < PRACTICAL_BOUND_WH:  # explicit Euler undamped: 1.4e-6 is rounding, not a bound
            rd.fail("sim.integrator", f"{sim['integrator']} is unstable on an undamped contact at "
                                      "any step; use another method or damping")
        need = math.ceil(w * sim["dt"] / (bound * STABILITY_MARGIN))
        who = f"ship {sh['id']!r} (ships[{i}])"
        if need > MAX_SUBSTEPS_PER_TICK:
            rd.fail("sim.dt", f"{sim['integrator']} needs {need:,} sub-steps a tick of "
                              f"{sim['dt']:g} s on the stiffest contact of {who} (at most "
                              f"{MAX_SUBSTEPS_PER_TICK}); use a shorter tick or another method")
        if sim["on_unstable"] == "error":
            rd.fail("sim.dt", f"{sim['integrator']} with a contact sub-step of {h:g} s is unstable "
                              f"for the contact of {who} (omega h = {w * h:.3f} >= its limit "
                              f"{bound:.3f}); set sim.max_substep <= {sim['dt'] / need:.6g} or "
                              f"sim.on_unstable = \"substep\"")
        out.append(max(n_scene, need))
    return out


def _check_initial(rd: _Reader, sh: dict, con: dict, pre: str) -> None:
    """A start must be a state physics can be in (MODEL-NOTES 27): a flying ship's feet are clear
    of the ground; a ship in contact touches it, pressed in no deeper than an impact at
    crash_speed could press it (its springs then hold at most the energy of such an impact, so
    nothing comes out of the ground faster); landed and tipped ships are pinned, at rest."""
    ini = sh["initial"]
    state, alt = ini["state"], ini["altitude"]
    deepest = con["crash_speed"] / math.sqrt(sh["stiffness_per_kg"])
    if state == "flying" and alt < 0.0:
        rd.fail(pre + "altitude", f"a flying ship's feet are above the ground (altitude >= 0, got "
                                  f"{alt:g}); a ship in the ground is in contact: "
                                  f"state = \"contact\"")
    if state in ("contact", "landed"):
        if alt > 0.0:
            rd.fail(pre + "altitude", f"a {state} ship touches the ground (altitude <= 0, got "
                                      f"{alt:g}); a ship above it is flying")
        if alt < -deepest:
            rd.fail(pre + "altitude", f"{alt:g} m presses the feet deeper than an impact at "
                                      f"contact.crash_speed can ({-deepest:.4g} m = crash_speed / "
                                      f"sqrt(stiffness_per_kg)); the springs would throw the ship "
                                      f"out faster than that")
    if state in ("landed", "tipped"):
        for key in ("vertical_speed", "horizontal_speed"):
            if ini[key] != 0.0:
                rd.fail(pre + key, f"must be 0 for a {state} ship (it is pinned)")
        if any(x != 0.0 for x in ini["angular_velocity"]):
            rd.fail(pre + "angular_velocity", f"must be 0 for a {state} ship (it is pinned)")
        if alt != 0.0 and state == "tipped":
            rd.fail(pre + "altitude", "must be 0 for a tipped ship (it is pinned)")
    # the footprint holds the centre of mass while h sin(tilt) (|cos yaw| + |sin yaw|) < a cos(tilt)
    # (sim.rest.over_footprint: toward a foot atan(a / h), toward an edge atan(a / (sqrt 2 h)))
    th, yaw = math.radians(ini["tilt_deg"]), math.radians(ini["yaw_deg"])
    cos_yaw, sin_yaw = trig.cos_sin(yaw)
    cos_th, sin_th = trig.cos_sin(th)
    reach = abs(cos_yaw) + abs(sin_yaw)
    if state == "landed" and not (sh["com_height"] * sin_th * reach < sh["leg_radius"] * cos_th):
        crit = math.degrees(math.atan2(sh["leg_radius"], sh["com_height"] * reach))
        rd.fail(pre + "tilt_deg", f"a landed ship must stand: its centre of mass over its "
                                  f"footprint, tilt below {crit:.2f} deg at this yaw")
    if state == "tipped" and not (con["tipped_angle_deg"] < ini["tilt_deg"]
                                  <= con["tipped_rest_deg"]):
        rd.fail(pre + "tilt_deg", "a tipped ship needs contact.tipped_angle_deg < tilt_deg <= "
                                  "contact.tipped_rest_deg")
    if state == "contact" and ini["tilt_deg"] >= con["tipped_angle_deg"]:
        rd.fail(pre + "tilt_deg", "a ship in contact must be tilted less than contact.tipped_angle_deg")


def _params_of(cls, section: str, tables: dict, **extra):
    """The dataclass of one section of the parameters from the resolved document: each setting
    landing there (sim.settings), its value converted (an enum's member for its string)."""
    return cls(**{s.field: s.to_param(tables[s.table][s.name]) for s in landing_in(section)},
               **extra)


def _params(res: dict, n_substeps: list[int]) -> Params:
    """The parameters of every ship of the resolved document ``res``, and of its scene."""
    sim, ships = res["sim"], res["ships"]
    tables = {"": res, "sim": sim, "contact": res["contact"], "body": res["body"],
              "controller": res["controller"]}
    ter = res["body"]["terrain"]
    # a bump's keys land in the terrain's columns (a tuple over the bumps)
    terrain = Terrain(**{s.field: (tuple(b[s.name] for b in ter["bumps"])
                                   if s.table == "body.terrain.bumps" else ter[s.name])
                         for s in landing_in("terrain")})
    bp = _params_of(BodyParams, "body", tables, terrain=terrain)
    cp = _params_of(ContactParams, "contact", tables)
    spar = _params_of(SimParams, "sim", tables)
    shp = ShipParams.of(
        len(ships), ship_id=tuple(s["id"] for s in ships),
        player_id=tuple(s["player_id"] for s in ships),
        **{st.field: [s[st.name] for s in ships] for st in landing_in("ships")},
        contact_omega_radps=[math.sqrt(s["stiffness_per_kg"]) for s in ships],
        n_substeps=n_substeps)
    ctl = _params_of(ControllerParams, "controller", tables)
    return Params(spar, cp, bp, shp, ctl)


def _at_start(ships: list[dict], dt_s: float) -> list[int]:
    """The ships present at tick 0 (the others join later), by their index."""
    return [i for i, s in enumerate(ships) if _tick_of(s["spawn_t"], dt_s) == 0]


def _build(res: dict, n_substeps: list[int]) -> Scenario:
    from touchdown.sim.placement import initial_state  # compiled: loaded where ships are placed
    ships = res["ships"]
    params = _params(res, n_substeps)
    spar = params.sim
    initial = initial_state(params, ships)
    spawns, retires, commands = [], [], []
    at_start = _at_start(ships, spar.dt_s)
    for s in ships:
        joins = _tick_of(s["spawn_t"], spar.dt_s)
        if joins != 0:
            spawns.append(Spawn(joins, {k: v for k, v in s.items() if k not in TIMING_KEYS}))
        if s["retire_t"] is not None:
            retires.append(Retire(_tick_of(s["retire_t"], spar.dt_s), s["id"]))
        for x in s["inputs"]:
            commands.append(command_of(_tick_of(x["t"], spar.dt_s), s["id"],
                                    [f.choices.from_label(x[f.name]) if f.choices else x[f.name]
                                     for f in INPUT_FIELDS]))
    # commands in order of tick, then of the ships' order in the scenario (a stable sort)
    timeline = Timeline.of(spawns, retires, commands)
    if len(at_start) < len(ships):
        params, initial = params.take(at_start), initial.take(at_start)
    return Scenario(res["name"], res["description"], res, params, initial, timeline)


def _tick_of(t_s: float, dt_s: float) -> int:
    """The first tick at or after ``t_s`` (a time a hair past a tick, from rounding, is that
    tick)."""
    return int(math.ceil(t_s / dt_s - 1e-9))
