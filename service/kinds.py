"""The command stream's commands as one table: a row per kind with its fields (each with its
check), what the entry as a whole must hold, and what the command does to the shard's fleet.
:func:`service.commands.parse` (an entry to a request, or a rejection) and
:meth:`service.shard.Shard._apply` (a request to the world, or a rejection) are both read off
it; a new command is a row here.

A command that sets an input (throttle, rcs, hold) is derived from that input's row of
``sim.fields.INPUTS`` (its range or choices, and the names it carries them under): it checks its
numbers against the same ranges as a recorded command, and becomes one: the
ship's inputs of this tick (``pending``, one list ``[throttle, rcs, hold]`` a ship, in
``sim.timeline.INPUTS`` order) go to ``World.commands`` once every request of the tick is
applied (service.shard), and so into the log's CommandBatch. A spawn and a retire are the
world's (``World.spawn``, ``World.retire``: the log's FleetChange); an autoland hands the ship
to the autopilot (service.autopilot), whose inputs are recorded commands too.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Callable

from touchdown.sim.enums import SurfaceState
from touchdown.sim.scenario import ScenarioError
from touchdown.sim.fields import INPUTS as INPUT_FIELDS
from touchdown.sim.timeline import INPUTS, CommandError
from touchdown.sim.world import World


@dataclass(frozen=True)
class Field:
    """One field a command carries: ``value`` turns its text into the request's value, or None
    if the text is not one (the rejection says the field ``must be`` what ``expects`` says)."""

    name: str
    value: Callable[[str], object]
    expects: str = ""
    printable: bool = True  # must be printable UTF-8 text (a spawn's JSON is checked as JSON)


#: applying a request: (world, request, the inputs given this tick by ship, the autopilot's
#: ships, the ship's row if the kind needs it present) -> the reason it is refused, or None
Apply = Callable[[World, object, dict, dict, "int | None"], "str | None"]


@dataclass(frozen=True)
class Kind:
    """One command: its fields (besides ``cmd``, ``ship_id`` and ``player_id``), ``check`` of the
    entry as a whole once each field is read (values, ship_id, player_id -> the values, or the
    reason it is refused), and ``apply``."""

    name: str
    fields: tuple[Field, ...]
    apply: Apply
    check: Callable[[dict, str, str], "dict | str"] | None = None
    #: for a ship in the fleet now (else "no ship ... in the fleet")
    present: bool = True
    #: for a ship the fleet knows: its player's alone, at most Limits.max_commands_per_ship a
    #: tick (a spawn names a new one)
    of_ship: bool = True
    #: how the shard's ship count changes (a spawn into a full shard is refused)
    ships: int = 0
    #: the parts of a ship the command sets (a ship takes one command a tick for each part:
    #: service.serve's admission); a spawn, a retire or an autoland sets the whole ship
    parts: frozenset = frozenset()


def number(text: str) -> float | None:
    """A finite decimal number, or None. ``float`` alone would take 'nan', 'inf' and '1_0'."""
    text = text.strip()
    if not text or len(text) > 32 or any(c not in "0123456789+-.eE" for c in text):
        return None
    try:
        x = float(text)
    except ValueError:
        return None
    return x if math.isfinite(x) else None


def _number_in(lo: float, hi: float, name: str) -> Field:
    def value(text: str) -> float | None:
        x = number(text)
        return x if x is not None and lo <= x <= hi else None
    return Field(name, value, f"a number in {lo:g}..{hi:g}")


def _one_of(labels: tuple[str, ...], name: str) -> Field:
    return Field(name, lambda text: text if text in labels else None,
                 f"one of {', '.join(labels)}")


def in_force(world: World, i: int) -> list:
    """The inputs ship row ``i`` flies with now, as ``pending`` holds them."""
    rows = world.inputs.rows
    return [int(rows[f.name][i]) if f.choices is not None else
            float(rows[f.name][i]) if f.per_ship == 1 else
            tuple(float(x) for x in rows[f.name][i]) for f in INPUT_FIELDS]


def _sets(name: str, value_of: Callable[[dict], object]) -> Apply:
    """A command that sets one of the ship's inputs (``name``, of sim.timeline.INPUTS) from this
    tick on, the others as they are (given this tick, or in force)."""
    slot = INPUTS.index(name)

    def apply(world, req, pending, autoland, i):
        # a player's hand on the controls takes them back from the autopilot
        autoland.pop(req.ship_id, None)
        cur = list(pending.get(req.ship_id) or in_force(world, i))
        cur[slot] = value_of(req.values)
        pending[req.ship_id] = cur
        return None
    return apply


def _input_kind(f) -> "Kind":
    """The command that sets input ``f`` (a row of sim.fields.INPUTS): its numbers in range, or
    its choice by label, under the names ``f.wire``."""
    if f.choices is not None:
        (name,) = f.wire
        return Kind(f.name, (_one_of(f.labels, name),),
                    _sets(f.name, lambda v: int(f.choices.from_label(v[name]))),
                    parts=frozenset((f.name,)))
    fields = tuple(_number_in(*f.limits, name) for name in f.wire)
    if f.per_ship == 1:
        (name,) = f.wire
        value = lambda v: v[name]  # noqa: E731
    else:
        value = lambda v: tuple(v[name] for name in f.wire)  # noqa: E731
    return Kind(f.name, fields, _sets(f.name, value), parts=frozenset((f.name,)))


def _spawn_table(values: dict, ship_id: str, player: str) -> dict | str:
    try:
        spec = json.loads(values["ship"])
    except (ValueError, RecursionError):
        return "spawn: ship is not valid JSON"
    if not isinstance(spec, dict):
        return "spawn: ship must be a JSON object (one [[ships]] table)"
    if "id" in spec and spec["id"] != ship_id:
        return f"spawn: the table's id {show(str(spec['id']))} is not ship_id"
    if "player_id" in spec and spec["player_id"] != player:
        return ("spawn: the table's player_id is not the command's player_id (a ship "
                "belongs to the player who spawns it)")
    return {"ship": {**spec, "id": ship_id, "player_id": player}}


def _spawn(world, req, pending, autoland, i):
    try:
        world.spawn(req.values["ship"])
    except ScenarioError as exc:  # the table, by the scenario's rules
        return f"spawn: ship.{exc.key.removeprefix('ships[0].')}: {exc.problem}"
    except CommandError as exc:
        return str(exc).splitlines()[0]
    return None


def _retire(world, req, pending, autoland, i):
    try:
        world.retire(req.ship_id)
    except CommandError as exc:
        return str(exc).splitlines()[0]
    pending.pop(req.ship_id, None)
    autoland.pop(req.ship_id, None)
    return None


def _autoland(world, req, pending, autoland, i):
    if SurfaceState(int(world.state.rows["surface_state"][i])) is SurfaceState.CRASHED:
        return f"autoland: ship {req.ship_id!r} has crashed"
    autoland[req.ship_id] = None
    return None


#: every command, by name (SPEC.md section 5; docs/SERVICE.md)
WHOLE = frozenset((*INPUTS, "ship"))  # every part of a ship

KINDS: dict[str, Kind] = {k.name: k for k in (
    # a command per input (throttle, rcs, hold), each as sim.fields.INPUTS declares it
    *(_input_kind(f) for f in INPUT_FIELDS),
    Kind("spawn", (Field("ship", str, printable=False),), _spawn, check=_spawn_table,
         present=False, of_ship=False, ships=1, parts=WHOLE),
    Kind("retire", (), _retire, present=False, ships=-1, parts=WHOLE),
    Kind("autoland", (), _autoland, parts=WHOLE),
)}


def parts_of(req) -> frozenset:
    """The parts of its ship a request sets (none for an entry rejected as it was read)."""
    kind = KINDS.get(getattr(req, "cmd", ""))
    return kind.parts if kind is not None and not hasattr(req, "reason") else frozenset()


def apply(world: World, req, pending: dict, autoland: dict) -> str | None:
    """Apply request ``req`` (service.commands.Request) to ``world`` as its kind says: the
    reason it cannot be applied, or None."""
    kind = KINDS[req.cmd]
    i = None
    if kind.present:
        i = world.row(req.ship_id)
        if i is None:
            return f"{req.cmd}: no ship {req.ship_id!r} in the fleet at tick {world.tick}"
    return kind.apply(world, req, pending, autoland, i)


def show(s: str) -> str:
    """A value as a message shows it: quoted, cut short, unprintable characters escaped."""
    s = s if len(s) <= 40 else s[:40] + "..."
    return ascii(s)


__all__ = ["KINDS", "Kind", "Field", "WHOLE", "apply", "in_force", "number", "parts_of", "show"]
