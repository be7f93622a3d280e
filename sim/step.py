"""The tick: ``step(params, state, inputs) -> (state, outputs, events)``, a pure function.

The batch API. The batch is stepped by one compiled loop over its ships (:func:`step_ticks`,
:func:`step_ships`; sim.compiled); each ship's tick is :func:`sim.phases.step_ship`, its phases
in order (sim.phases), the free flight among them (sim.flight). Before each tick the commands
for it are applied to the ships' inputs (:func:`apply_commands`); the events come back as
:class:`sim.state.Event` (:func:`transitions`).

A ship's numbers depend only on its own state, inputs and parameters: nothing is summed or compared
across ships, so a ship stepped alone or among thousands gives bit-identical results.
"""
from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np

from touchdown.sim.compiled import borrowed, entry, kernel, separate
from touchdown.sim.enums import TRANSITION_KINDS
from touchdown.sim.frames import body_rotation
from touchdown.sim.params import Params
from touchdown.sim.phases import observe, step_ship
from touchdown.sim.ship import (CRASHED, LANDED, NO_COMMANDS, NO_REPORT, TIPPED, Commands, EventLog,
    Here, Turn, load)
from touchdown.sim.state import (Event, INPUTS_DTYPE, Inputs, OUTPUTS_DTYPE, Outputs, STATE_DTYPE,
    State, TRANSITION_DTYPE, event_of)


class Written(NamedTuple):
    """Where step_ticks writes a block of ticks: row k of each per-tick array is the k-th tick."""

    states: np.ndarray  # (ticks, ships) sim.state.STATE_DTYPE
    outputs: np.ndarray  # (ticks, ships) OUTPUTS_DTYPE
    inputs: np.ndarray  # (ticks, ships) INPUTS_DTYPE: the commands in force
    events: np.ndarray  # TRANSITION_DTYPE, appended
    event_ticks: np.ndarray  # the tick each event led to
    count: np.ndarray  # count[0]: the events so far
    rest: "Resting"  # the ships at a fixed point: read, and updated as ships reach or leave one


class Resting(NamedTuple):
    """Ships at a fixed point of the step, which step_ticks does not step again: a ship whose tick
    gave back its state bit for bit with no transition, on a body that does not turn, is given
    the same state and telemetry at every later tick while its state and inputs stay as they were
    then (the step is a pure function of them, its parameters and the body's angles), so those
    ticks are copied instead of stepped. Landed and tipped ships at rest are such. Each array is a
    64-bit word view of its records (``_words``): rows compared and copied word by word."""

    on: bool  # the body does not turn: a pinned ship's pose is the same at every tick
    fixed: np.ndarray  # bool per ship: the fix_* rows hold its fixed point
    state_w: np.ndarray  # (ships, words) the state being stepped
    inputs_w: np.ndarray  # (ships, words) its inputs
    outputs_w: np.ndarray  # (ticks, ships, words) Written.outputs
    fix_state_w: np.ndarray  # (ships, words) each fixed ship's state ...
    fix_inputs_w: np.ndarray  # ... the inputs it stepped with ...
    fix_outputs_w: np.ndarray  # ... and its telemetry then
    before_w: np.ndarray  # (words,) scratch: a ship's state before its step


