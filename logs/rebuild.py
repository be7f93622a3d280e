"""A run rebuilt from its log: the log's scenario checked by the scenario's own rules
(``scenario_of``), its fleet's parameters by key (``fleet_params``; ``log_params`` without the
scenario's start, so without compiled code: what a reader of the log's numbers needs), and the
world a replay folds over, from tick 0 (``recorded_world``) or from a keyframe
(``keyframe_world``).
"""
from __future__ import annotations

import json

import numpy as np

from touchdown.logs import LogError
from touchdown.logs.reader import LogReader, TickData
from typing import TYPE_CHECKING, Callable

from touchdown.sim.params import Params, ShipParams
from touchdown.sim.scenario import Scenario, ScenarioError, Scene, parse, parse_params
from touchdown.sim.state import State, concatenate

if TYPE_CHECKING:  # (compiled: imported where a world is built)
    from touchdown.sim.world import World


def fleet_params(reader: LogReader, scn: Scenario) -> Params:
    """The log's scene with every ship it ever held, in key order (row k: ship key k): the
    header's from its scenario, each joined one from the table it joined with."""
    return _fleet(reader, scn.params, scn.scene.ship_params)


def log_params(reader: LogReader) -> Params:
    """:func:`fleet_params` of the log's own scenario (checked as :func:`scenario_of` checks it,
    with its messages), without the scenario's start (sim.scenario.parse_params): no compiled
    code runs or loads."""
    path = str(reader.path)
    doc = _recorded(reader)
    try:
        if not doc["ships"] and reader.log_format >= 3:  # no ships at its first tick
            params = _without_ships(doc, path, place=False)
        else:
            params = parse_params(doc, path)
    except ScenarioError as exc:
        raise LogError(str(exc)) from None
    _agrees(reader, params)
    # the recorded document is the resolved one (it re-parses to itself): its scene
    scene = Scene({k: v for k, v in doc.items() if k != "ships"}, doc.get("name", ""))
    return _fleet(reader, params, scene.ship_params)


def _fleet(reader: LogReader, params: Params, ship: Callable[[dict], ShipParams]) -> Params:
    table = reader.ship_table()
    ships = [params.ships]
    for k in range(len(params.ships.ship_id), len(table)):
        try:
            ships.append(ship(table.specs[k]))
        except ScenarioError as exc:
            raise LogError(f"{reader.path}: ship {table.ids[k]!r}: {exc}") from None
    return params.with_ships(concatenate(ships))


def keyframe_world(reader: LogReader, scn: Scenario, keyframe: "TickData") -> World:
    """The world a replay folds over from ``keyframe``'s tick (a log that starts later than tick
    0, or a window): its ships in the state recorded there (their parameters from ``scn``, the
    log's scenario, perhaps changed by a what-if, and the tables ships joined with), the commands
    in force then, and the log's joins, leaves and commands after it."""
    world = recorded_world(reader, scn)
    world.params = fleet_params(reader, scn).take(keyframe.keys)
    world.state, world.inputs = keyframe.state(), keyframe.inputs()
    world.timeline = world.timeline.from_tick(keyframe.tick)
    return world


def recorded_world(reader: LogReader, scn: Scenario) -> World:
    """The world a replay folds over: ``scn``'s ships at tick 0 (the log's scenario, perhaps
    changed by a what-if), with the log's recorded joins, leaves and commands (format 3; before
    it, the scenario's own inputs)."""
    from touchdown.sim.world import World
    world = World.of(scn)
    if reader.log_format >= 3:
        world.timeline = reader.timeline()
        table = reader.ship_table()
        for sid, spec in zip(table.ids, table.specs):
            if spec is not None:
                world.known[sid] = spec
    return world


