"""Running a scenario: replay as a fold of the step over the commands. Pure: no I/O, no clock.

The ticks are stepped in blocks by the compiled loop (sim.step.step_ticks): a block holds every
state, telemetry and command of its ticks as record arrays, so a long run of one ship pays the
interpreter once per block, not once per tick, and a consumer (the log, a comparison) takes a block
at a time. :func:`run` gives the same ticks one record at a time.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

import numpy as np

from sim.scenario import Scenario
from sim.state import (INPUTS_DTYPE, OUTPUTS_DTYPE, STATE_DTYPE, TRANSITION_DTYPE, Event, Inputs,
                       Outputs, State)
from sim.step import outputs_at, rotations, step_ticks, tick_capacity, transitions

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


@dataclass(frozen=True)
class Block:
    """Consecutive ticks of a run: row k of each array is tick ``first_tick + k``."""

    first_tick: int
    states: np.ndarray  # (K, N) STATE_DTYPE: the state at the end of each tick
    outputs: np.ndarray  # (K, N) OUTPUTS_DTYPE: what each tick reported
    inputs: np.ndarray  # (K, N) INPUTS_DTYPE: the commands applied in the step into each tick
    events: list[Event]  # the transitions, in order

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
                             Inputs(rows=self.inputs[k]))


def initial_record(scn: Scenario) -> TickRecord:
    st = scn.initial
    return TickRecord(0, st, outputs_at(scn.params, st), [], Inputs.zeros(st.n))


def block_ticks(n_ships: int) -> int:
    per_tick = n_ships * (STATE_DTYPE.itemsize + OUTPUTS_DTYPE.itemsize + INPUTS_DTYPE.itemsize)
    return max(1, min(MAX_BLOCK_TICKS, BLOCK_BYTES // max(per_tick, 1)))


def run_blocks(scn: Scenario, start: State | None = None, last_tick: int | None = None,
               max_ticks: int | None = None, ramp: bool = False) -> Iterator[Block]:
    """The run as blocks: the tick-0 record first (unless ``start`` is given), then blocks of at
    most ``max_ticks`` (default: about a megabyte of records) until ``last_tick`` (default: the
    scenario's duration). ``ramp``: the first blocks are short and each twice the last, so a
    consumer that stops early (a cut log's replay) has stepped at most twice what it used.
    Commands come from the scenario; from ``start`` at tick T, those of ticks before T are in
    force."""
    params = scn.params
    last = params.sim.n_ticks if last_tick is None else last_tick
    if start is None:
        rec0 = initial_record(scn)
        yield Block(0, rec0.state.rows[None, :].copy(), rec0.outputs.rows[None, :].copy(),
                    rec0.inputs.rows[None, :].copy(), [])
        start = rec0.state
    commands = scn.commands
    c = int(np.searchsorted(commands["tick"], start.tick, side="left"))
    inputs = scn.inputs_at(start.tick - 1).rows.copy() if start.tick > 0 \
        else Inputs.zeros(start.n).rows
    state = start.rows.copy()
    n = start.n
    size = max_ticks or block_ticks(n)
    cap = tick_capacity(params)
    tick = start.tick
    ramp_size = 1
    while tick < last:
        k_max = min(size, last - tick)
        if ramp:
            k_max = min(k_max, ramp_size)
            ramp_size *= 2
        states = np.empty((k_max, n), STATE_DTYPE)
        outputs = np.empty((k_max, n), OUTPUTS_DTYPE)
        ins = np.empty((k_max, n), INPUTS_DTYPE)
        # a block's transitions: room for its first tick's worst case, and more as it goes
        events = np.empty(cap * min(k_max, 8), TRANSITION_DTYPE)
        event_ticks = np.empty(events.shape[0], np.int64)
        count = np.zeros(1, np.int64)
        done, c = step_ticks(params.scene, params.terrain, params.ships.rows, state, inputs,
                             commands, c, rotations(params, tick, k_max), states, outputs, ins,
                             events, event_ticks, count, tick, cap)
        m = int(count[0])
        yield Block(tick + 1, states[:done], outputs[:done], ins[:done],
                    transitions(events[:m], event_ticks[:m]))
        tick += done


def run(scn: Scenario, start: State | None = None, last_tick: int | None = None
        ) -> Iterator[TickRecord]:
    """Yield the tick-0 record (unless ``start`` is given), then one record per step until
    ``last_tick`` (default: the scenario's duration)."""
    for block in run_blocks(scn, start, last_tick):
        yield from block.records()
