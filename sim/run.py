"""Running a scenario: a fold of the step over its ships' joins, leaves and commands (sim.world).
Pure: no I/O, no clock.

The ticks are stepped in blocks by the compiled loop (sim.step.step_ticks): a block holds every
state, telemetry and command of its ticks as record arrays, so a long run of one ship pays the
interpreter once per block, not once per tick, and a consumer (the log, a comparison) takes a block
at a time. :func:`run` gives the same ticks one record at a time.
"""
from __future__ import annotations

from typing import Iterator

from sim.scenario import Scenario
from sim.state import State
from sim.world import Block, TickRecord, World, block_ticks  # noqa: F401 - re-exported


def world_at(scn: Scenario, start: State | None = None) -> World:
    """The scenario's world at tick 0, or at ``start`` (a state of its tick-0 ships, or of some of
    them, at tick ``start.tick``: those ships' commands before it in force, what comes later
    still to come)."""
    world = World.of(scn)
    if start is None:
        return world
    if start.n != world.state.n:  # some of the ships: which ones, by their places at tick 0
        raise ValueError("run from a state: give World a fleet of its own for a subset of ships")
    world.state = start
    world.inputs = scn.inputs_at(start.tick - 1)
    world.timeline = world.timeline.from_tick(start.tick)
    return world


def run_blocks(scn: Scenario, start: State | None = None, last_tick: int | None = None,
               max_ticks: int | None = None, ramp: bool = False) -> Iterator[Block]:
    """The run as blocks: the tick-0 record first (unless ``start`` is given), then blocks until
    ``last_tick`` (default: the scenario's duration); see World.blocks."""
    world = world_at(scn, start)
    if start is None:
        yield world.first_block()
    last = scn.params.sim.n_ticks if last_tick is None else last_tick
    yield from world.blocks(last, max_ticks, ramp)


def run(scn: Scenario, start: State | None = None, last_tick: int | None = None
        ) -> Iterator[TickRecord]:
    """Yield the tick-0 record (unless ``start`` is given), then one record per step until
    ``last_tick`` (default: the scenario's duration)."""
    for block in run_blocks(scn, start, last_tick):
        yield from block.records()
