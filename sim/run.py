"""Running a scenario: a fold of the step over its ships' joins, leaves and commands (sim.world).
Pure: no I/O, no clock.

The ticks are stepped in blocks by the compiled loop (sim.step.step_ticks): a block holds every
state, telemetry and command of its ticks as record arrays, so a long run of one ship pays the
interpreter once per block, not once per tick, and a consumer (the log, a comparison) takes a block
at a time. :func:`run` gives the same ticks one record at a time.
"""
from __future__ import annotations

from typing import Iterator

from touchdown.sim.scenario import Scenario
from touchdown.sim.world import Block, TickRecord, World, block_ticks  # noqa: F401 - re-exported


def run_blocks(scn: Scenario, last_tick: int | None = None, max_ticks: int | None = None
               ) -> Iterator[Block]:
    """The run as blocks: the tick-0 record first, then blocks until ``last_tick`` (default: the
    scenario's duration) of at most ``max_ticks`` (World.blocks)."""
    world = World.of(scn)
    yield world.first_block()
    last = scn.params.sim.n_ticks if last_tick is None else last_tick
    yield from world.blocks(last, max_ticks)


def run(scn: Scenario, last_tick: int | None = None) -> Iterator[TickRecord]:
    """Yield the tick-0 record, then one record per step until ``last_tick`` (default: the
    scenario's duration)."""
    for block in run_blocks(scn, last_tick):
        yield from block.records()
