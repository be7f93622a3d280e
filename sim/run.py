"""Running a scenario: replay as a fold of ``step`` over the input schedule. Pure: no I/O, no clock."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

from sim.scenario import Scenario
from sim.state import Event, Inputs, Outputs, State
from sim.step import outputs_at, step


@dataclass(frozen=True)
class TickRecord:
    """The state at ``tick`` (time tick * dt), what the tick reported, the transitions that led to
    it, and the commands that were applied during the step into it (tick 0: none yet)."""

    tick: int
    state: State
    outputs: Outputs
    events: list[Event]
    inputs: Inputs


def initial_record(scn: Scenario) -> TickRecord:
    st = scn.initial
    return TickRecord(0, st, outputs_at(scn.params, st), [], Inputs.zeros(st.n))


def run(scn: Scenario, start: State | None = None, start_inputs: Inputs | None = None,
        last_tick: int | None = None) -> Iterator[TickRecord]:
    """Yield the tick-0 record (unless ``start`` is given), then one record per step until
    ``last_tick`` (default: the scenario's duration)."""
    last = scn.params.sim.n_ticks if last_tick is None else last_tick
    if start is None:
        rec0 = initial_record(scn)
        yield rec0
        state = rec0.state
        inputs = scn.inputs_at(0)
    else:
        state = start
        inputs = scn.inputs_at(state.tick, start_inputs, state.tick - 1) if start_inputs is not None \
            else scn.inputs_at(state.tick)
    while state.tick < last:
        if state.tick > 0:
            inputs = scn.inputs_at(state.tick, inputs, state.tick - 1)
        new_state, out, events = step(scn.params, state, inputs)
        yield TickRecord(new_state.tick, new_state, out, events, inputs)
        state = new_state
