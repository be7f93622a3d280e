"""What comes from outside a run: ships joining and leaving, and the players' commands.

A run is a fold of the step over these (sim.world): the scenario is only one place they come from;
the Python API (World.spawn, retire, command) and a log's own records are others. Each names its
ship by id, never by a position in the batch, so that a ship joining or leaving moves no other
ship's commands.

Ticks: a command of tick t is applied in the step from t to t + 1 (the scenario's ``t`` is when it
takes hold) and holds until the ship's next command; a ship that joins at tick T is in the state
of tick T (placed where its ``initial`` table says, at that tick's rotation of the body) and steps
from there; a ship that leaves at tick T is last in the state of tick T - 1.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, make_dataclass
from itertools import pairwise

from touchdown.sim import fields as _fields
from touchdown.sim.errors import TouchdownError


#: the inputs a command gives a ship, in the order Command and World.commands take them (declared
#: once, with their ranges, in sim.fields: :data:`sim.fields.INPUTS`)
INPUTS = tuple(f.name for f in _fields.INPUTS)
_INPUT = {f.name: f for f in _fields.INPUTS}
THROTTLE = _INPUT["throttle"].limits  # of the ship's max thrust
RCS = _INPUT["rcs"].limits  # of its max RCS torque, per body axis
HOLD_MODES = _INPUT["hold"].labels

_COUNT = {2: "two", 3: "three", 4: "four"}


class CommandError(TouchdownError, ValueError):
    """A command, spawn or retire that cannot be applied; ``str()`` is one line naming the ship
    and the field."""


#: what _check holds each input to: (name, its choices or None, (lo, hi) or None, numbers)
_CHECKS = tuple((f.name, None if f.choices is None else frozenset(int(m) for m in f.choices),
                 f.limits, f.per_ship) for f in _fields.INPUTS)


def _check(self) -> "Command":
    """This command if every value is in range, else CommandError naming the field (a log's
    timeline checks each of its commands: a million in ~1.5 s)."""
    if not isinstance(self.tick, int) or self.tick < 0:
        raise CommandError(f"{_where(self)}: tick must be a whole number >= 0")
    for name, choices, limits, n in _CHECKS:
        x = getattr(self, name)
        if choices is not None:
            if x not in choices:
                raise CommandError(f"{_where(self)}: {name} must be one of "
                                   f"{', '.join(_INPUT[name].labels)}, got {x!r}")
            continue
        lo, hi = limits
        if n == 1:
            if not (_finite(x) and lo <= x <= hi):
                raise CommandError(f"{_where(self)}: {name} must be {lo:g}..{hi:g}, got {x!r}")
        elif len(x) != n or not all([_finite(v) and lo <= v <= hi for v in x]):
            raise CommandError(f"{_where(self)}: {name} must be {_COUNT[n]} numbers in "
                               f"{lo:g}..{hi:g}, got {x!r}")
    return self


def _where(c) -> str:
    return f"command for ship {c.ship_id!r} at tick {c.tick}"


def _inputs(self) -> tuple:
    """The inputs' values, in :data:`INPUTS` order (a row of sim.state.INPUTS_DTYPE)."""
    return tuple(getattr(self, name) for name in INPUTS)


#: From tick ``tick`` on, ship ``ship_id`` is given these inputs (sim.fields.INPUTS: ``throttle``
#: 0..1 of its max_thrust, ``rcs`` -1..1 of max_rcs_torque per body axis, ``hold`` a HoldMode
#: value); a field each, derived from the table, each defaulting to zero (hold off).
Command = make_dataclass(
    "Command",
    [("tick", int), ("ship_id", str),
     *[(f.name, float if f.per_ship == 1 and f.choices is None else
        int if f.choices is not None else tuple, field(default=f.default))
       for f in _fields.INPUTS]],
    frozen=True, slots=True,  # (no __dict__: 72 bytes a command, not ~112)
    namespace={"check": _check, "inputs": property(_inputs),
               "__doc__": "From tick ``tick`` on, ship ``ship_id`` is given these inputs "
                          "(sim.fields.INPUTS: throttle 0..1 of its max_thrust, rcs -1..1 of "
                          "max_rcs_torque per body axis, hold a HoldMode value)."})


Command.__module__ = __name__  # (make_dataclass's ``module`` is Python 3.12's): pickled by name


def command_of(tick: int, ship_id: str, values) -> "Command":
    """A Command from its inputs' values in :data:`INPUTS` order, as a record, a proto or a caller
    gives them (a vector as any sequence, a choice as any integer)."""
    return Command(tick, ship_id, *(f.value(x) for f, x in zip(_fields.INPUTS, values, strict=True)))


def _finite(x) -> bool:
    if type(x) is float:
        return math.isfinite(x)
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


@dataclass(frozen=True)
class Spawn:
    """Ship ``spec`` (one resolved ``[[ships]]`` table: every default filled in, ``id`` its name)
    joins at tick ``tick``."""

    tick: int
    spec: dict = field(hash=False, compare=True)

    @property
    def ship_id(self) -> str:
        return self.spec["id"]


@dataclass(frozen=True)
class Retire:
    """Ship ``ship_id`` leaves at tick ``tick``."""

    tick: int
    ship_id: str


def _by_tick(items) -> tuple:
    """``items`` as a tuple sorted by tick, stably: as given if already in order (one pass)."""
    items = tuple(items)
    if all(a.tick <= b.tick for a, b in pairwise(items)):
        return items
    return tuple(sorted(items, key=lambda x: x.tick))  # a stable sort keeps same-tick order


@dataclass(frozen=True)
class Timeline:
    """Joins, leaves and commands, each sorted by tick (ties in the order they were given)."""

    spawns: tuple[Spawn, ...] = ()
    retires: tuple[Retire, ...] = ()
    commands: tuple[Command, ...] = ()

    @staticmethod
    def of(spawns=(), retires=(), commands=()) -> "Timeline":
        """Each sorted by tick, stably (a log's are already: they are not sorted again, which
        for a million commands would take a list and a key each more, ~16 MB)."""
        return Timeline(_by_tick(spawns), _by_tick(retires), _by_tick(commands))

    def for_ship(self, ship_id: str) -> "Timeline":
        """Only what concerns ship ``ship_id``."""
        return Timeline(tuple(s for s in self.spawns if s.ship_id == ship_id),
                        tuple(r for r in self.retires if r.ship_id == ship_id),
                        tuple(c for c in self.commands if c.ship_id == ship_id))

    def from_tick(self, tick: int) -> "Timeline":
        """What happens at ``tick`` or later: joins and leaves after it (the state of ``tick``
        already holds those of ``tick``), commands from it on."""
        return Timeline(tuple(s for s in self.spawns if s.tick > tick),
                        tuple(r for r in self.retires if r.tick > tick),
                        tuple(c for c in self.commands if c.tick >= tick))
