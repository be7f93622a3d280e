"""The closed vocabularies of the simulation: surface states, transition events, hold modes."""
from __future__ import annotations

from enum import IntEnum


class SurfaceState(IntEnum):
    """The seed's surface states plus ``CRASHED`` (terminal). Values are stored in logs: never renumber."""

    FLYING = 0
    CONTACT = 1
    LANDED = 2
    TIPPED = 3
    CRASHED = 4

    @property
    def label(self) -> str:
        """Name used in exports and scenario files: ``flying``, ``contact``, ..."""
        return self.name.lower()

    @property
    def seed_string(self) -> str:
        """The seed's ``surface_contact_state`` string ("" while flying)."""
        return "" if self is SurfaceState.FLYING else self.label

    @classmethod
    def from_label(cls, label: str) -> "SurfaceState":
        return cls[label.upper()]


class EventKind(IntEnum):
    """Transition events, published as ``ship.<name>``. Values are stored in logs: never renumber."""

    CONTACT = 1
    LANDED = 2
    TIPPED = 3
    RIGHTED = 4
    CRASHED = 5
    LIFTOFF = 6

    @property
    def topic(self) -> str:
        return "ship." + self.name.lower()


class HoldMode(IntEnum):
    """Attitude-controller hold modes. ``OFF`` leaves the RCS to the player's commands alone."""

    OFF = 0
    KILL_ROTATION = 1  # drive the angular velocity relative to the body's surface to zero
    RADIAL = 2  # point the long axis along local up, and stop rotating

    @property
    def label(self) -> str:
        return self.name.lower()

    @classmethod
    def from_label(cls, label: str) -> "HoldMode":
        return cls[label.upper()]


S = SurfaceState
#: Every transition the model can take, and the event it publishes (the seed's table plus crashes).
TRANSITION_EVENTS: dict[tuple[SurfaceState, SurfaceState], EventKind] = {
    (S.FLYING, S.CONTACT): EventKind.CONTACT,
    (S.FLYING, S.CRASHED): EventKind.CRASHED,
    (S.CONTACT, S.LANDED): EventKind.LANDED,
    # a landed ship whose balance the player's thrust or RCS changes is in contact again
    # (MODEL-NOTES 45): its event is ship.contact, from landed
    (S.LANDED, S.CONTACT): EventKind.CONTACT,
    (S.CONTACT, S.TIPPED): EventKind.TIPPED,
    (S.CONTACT, S.FLYING): EventKind.LIFTOFF,
    (S.CONTACT, S.CRASHED): EventKind.CRASHED,
    (S.TIPPED, S.CONTACT): EventKind.RIGHTED,
    (S.TIPPED, S.CRASHED): EventKind.CRASHED,
    (S.TIPPED, S.FLYING): EventKind.LIFTOFF,
    (S.LANDED, S.FLYING): EventKind.LIFTOFF,
}
del S
#: TRANSITION_EVENTS in plain ints, (from, to) -> kind: what a block's transitions are turned into
#: events by (sim.step.transitions), where building two enums a transition cost a third of it
TRANSITION_KINDS: dict[tuple[int, int], int] = {(int(a), int(b)): int(k)
                                                for (a, b), k in TRANSITION_EVENTS.items()}
