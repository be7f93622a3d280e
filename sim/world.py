"""A fleet through time: ships join and leave between ticks, commands come in, and the step folds
over them. Pure: no I/O, no clock.

A :class:`World` holds the ships present at its tick (their parameters, state and the commands in
force, each row named by its ship id) and a :class:`sim.timeline.Timeline` of what is still to
come. :meth:`World.blocks` steps it in blocks of ticks with the compiled loop
(sim.step.step_ticks); a block ends before every tick at which ships join or leave, and that tick
is stepped as a block of its own, so the records of each block share one list of ships.

Why a ship's numbers never depend on its neighbours: the step is a loop over ships with nothing
shared between them but the scene (sim.step), so removing a row or appending one changes no other
row's arithmetic; the body's rotation at a tick is a function of the tick alone.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterator

import numpy as np

from touchdown.sim import vec
from touchdown.sim.compiled import entry, kernel
from touchdown.sim.params import Params, ShipParams
from touchdown.sim.placement import quat_from_axes
from touchdown.sim.scenario import Scenario, Scene, parse
from touchdown.sim.state import (COMMAND_DTYPE, INPUTS_DTYPE, OUTPUTS_DTYPE, STATE_DTYPE,
    TRANSITION_DTYPE, Event, Inputs, Outputs, State, concatenate)
from touchdown.sim.step import (Queue, Span, Written, outputs_at, resting, rotations, step_ticks,
    tick_capacity, transitions)
from touchdown.sim.fields import INPUTS as INPUT_FIELDS
from touchdown.sim.timeline import INPUTS, Command, CommandError, Retire, Spawn, Timeline, command_of

#: A block holds about this many bytes of records: long enough that the interpreter's share of a
#: lone ship's tick is small, short enough to stay in cache.
BLOCK_BYTES = 1 << 20
MAX_BLOCK_TICKS = 1024


@dataclass(frozen=True)
class TickRecord:
    """The state at ``tick`` (time tick * dt), what the tick reported, the transitions that led to
    it, and the commands that were applied during the step into it (tick 0: none yet)."""

    tick: int
    state: State
    outputs: Outputs
    events: list[Event]
    inputs: Inputs
    ship_ids: tuple[str, ...] = ()


@dataclass(frozen=True)
class Block:
    """Consecutive ticks of a run: row k of each array is tick ``first_tick + k``, column i ship
    ``ship_ids[i]``. ``spawned`` and ``retired``: the ships that joined and left at
    ``first_tick`` (a block starts at every such tick); ``commands``: those applied in the steps
    into this block's ticks (their ticks ``first_tick - 1 .. last_tick - 1``)."""

    first_tick: int
    states: np.ndarray  # (K, N) STATE_DTYPE: the state at the end of each tick
    outputs: np.ndarray  # (K, N) OUTPUTS_DTYPE: what each tick reported
    inputs: np.ndarray  # (K, N) INPUTS_DTYPE: the commands applied in the step into each tick
    events: list[Event]  # the transitions, in order
    ship_ids: tuple[str, ...] = ()
    spawned: tuple[Spawn, ...] = ()
    retired: tuple[Retire, ...] = ()
    commands: tuple[Command, ...] = ()

    def __len__(self) -> int:
        return int(self.states.shape[0])

    @property
    def last_tick(self) -> int:
        return self.first_tick + len(self) - 1

    def records(self) -> Iterator[TickRecord]:
        by_tick: dict[int, list[Event]] = {}
        for ev in self.events:
            by_tick.setdefault(ev.tick, []).append(ev)
        for k in range(len(self)):
            tick = self.first_tick + k
            yield TickRecord(tick, State(rows=self.states[k], tick=tick),
                             Outputs(rows=self.outputs[k]), by_tick.get(tick, []),
                             Inputs(rows=self.inputs[k]), self.ship_ids)


