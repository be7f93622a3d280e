"""One shard of a live service's ships: a World, the autopilot's ships, the shard's flight log,
and the numbered entries it has emitted. No Redis here (service.redis_io is the edge): a tick is

    requests (parsed commands) -> the World's commands, joins and leaves  (or rejections)
    autopilot -> commands for the ships it flies
    step one tick -> the flight log -> transition events
    -> the tick's entries for the event stream, numbered, and the ships whose hash changed

Every entry the shard emits has a number, counting from the shard's creation, that is the same
whichever worker re-derives it: the step is a pure function of the world and the journal's
requests, so a worker that takes the shard over from a checkpoint re-emits the same entries with
the same numbers, and the event stream keeps the first of each (service.redis_io.PUBLISH).
"""
from __future__ import annotations

import itertools
import json
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from touchdown.proto import service_pb2 as spb
from touchdown.logs.header import LABELS, SEED_STRINGS, surface_state
from touchdown.logs.redis_stream import event_entry
from touchdown.service.autopilot import AutolandOutcome, autoland_commands
from touchdown.service.commands import Rejected, Request
from touchdown.service.kinds import KINDS, apply
from touchdown.service.telemetry import telemetry_message
from touchdown.sim.enums import SurfaceState
from touchdown.sim.world import Block, World

REJECTED = "ship.command_rejected"
RETIRED = "ship.retired"
AUTOLAND_DONE = "ship.autoland_complete"
AUTOLAND_FAILED = "ship.autoland_failed"


class Entry(NamedTuple):
    """One entry for the event stream: its number in the shard's sequence (a successor re-emits
    the same entries with the same numbers; Redis's mark drops those already out) and its
    fields."""

    number: int
    fields: dict


@dataclass
class TickOut:
    """What one tick of a shard gives the outside: ``entries`` for the event stream (each an
    :class:`Entry`), ``hashes`` (ship id -> its hash's fields, None: the ship left), and the
    block that was stepped (for telemetry)."""

    entries: list[Entry] = field(default_factory=list)
    hashes: dict[str, dict | None] = field(default_factory=dict)
    blocks: list[Block] = field(default_factory=list)
    #: what each request came to, for the shard's results stream: JSON of {stream: {"applied":
    #: [entry ids], "rejected": [entry ids]}} ("" when the tick had no requests)
    results: str = ""


@dataclass(frozen=True)
class Limits:
    """What one shard admits (settings of ``touchdown serve``; 0: no limit)."""

    max_ships: int = 20_000  # ships in the shard; a spawn past it is rejected
    max_commands_per_ship: int = 4  # commands for one ship in one tick; the rest rejected
    #: rejection events a tick for one sender (a player); the rest counted, not published
    max_rejections: int = 100


@dataclass
class Counts:
    applied: int = 0
    rejected: int = 0  # every rejection, published or not
    unpublished: int = 0  # rejections counted only (past Limits.max_rejections in a tick)