def _words(rows: np.ndarray) -> np.ndarray:
    """A 64-bit word view of a record array's rows (its last axis the record's words)."""
    return rows.view(np.uint64).reshape(rows.shape + (rows.dtype.itemsize // 8,))


def resting(n_ships: int, state: np.ndarray, inputs: np.ndarray, outputs: np.ndarray,
            on: bool, kept: Resting | None = None) -> Resting:
    """A Resting over these arrays; ``kept``: the fixed points of an earlier block of the same
    ships (their rows kept), else none known."""
    if kept is None or kept.fixed.shape[0] != n_ships:
        kept = Resting(on, np.zeros(n_ships, np.bool_), _words(state), _words(inputs),
                       _words(outputs), np.zeros((n_ships, STATE_DTYPE.itemsize // 8), np.uint64),
                       np.zeros((n_ships, INPUTS_DTYPE.itemsize // 8), np.uint64),
                       np.zeros((n_ships, OUTPUTS_DTYPE.itemsize // 8), np.uint64),
                       np.zeros(STATE_DTYPE.itemsize // 8, np.uint64))
    return kept._replace(on=on, state_w=_words(state), inputs_w=_words(inputs),
                         outputs_w=_words(outputs))


def no_resting(state: np.ndarray, inputs: np.ndarray, outputs: np.ndarray) -> Resting:
    """A Resting that finds no fixed point: every ship is stepped (``step``: one tick of a
    batch, where nothing is kept from tick to tick)."""
    return resting(state.shape[0], state, inputs, outputs, False)


@kernel
def _same_words(a, b):
    for j in range(a.shape[0]):
        if a[j] != b[j]:
            return False
    return True


@kernel
def _copy_words(src, dst):
    for j in range(src.shape[0]):
        dst[j] = src[j]


@separate
def step_ships(recs, state, inputs, outputs, turn, events, count):
    """Every ship's tick, one after another (``turn``: the body's angles, a :class:`Turn`):
    ``state`` is updated in place, ``outputs`` written, and the transitions appended to
    ``events`` (``count[0]`` of them; sim.ship.emit)."""
    cfg, ter, ships = recs.scene[0], recs.terrain[0], recs.ships
    for i in range(state.shape[0]):
        step_ship(Here(cfg, ter, ships[i], turn), state[i], inputs[i], outputs[i],
                  EventLog(borrowed(events), borrowed(count), i))


@kernel
def apply_commands(commands, c, tick, inputs):
    """The commands for ticks up to ``tick`` (``commands`` sorted by tick, from index ``c``) into
    the ships' ``inputs``; returns the index of the next command."""
    while c < commands.shape[0] and commands[c].tick <= tick:
        cmd = commands[c]
        inputs[cmd.ship] = cmd.inputs  # every input (sim.fields.INPUTS), whole
        c += 1
    return c


class Queue(NamedTuple):
    """The commands still to apply: ``table`` (sim.state.COMMAND_DTYPE, sorted by tick) from
    index ``next``."""

    table: np.ndarray
    next: int


class Span(NamedTuple):
    """The ticks a call steps: from ``first_tick``; ``rotations[k]`` is the body's (cos, sin) at
    the k-th one's start (:func:`rotations`)."""

    first_tick: int
    rotations: np.ndarray


@entry
def step_ticks(recs, state, inputs, queue, span, out, tick_capacity):
    """Ticks ``span.first_tick``, ``span.first_tick + 1``, ... one after another, up to
    ``len(out.states)`` (``recs``: :class:`Records`; ``out``: :class:`Written`): before the step
    from each tick the commands of ``queue`` for it are applied to ``inputs``; after it the state,
    the telemetry and the commands in force are row k of ``out.states``, ``out.outputs`` and
    ``out.inputs``. Transitions are appended to ``out.events`` (the tick each one led to in
    ``out.event_ticks``); the loop stops early when fewer than ``tick_capacity`` places are left.
    ``out.rest`` (:class:`Resting`): the ships at a fixed point, whose ticks are copied, not
    stepped; it is updated as ships reach or leave one. Returns (ticks stepped, index of the
    next command)."""
    cfg, ter, ships = recs.scene[0], recs.terrain[0], recs.ships
    commands, first_tick, rotations = queue.table, span.first_tick, span.rotations
    states_out, outputs_out, inputs_out = out.states, out.outputs, out.inputs
    events, event_ticks, count, rest = out.events, out.event_ticks, out.count, out.rest
    c = queue.next
    for k in range(states_out.shape[0]):
        if events.shape[0] - count[0] < tick_capacity:
            return k, c
        tick = first_tick + k
        c = apply_commands(commands, c, tick, inputs)
        n0 = count[0]
        # each ship's tick, one after another (as step_ships, whose own compiled library would
        # repeat this one's: step_ship is inlined here)
        out_k = outputs_out[k]
        turn = Turn(rotations[k, 0], rotations[k, 1], rotations[k + 1, 0], rotations[k + 1, 1])
        for i in range(state.shape[0]):
            if (rest.fixed[i] and _same_words(rest.state_w[i], rest.fix_state_w[i])
                    and _same_words(rest.inputs_w[i], rest.fix_inputs_w[i])):
                _copy_words(rest.fix_outputs_w[i], rest.outputs_w[k, i])
                continue
            # only a pinned ship can come back to its state bit for bit (a flying or sliding
            # one moves): the others are not watched, and pay nothing for it
            surf = state[i].surface_state
            watch = rest.on and (surf == LANDED or surf == TIPPED or surf == CRASHED)
            if watch:
                _copy_words(rest.state_w[i], rest.before_w)
            n_i = count[0]
            step_ship(Here(cfg, ter, ships[i], turn), state[i], inputs[i], out_k[i],
                      EventLog(borrowed(events), borrowed(count), i))
            fixed = (watch and count[0] == n_i
                     and _same_words(rest.state_w[i], rest.before_w))
            rest.fixed[i] = fixed
            if fixed:
                _copy_words(rest.state_w[i], rest.fix_state_w[i])
                _copy_words(rest.inputs_w[i], rest.fix_inputs_w[i])
                _copy_words(rest.outputs_w[k, i], rest.fix_outputs_w[i])
        for e in range(n0, min(count[0], events.shape[0])):
            event_ticks[e] = tick + 1
        # record by record: a slice assignment compiles numba's shape-mismatch message (string
        # formatting: about 2 s of a first compile) for shapes that always match here
        for i in range(state.shape[0]):
            states_out[k, i] = state[i]
            inputs_out[k, i] = inputs[i]
    return states_out.shape[0], c


def tick_capacity(params: Params) -> int:
    """Transitions a batch can make in a tick: per ship, a liftoff at its start, then per sub-step
    a located touchdown and the transition at its end (or a touchdown already past tipped_angle:
    two at once), none after a tip or crash, and landing after that."""
    return int(np.sum(2 * params.ships.n_substeps + 3))


def rotations(params: Params, first_tick: int, n_ticks: int) -> np.ndarray:
    """(cos, sin) of the body's angle at the start of ticks first_tick .. first_tick + n_ticks
    (sim.frames.body_rotation: one libm call per tick, outside the kernels)."""
    om, dt = params.body.omega_radps, params.sim.dt_s
    out = np.empty((n_ticks + 1, 2))
    if om == 0.0:
        out[:, 0], out[:, 1] = 1.0, 0.0
        return out
    for k in range(n_ticks + 1):
        out[k] = body_rotation(om, (first_tick + k) * dt)
    return out


def step(params: Params, state: State, inputs: Inputs) -> tuple[State, Outputs, list[Event]]:
    """Advance the batch by one tick (pure: ``state`` and ``inputs`` are not changed)."""
    n = state.n
    states, outputs, ins = (np.empty((1, n), STATE_DTYPE), np.empty((1, n), OUTPUTS_DTYPE),
                            np.empty((1, n), INPUTS_DTYPE))
    cap = tick_capacity(params)
    events, event_ticks = np.empty(cap, TRANSITION_DTYPE), np.empty(cap, np.int64)
    count = np.zeros(1, np.int64)
    rows, in_rows = state.rows.copy(), inputs.rows.copy()
    step_ticks(params.records, rows, in_rows, Queue(NO_COMMANDS, 0),
               Span(state.tick, rotations(params, state.tick, 1)),
               Written(states, outputs, ins, events, event_ticks, count,
                       no_resting(rows, in_rows, outputs)), cap)
    tick = state.tick + 1
    return (State(rows=states[0], tick=tick), Outputs(rows=outputs[0]),
            transitions(events[:count[0]], event_ticks[:count[0]], params.sim.dt_s))


def transitions(events: np.ndarray, ticks: np.ndarray, dt_s: float,
                ship_ids: Sequence[str] = ()) -> list[Event]:
    """The kernel's transitions as Events (by tick, then ship, each ship's in the order they
    happened), each named by its ship's id where ``ship_ids`` (the batch's, in order) are given.
    An event of the step into tick n happened t_offset after that step's start: at
    n dt - (dt - t_offset) (exactly n dt for one at the tick's end)."""
    out = []
    for e, tick in zip(events.tolist(), ticks.tolist()):
        ship, a, b, v, t_offset = e
        out.append(event_of(tick, ship, TRANSITION_KINDS[(a, b)], a, b, v,
                            ship_id=ship_ids[ship] if ship_ids else "",
                            t_event_s=tick * dt_s - (dt_s - t_offset)))
    return out


@entry
def observe_ships(scene, terrain, ships, state, outputs, cos_t, sin_t):
    """The telemetry of a batch at rest in its state (no commands, no forces of a step): what a
    log records for the tick a run starts from."""
    cfg, ter = scene[0], terrain[0]
    idle = Commands(0.0, 0.0, (0.0, 0.0, 0.0), False)
    for i in range(state.shape[0]):
        observe(Here(cfg, ter, ships[i], Turn(cos_t, sin_t, cos_t, sin_t)), load(state[i]), idle,
                NO_REPORT, outputs[i])


def outputs_at(params: Params, state: State) -> Outputs:
    """:func:`observe_ships` of ``state`` at its tick."""
    c, s = body_rotation(params.body.omega_radps, state.tick * params.sim.dt_s)
    out = Outputs.zeros(state.n)
    observe_ships(params.scene, params.terrain, params.ships.rows, state.rows, out.rows, c, s)
    return out