def block_ticks(n_ships: int) -> int:
    per_tick = n_ships * (STATE_DTYPE.itemsize + OUTPUTS_DTYPE.itemsize + INPUTS_DTYPE.itemsize)
    return max(1, min(MAX_BLOCK_TICKS, BLOCK_BYTES // max(per_tick, 1)))


@dataclass
class World:
    """The ships present at ``state.tick``, the commands in force, and what is still to come.

    ``spawn``, ``retire`` and ``command`` add to what is to come: a ship joins or leaves at the
    next tick, a command holds from the step that begins at this tick. Each is checked when given
    (CommandError, one line naming the ship and the field), so that nothing that was accepted can
    fail later, and is recorded in the blocks, which is what a log keeps and a replay folds over.
    The world steps its own state in place (``state`` is the world now; the blocks hold copies).
    """

    scene: Scene
    params: Params
    state: State
    inputs: Inputs
    timeline: Timeline = field(default_factory=Timeline)
    #: ship id -> its table, for every ship that has been in this world (a spawned id is never
    #: reused: it names one ship in a log)
    known: dict[str, dict] = field(default_factory=dict)
    _index: tuple = field(default=((), {}), repr=False)  # ship ids -> rows, for the fleet of now
    _own: tuple = field(default=(None, None), repr=False)  # the state and inputs it stepped
    #: (sim.step.Resting, the params it was for): the ships at a fixed point of the step
    _resting: tuple = field(default=(None, None), repr=False)

    @classmethod
    def of(cls, scn: Scenario) -> "World":
        """The scenario's ships at tick 0, with its joins, leaves and commands to come."""
        known = {s["id"]: s for s in scn.resolved["ships"]}
        return cls(scn.scene, scn.params, scn.initial, Inputs.zeros(scn.initial.n), scn.timeline,
                   known)

    @classmethod
    def empty(cls, scene: Scene, tick: int = 0) -> "World":
        """No ships yet, at ``tick``: a live service's world before anything is spawned."""
        placeholder = parse({**scene.doc, "ships": [{"id": "_"}]}, scene.source)
        none = np.zeros(1, dtype=bool)
        state = State(rows=placeholder.initial.select(none).rows, tick=tick)
        return cls(scene, placeholder.params.take(none), state, Inputs.zeros(0))

    @classmethod
    def restore(cls, scene: Scene, ships: ShipParams, state: State, inputs: Inputs,
                known: dict[str, dict]) -> "World":
        """The world of ``ships`` in ``state`` with ``inputs`` in force (a checkpoint's), with
        nothing to come; ``known``: the tables of every ship that has been in it."""
        base = cls.empty(scene, state.tick)
        return cls(scene, base.params.with_ships(ships), state, inputs, Timeline(), dict(known))

    def select(self, keep: np.ndarray, timeline: Timeline | None = None,
               known: dict[str, dict] | None = None) -> "World":
        """The world of the ships ``keep`` (a mask over the rows) alone, at this tick: their
        parameters, state and inputs in force; what is to come is ``timeline`` (by default this
        world's) and the ships that have been in it ``known`` (by default this world's). A new
        world: this one is left as it is."""
        return World(self.scene, self.params.take(keep), self.state.select(keep),
                     self.inputs.select(keep), self.timeline if timeline is None else timeline,
                     dict(self.known if known is None else known))

    @property
    def tick(self) -> int:
        return self.state.tick

    @property
    def ship_ids(self) -> tuple[str, ...]:
        return self.params.ships.ship_id

    # -- what comes from outside ---------------------------------------------------------------
    def spawn(self, spec: dict) -> str:
        """Ship ``spec`` (one ``[[ships]]`` table, SPEC.md section 3) joins at the next tick;
        returns its id. ScenarioError on a bad table; CommandError on an id in use."""
        ships, _state = self.scene.ship(spec)  # checked here, by the scenario's rules
        ship_id = ships.ship_id[0]
        if ship_id in self.known:
            raise CommandError(f"spawn: ship id {ship_id!r} is taken (ids name one ship for "
                               f"the life of a run)")
        resolved = dict(spec, id=ship_id)
        self.known[ship_id] = resolved
        self._add(spawns=[Spawn(self.tick + 1, resolved)])
        return ship_id

    def retire(self, ship_id: str) -> None:
        """Ship ``ship_id`` leaves at the next tick."""
        if ship_id not in self._present_next():
            raise CommandError(f"retire: no ship {ship_id!r} in the fleet")
        self._add(retires=[Retire(self.tick + 1, ship_id)])

    def command(self, ship_id: str, *values, **named) -> Command:
        """Inputs for ship ``ship_id`` from the step that begins at this tick: each of
        sim.fields.INPUTS (throttle, rcs, hold) in that order or by name, zero (hold off) if
        left out."""
        given = dict(zip(INPUTS, values, strict=False))
        unknown = set(named) - set(INPUTS)
        if unknown or len(values) > len(INPUTS) or set(given) & set(named):
            raise TypeError(f"command takes the inputs {', '.join(INPUTS)}, got "
                            f"{len(values)} positional and {sorted(named)}")
        given.update(named)
        return self.commands([(ship_id, *(given.get(f.name, f.default) for f in INPUT_FIELDS))])[0]

    def commands(self, given) -> list[Command]:
        """Many ships' inputs at once, each ``(ship_id, *inputs)`` (sim.fields.INPUTS' order:
        throttle, rcs, hold): as many calls of :meth:`command`, in one pass (a live service gives
        thousands a tick). All are checked before any is taken."""
        index = self._fleet_index()
        cmds = []
        for ship_id, *values in given:
            cmd = command_of(self.tick, ship_id, values).check()
            if ship_id not in index:
                raise CommandError(f"command: no ship {ship_id!r} in the fleet at tick "
                                   f"{self.tick}")
            cmds.append(cmd)
        self._add(commands=cmds)
        return cmds

    def row(self, ship_id: str) -> int | None:
        """The row of ship ``ship_id`` in the fleet of now, or None."""
        return self._fleet_index().get(ship_id)

    def _fleet_index(self) -> dict[str, int]:
        """Ship id -> row, for the fleet of now (built again only when the fleet changes)."""
        ids = self.ship_ids
        if self._index[0] is not ids:  # the same tuple while the fleet is the same
            self._index = (ids, {sid: i for i, sid in enumerate(ids)})
        return self._index[1]

    def _present_next(self) -> set[str]:
        ids = set(self.ship_ids)
        ids.update(s.ship_id for s in self.timeline.spawns if s.tick == self.tick + 1)
        ids.difference_update(r.ship_id for r in self.timeline.retires if r.tick == self.tick + 1)
        return ids

    def _add(self, spawns=(), retires=(), commands=()) -> None:
        t = self.timeline
        self.timeline = Timeline(_merged(t.spawns, spawns), _merged(t.retires, retires),
                                 _merged(t.commands, commands))

    # -- the fold --------------------------------------------------------------------------------
    def first_block(self) -> Block:
        """The record of this world's own tick, as the state is (a run's tick 0)."""
        st = self.state
        out = outputs_at(self.params, st)
        return Block(st.tick, st.rows[None, :].copy(), out.rows[None, :].copy(),
                     self.inputs.rows[None, :].copy(), [], self.ship_ids)

    def blocks(self, last_tick: int, max_ticks: int | None = None, ramp: bool = False
               ) -> Iterator[Block]:
        """Step to ``last_tick``, a block at a time (default about a megabyte of records; with
        ``ramp`` the first blocks are short and each twice the last, so a consumer that stops
        early has stepped at most twice what it used)."""
        ramp_size = 1
        while self.tick < last_tick:
            change = self._next_change()
            if change == self.tick + 1:
                yield self._change_tick()
                continue
            size = max_ticks or block_ticks(self.state.n)
            k_max = min(size, last_tick - self.tick, change - 1 - self.tick)
            if ramp:
                k_max = min(k_max, ramp_size)
                ramp_size *= 2
            yield self._step(k_max)

    def _next_change(self) -> int:
        t = self.timeline
        ticks = [x.tick for x in (t.spawns[:1] + t.retires[:1])]  # each sorted by tick
        return min(ticks) if ticks else 1 << 62

    def _step(self, k_max: int, spawned=(), retired=()) -> Block:
        """Up to ``k_max`` ticks of the present fleet (fewer if its transitions fill the block's
        room), with the commands of those ticks."""
        params, n, first = self.params, self.state.n, self.tick
        commands, rest = self._commands_until(first + k_max)
        table = self._command_table(commands)
        # the world's own arrays are stepped in place; any others (a scenario's initial state,
        # a keyframe's) are copied once, the first time
        state, inputs = self.state.rows, self.inputs.rows
        if state is not self._own[0]:
            state = state.copy()
        if inputs is not self._own[1]:
            inputs = inputs.copy()
        self._own = (state, inputs)
        states = np.empty((k_max, n), STATE_DTYPE)
        outputs = np.empty((k_max, n), OUTPUTS_DTYPE)
        ins = np.empty((k_max, n), INPUTS_DTYPE)
        cap = tick_capacity(params)
        events = np.empty(cap * min(k_max, 8), TRANSITION_DTYPE)
        event_ticks = np.empty(events.shape[0], np.int64)
        count = np.zeros(1, np.int64)
        # the ships at a fixed point of the step, carried from block to block of the same fleet
        # (a change of ships starts afresh); step_ticks compares their rows before it trusts them
        kept, of = self._resting
        self._resting = (resting(n, state, inputs, outputs, params.body.omega_radps == 0.0,
                                 kept if of is params else None), params)
        done, c = step_ticks(params.records, state, inputs, Queue(table, 0),
                             Span(first, rotations(params, first, k_max)),
                             Written(states, outputs, ins, events, event_ticks, count,
                                     self._resting[0]), cap)
        applied = commands[:c]
        self.timeline = Timeline(self.timeline.spawns, self.timeline.retires,
                                 commands[c:] + rest)
        m = int(count[0])
        ids = self.ship_ids
        self.state = State(rows=state, tick=first + done)
        self.inputs = Inputs(rows=inputs)
        return Block(first + 1, states[:done], outputs[:done], ins[:done],
                     transitions(events[:m], event_ticks[:m], self.params.sim.dt_s, ids), ids, tuple(spawned),
                     tuple(retired), applied)

    def _commands_until(self, tick: int) -> tuple[tuple[Command, ...], tuple[Command, ...]]:
        """The commands before ``tick`` (applied in the coming steps) and the rest."""
        cmds = self.timeline.commands
        k = 0
        while k < len(cmds) and cmds[k].tick < tick:
            k += 1
        return cmds[:k], cmds[k:]

    def _command_table(self, commands: tuple[Command, ...]) -> np.ndarray:
        table = np.zeros(len(commands), COMMAND_DTYPE)
        if not commands:  # most blocks: no index of the fleet built
            return table
        index = self._fleet_index()
        for k, c in enumerate(commands):
            if c.ship_id not in index:  # accepted only for present ships: a bad timeline
                raise CommandError(f"command for ship {c.ship_id!r} at tick {c.tick}: the ship "
                                   f"is not in the fleet then")
            table[k] = (c.tick, index[c.ship_id], c.inputs)
        return table

    def _change_tick(self) -> Block:
        """The tick at which ships join or leave: the leaving ships dropped, the rest stepped
        into it, the joining ones appended where their tables place them at that tick."""
        tick = self.tick + 1
        t = self.timeline
        retired = tuple(r for r in t.retires if r.tick == tick)
        spawned = tuple(s for s in t.spawns if s.tick == tick)
        self.timeline = Timeline(t.spawns[len(spawned):], t.retires[len(retired):], t.commands)
        if retired:
            gone = {r.ship_id for r in retired}
            keep = np.array([sid not in gone for sid in self.ship_ids], dtype=bool)
            self.params = self.params.take(keep)
            self.state = self.state.select(keep)
            self.inputs = self.inputs.select(keep)
            self.timeline = Timeline(self.timeline.spawns, self.timeline.retires,
                                     tuple(c for c in self.timeline.commands
                                           if c.ship_id not in gone))
        block = self._step(1, spawned, retired)
        if not spawned:
            return block
        new_ships, new_states = [], []
        for s in spawned:
            ships, st = self.scene.ship(s.spec)
            new_ships.append(ships)
            new_states.append(st)
            self.known.setdefault(s.ship_id, s.spec)
        ships = concatenate(new_ships)
        joined = State(rows=concatenate(new_states).rows, tick=tick)
        c, s_ = rotations(self.params, tick, 0)[0]
        if c != 1.0 or s_ != 0.0:
            _turn_rows(joined.rows, c, s_)
        their_outputs = outputs_at(self.params.with_ships(ships), joined)
        self.params = self.params.with_ships(concatenate([self.params.ships, ships]))
        self.state = State(rows=np.concatenate([self.state.rows, joined.rows]), tick=tick)
        self.inputs = Inputs(rows=np.concatenate([self.inputs.rows,
                                                  np.zeros(joined.n, INPUTS_DTYPE)]))
        return Block(tick, self.state.rows[None, :].copy(),
                     np.concatenate([block.outputs[0], their_outputs.rows])[None, :],
                     self.inputs.rows[None, :].copy(), block.events, self.ship_ids, spawned,
                     retired, block.commands)


@entry
def _turn_rows(rows, cos_t, sin_t):
    """Turn ships placed at tick 0 to where the body has carried their site by a tick whose
    rotation is (cos_t, sin_t) about the spin axis z: positions, velocities and attitudes turn;
    the body-frame angular velocity and the body-fixed pin fields do not."""
    for i in range(rows.shape[0]):
        r = rows[i]
        p = _rz((r.pos_m[0], r.pos_m[1], r.pos_m[2]), cos_t, sin_t)
        v = _rz((r.vel_mps[0], r.vel_mps[1], r.vel_mps[2]), cos_t, sin_t)
        q = (r.quat[0], r.quat[1], r.quat[2], r.quat[3])
        ex = _rz(vec.quat_rotate(q, (1.0, 0.0, 0.0)), cos_t, sin_t)
        ey = _rz(vec.quat_rotate(q, (0.0, 1.0, 0.0)), cos_t, sin_t)
        ez = _rz(vec.quat_rotate(q, (0.0, 0.0, 1.0)), cos_t, sin_t)
        q2 = quat_from_axes(ex, ey, ez)
        for k in range(3):
            r.pos_m[k] = p[k]
            r.vel_mps[k] = v[k]
        for k in range(4):
            r.quat[k] = q2[k]


@kernel
def _rz(v, c, s):
    return (c * v[0] - s * v[1], s * v[0] + c * v[1], v[2])


def _merged(old: tuple, new) -> tuple:
    """``old`` (in tick order) with ``new`` added, in tick order, same-tick order kept (as
    Timeline.of's stable sort); appended without a sort when ``new`` comes after ``old``, as a
    live service's commands and spawns do (hundreds a tick: a sort each was quadratic)."""
    new = tuple(new)
    if not new:
        return old
    ticks = [x.tick for x in new]
    if all(a <= b for a, b in zip(ticks, ticks[1:])) and (not old or old[-1].tick <= ticks[0]):
        return old + new
    return tuple(sorted(old + new, key=lambda x: x.tick))
