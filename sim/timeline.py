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
from dataclasses import dataclass, field

from touchdown.sim.enums import HoldMode
from touchdown.sim.errors import TouchdownError


#: the inputs a command gives a ship, in the order World.commands takes them, and their ranges:
#: a recorded command's (Command.check) and a live one's (service.kinds) checks
INPUTS = ("throttle", "rcs", "hold")
THROTTLE = (0.0, 1.0)  # of the ship's max thrust
RCS = (-1.0, 1.0)  # of its max RCS torque, per body axis
HOLD_MODES = tuple(m.label for m in HoldMode)


class CommandError(TouchdownError, ValueError):
    """A command, spawn or retire that cannot be applied; ``str()`` is one line naming the ship
    and the field."""


@dataclass(frozen=True)
class Command:
    """From tick ``tick`` on, ship ``ship_id`` is given these inputs: ``throttle`` 0..1 of its
    max_thrust, ``rcs`` -1..1 of max_rcs_torque per body axis, ``hold`` a HoldMode value."""

    tick: int
    ship_id: str
    throttle: float = 0.0
    rcs: tuple[float, float, float] = (0.0, 0.0, 0.0)
    hold: int = int(HoldMode.OFF)

    def check(self) -> "Command":
        """This command if every value is in range, else CommandError naming the field."""
        where = f"command for ship {self.ship_id!r} at tick {self.tick}"
        if not isinstance(self.tick, int) or self.tick < 0:
            raise CommandError(f"{where}: tick must be a whole number >= 0")
        lo, hi = THROTTLE
        if not (_finite(self.throttle) and lo <= self.throttle <= hi):
            raise CommandError(f"{where}: throttle must be {lo:g}..{hi:g}, got {self.throttle!r}")
        lo, hi = RCS
        if len(self.rcs) != 3 or not all(_finite(x) and lo <= x <= hi for x in self.rcs):
            raise CommandError(f"{where}: rcs must be three numbers in {lo:g}..{hi:g}, got "
                               f"{self.rcs!r}")
        if self.hold not in {int(m) for m in HoldMode}:
            raise CommandError(f"{where}: hold must be one of {', '.join(HOLD_MODES)}, got "
                               f"{self.hold!r}")
        return self


def _finite(x) -> bool:
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


@dataclass(frozen=True)
class Timeline:
    """Joins, leaves and commands, each sorted by tick (ties in the order they were given)."""

    spawns: tuple[Spawn, ...] = ()
    retires: tuple[Retire, ...] = ()
    commands: tuple[Command, ...] = ()

    @staticmethod
    def of(spawns=(), retires=(), commands=()) -> "Timeline":
        key = lambda x: x.tick  # noqa: E731 - a stable sort keeps same-tick order
        return Timeline(tuple(sorted(spawns, key=key)), tuple(sorted(retires, key=key)),
                        tuple(sorted(commands, key=key)))

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