@dataclass
class Shard:
    index: int
    world: World
    log: object  # service.flightlog.ServiceLog (write_block, flush, close)
    body: str
    autoland: dict[str, None] = field(default_factory=dict)  # insertion-ordered set
    published: int = 0  # entries emitted so far: the next one's number
    limits: Limits = field(default_factory=Limits)
    counts: Counts = field(default_factory=Counts)
    #: the command streams its entries come from: its own, and the shared one they are routed
    #: from (a rejection names the entry by stream and id)
    streams: tuple[str, str] = ("", "")

    @property
    def tick(self) -> int:
        return self.world.tick

    def step(self, requests: list[Request | Rejected], phase=None) -> TickOut:
        """Apply ``requests`` at this tick, fly the autopilot's ships, step one tick.
        ``phase``: a service.phases.Phases to time the parts in (or None)."""
        phase = phase or _no_phase
        out = TickOut()
        t = self.world.tick
        pending: dict[str, list] = {}
        self._per_ship: dict[str, int] = {}
        self._ships_next = self.world.state.n  # with the spawns accepted this tick
        shown: dict[str, int] = {}
        results: dict[str, dict[str, list]] = {}
        for req in requests:
            reason = self._apply(req, pending) if isinstance(req, Request) else req.reason
            stream = self.streams[1] if req.origin else self.streams[0]
            by = results.setdefault(stream, {"applied": [], "rejected": []})
            by["applied" if reason is None else "rejected"].append(req.origin or req.entry_id)
            if reason is None:
                self.counts.applied += 1
                continue
            self.counts.rejected += 1
            sender = req.player_id
            if self.limits.max_rejections and shown.get(sender, 0) >= self.limits.max_rejections:
                self.counts.unpublished += 1
                continue
            shown[sender] = shown.get(sender, 0) + 1
            self._emit(out, self._rejection(req, reason, t))
        if results:
            out.results = json.dumps(results, separators=(",", ":"))
        with phase("autopilot"):
            self._autopilot(out, pending, t)
        self.world.commands((sid, *given) for sid, given in pending.items())
        with phase("step"):
            blocks = list(self.world.blocks(t + 1))
        waits = getattr(self.log, "waits", None)
        serialized = getattr(self.log, "write_block_serialized", None)
        for block in blocks:
            before = waits() if waits else None
            with phase("log"):
                if serialized is not None:  # (each event serialized once: the log's bytes)
                    msgs, datas = serialized(block)
                else:
                    msgs = self.log.write_block(block)
                    datas = [m.SerializeToString() for m in msgs]
            if before:  # within "log": the writer's queue full, and rotations (wall seconds)
                for name, was, now in zip(("log_queue_full", "log_rotation"), before, waits()):
                    if now > was:
                        phase.add(name, now - was, 0.0)
            out.blocks.append(block)
            rows = {sid: i for i, sid in enumerate(block.ship_ids)} if block.spawned else {}
            for sp in block.spawned:
                out.hashes[sp.ship_id] = ship_hash(SurfaceState(int(
                    block.states[0]["surface_state"][rows[sp.ship_id]])), self.body,
                    block.first_tick,
                    sp.spec.get("player_id") or "player-" + sp.ship_id, self.index)
            for r in block.retired:
                out.hashes[r.ship_id] = None
                self.autoland.pop(r.ship_id, None)
                self._emit(out, {"event": RETIRED, "ship_id": r.ship_id,
                                 "player_id": self._player(r.ship_id), "body": self.body,
                                 "tick": str(block.first_tick)})
            # (the log's messages are the block's events, in order: their entries and hashes
            # made from the events' own numbers, not read back out of each message)
            # (an EventMessages has each event's player and the body: no message parsed)
            players = getattr(msgs, "player_ids", None)
            bodies = (itertools.repeat(msgs.body) if players is not None
                      else [m.body for m in msgs])
            if players is None:
                players = [m.player_id for m in msgs]
            for ev, player, body, data in zip(block.events, players, bodies, datas):
                self._emit(out, event_entry(ev, player, body, data))
                out.hashes[ev.ship_id] = ship_hash(surface_state(ev.to_state), self.body,
                                                   int(ev.tick), player, self.index)
        return out

    # -- requests ---------------------------------------------------------------------------
    def _apply(self, req: Request, pending: dict[str, list]) -> str | None:
        """Apply one request as its kind says (service.kinds); the reason it cannot be
        applied, or None."""
        kind, sid, lim = KINDS[req.cmd], req.ship_id, self.limits
        if kind.of_ship:
            owner = self._owner(sid)
            if owner is not None and req.player_id and owner != req.player_id:
                return (f"{req.cmd}: ship {sid!r} belongs to another player (player_id "
                        f"{req.player_id!r} may command only its own ships)")
            n = self._per_ship.get(sid, 0) + 1
            self._per_ship[sid] = n
            if lim.max_commands_per_ship and n > lim.max_commands_per_ship:
                return (f"{req.cmd}: more than {lim.max_commands_per_ship} commands for ship "
                        f"{sid!r} in tick {self.world.tick} (the per-ship rate)")
        if kind.ships > 0 and lim.max_ships and self._ships_next >= lim.max_ships:
            return (f"{req.cmd}: shard {self.index} is full ({lim.max_ships:,} ships, "
                    f"the most a shard takes)")
        reason = apply(self.world, req, pending, self.autoland)
        if reason is None:
            self._ships_next += kind.ships
        return reason

    def _row(self, sid: str) -> int | None:
        return self.world.row(sid)

    def _autopilot(self, out: TickOut, pending: dict[str, list], t: int) -> None:
        if not self.autoland:
            return
        row = self.world.row  # (an index kept while the fleet is the same: no set a tick)
        flying = sorted(s for s in self.autoland if row(s) is not None)
        for gone in [s for s in self.autoland if row(s) is None]:
            self.autoland.pop(gone)
        if not flying:
            return
        commands, outcomes = autoland_commands(self.world, flying)
        for c in commands:
            pending[c.ship_id] = [c.throttle, (0.0, 0.0, 0.0), c.hold]
        for sid in sorted(outcomes):
            outcome = outcomes[sid]
            self.autoland.pop(sid, None)
            event = AUTOLAND_DONE if outcome is AutolandOutcome.LANDED else AUTOLAND_FAILED
            self._emit(out, {"event": event, "ship_id": sid, "player_id": self._player(sid),
                             "body": self.body, "tick": str(t), "result": outcome.label})

    def _rejection(self, req, reason: str, t: int) -> dict:
        """The event that tells the sender: ``player_id`` is the sender's (the entry's), the
        ship's owner is ``owner_id`` where it is another player, and the entry is named by the
        ``stream`` it was read from and its ``entry_id`` there."""
        fields = {"event": REJECTED, "ship_id": req.ship_id, "player_id": req.player_id,
                  "body": self.body, "tick": str(t), "cmd": req.cmd, "reason": reason,
                  "stream": self.streams[1] if req.origin else self.streams[0],
                  "entry_id": req.origin or req.entry_id}
        owner = self._owner(req.ship_id) if req.ship_id else None
        if owner and owner != req.player_id:
            fields["owner_id"] = owner
        return fields

    def _owner(self, sid: str) -> str | None:
        """The player of ship ``sid`` (present, or known to this shard), or None."""
        i = self._row(sid)
        if i is not None:
            return self.world.params.ships.player_id[i]
        spec = self.world.known.get(sid)
        return (spec.get("player_id") or "player-" + sid) if spec else None

    def _player(self, sid: str) -> str:
        i = self._row(sid)
        if i is not None:
            return self.world.params.ships.player_id[i]
        spec = self.world.known.get(sid)
        return (spec.get("player_id") or "player-" + sid) if spec else ""

    def _emit(self, out: TickOut, fields: dict) -> None:
        fields["seq"] = f"{self.index}:{self.published}"
        out.entries.append(Entry(self.published, fields))
        self.published += 1

    @staticmethod
    def _state_of(block: Block, sid: str) -> int:
        return int(block.states[0]["surface_state"][block.ship_ids.index(sid)])

    # -- what other services read --------------------------------------------------------------
    def hashes_of(self, rows: np.ndarray, tick: int) -> dict[str, dict]:
        """The hash fields of the ships at ``rows`` (row numbers of the present fleet)."""
        ids = self.world.ship_ids
        players = self.world.params.ships.player_id
        states = self.world.state.rows["surface_state"]
        return {ids[i]: ship_hash(surface_state(states[i]), self.body, tick, players[i],
                                  self.index) for i in rows}

    @staticmethod
    def telemetry(block: Block, rows: np.ndarray, dt_s: float, index: int = 0
                  ) -> spb.Telemetry:
        """A sample of the ships at ``rows`` of ``block``'s last tick: where they are, how
        fast, how tilted (the step's own outputs of that tick: nothing recomputed). The service
        sends the same as bytes (service.telemetry.TelemetryEncoder), made without this
        message."""
        return telemetry_message(block.states[-1], block.outputs[-1], block.ship_ids, rows,
                                 block.last_tick, dt_s, index)


class _NoPhases:
    """service.phases.Phases for a shard stepped without one: nothing timed."""

    @contextmanager
    def __call__(self, name: str):
        yield

    def add(self, name: str, wall: float, cpu: float) -> None:
        pass


_no_phase = _NoPhases()


def ship_hash(state: SurfaceState, body: str, tick: int, player_id: str, shard: int) -> dict:
    """A ship's hash (SPEC.md section 5): its state, the seed's surface_contact_state and
    landed_body_name, the tick they hold at."""
    return {"state": LABELS[state], "surface_contact_state": SEED_STRINGS[state],
            "landed_body_name": "" if state is SurfaceState.FLYING else body,
            "tick": str(tick), "player_id": player_id, "shard": str(shard)}