def scenario_of(reader: LogReader, ship_id: str | None = None,
                overrides: dict | None = None) -> tuple[Scenario, int | None]:
    """The log's scenario (optionally one ship of it, or with ``overrides``); returns it and that
    ship's index. The resolved scenario is checked by the same rules as a scenario file, with the
    same messages, and must agree with its record (tick, tick count, method, ships)."""
    doc = _recorded(reader)
    try:
        if not doc["ships"] and reader.log_format >= 3:  # no ships at its first tick
            whole = _without_ships(doc, str(reader.path))
        else:
            whole = parse(doc, str(reader.path))
    except ScenarioError as exc:
        raise LogError(str(exc)) from None
    _agrees(reader, whole.params)
    index = None
    if ship_id is not None:
        ids = [s.get("id") for s in doc["ships"]]
        if ship_id not in ids:
            raise LogError(f"{reader.path}: no ship {ship_id!r} in this log (ships: "
                           f"{', '.join(map(str, ids))})")
        index = ids.index(ship_id)
        doc["ships"] = [doc["ships"][index]]
    if index is None and not overrides:
        return whole, None
    try:
        if not doc["ships"]:
            return _without_ships(doc, str(reader.path), overrides), index
        return parse(doc, str(reader.path), overrides), index
    except ScenarioError as exc:
        raise LogError(str(exc)) from None


def _recorded(reader: LogReader) -> dict:
    """The log's recorded (resolved) scenario document, as JSON gives it."""
    try:
        doc = json.loads(reader.scenario.resolved_json)
    except RecursionError:
        raise LogError(f"{reader.path}: the recorded scenario is not valid JSON (arrays or "
                       f"objects nested too deeply)") from None
    except ValueError as exc:  # JSONDecodeError, or an integer past Python's digit limit
        raise LogError(f"{reader.path}: the recorded scenario is not valid JSON "
                       f"({str(exc).split(';')[0][:100]})") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("ships"), list):
        raise LogError(f"{reader.path}: the recorded scenario is not a scenario")
    return doc


def _agrees(reader: LogReader, params: Params) -> None:
    """The log's scenario record must agree with its scenario: tick, tick count, method, ships."""
    rec, sim = reader.scenario, params.sim
    if (sim.dt_s, sim.n_ticks, sim.integrator, list(params.ships.ship_id)) != (
            rec.dt_s, rec.n_ticks, rec.integrator, list(rec.ship_ids)):
        raise LogError(f"{reader.path}: the scenario record disagrees with its own scenario "
                       f"(tick, tick count, method or ships)")


_ON_UNSTABLE = ("substep", "error", "allow")


def _without_ships(doc: dict, source: str, overrides: dict | None = None,
                   place: bool = True) -> Scenario | Params:
    """A scenario with no ships (a log whose fleet is empty at its first tick: a live service
    before anything is spawned), which sim.scenario.parse refuses: the scene is checked and
    resolved by the same rules, with a stand-in ship that is then dropped (its own stability is
    allowed, as it never runs); ``resolved`` is the scene with ``ships = []``. ``place`` False:
    only its parameters (sim.scenario.parse_params)."""
    from touchdown.sim.timeline import Timeline
    if overrides:
        from touchdown.sim.scenario import apply_overrides
        doc = apply_overrides(doc, overrides, source)
    sim = doc.get("sim", {})
    own = sim.get("on_unstable", "substep") if isinstance(sim, dict) else None
    stand_in = {**doc, "ships": [{"id": "(none)"}]}
    if own in _ON_UNSTABLE:
        stand_in["sim"] = {**sim, "on_unstable": "allow"}
    none = np.zeros(1, dtype=bool)
    if not place:
        params = parse_params(stand_in, source)
        if params.ships.n != 1:  # the stand-in joins later (a spawn time of its own): impossible
            raise ScenarioError(source, "ships", "no ships, and a scene that places none")
        return params.take(none)
    scn = parse(stand_in, source)
    if scn.params.ships.n != 1:  # the stand-in joins later (a spawn time of its own): impossible
        raise ScenarioError(source, "ships", "no ships, and a scene that places none")
    resolved = {**scn.resolved, "sim": {**scn.resolved["sim"], "on_unstable": own}, "ships": []}
    return Scenario(scn.name, scn.description, resolved, scn.params.take(none),
                    State(rows=scn.initial.select(none).rows, tick=0), Timeline())


__all__ = ["fleet_params", "keyframe_world", "log_params", "recorded_world", "scenario_of"]
