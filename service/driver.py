"""The one driver loop: step the world a block at a time, then hand the block to the sinks.

    world -> blocks -> LogWriter (returns the block's events as messages) -> the other sinks

Ctrl-C is handled here and only here: the first asks the loop to stop after the block in hand, so
that no library call (compression, a chunk being written) is cut in half, and the log is finished
with ``complete = false``; a second before then stops at once and removes the partial file. While
finishing or cleaning up, Ctrl-C is ignored: a file is either finished under its name or gone,
never a footerless ``.partial``.
"""
from __future__ import annotations

import itertools
import signal
import sys
import threading
from dataclasses import dataclass
from typing import Callable, Protocol, Sequence

from touchdown.logs.writer import LogWriter
from touchdown.proto import touchdown_pb2 as pb
from touchdown.sim.world import Block, World


class Sink(Protocol):
    """Takes each block after the log (with its events as the log wrote them)."""

    def __call__(self, block: Block, events: list[pb.TransitionEvent]) -> None: ...


@dataclass
class Outcome:
    """How a drive ended: ``done`` (reached its last tick), ``interrupted`` (Ctrl-C: the log is
    finished, marked incomplete) or ``abandoned`` (Ctrl-C twice: nothing kept)."""

    how: str
    last_tick: int
    events: int

    @property
    def exit_code(self) -> int:
        return 0 if self.how == "done" else 130


def drive(world: World, last_tick: int, log: LogWriter | None = None,
          sinks: Sequence[Sink] = (), progress: str | None = None,
          first_block: bool = True, on_close: Callable[[], None] | None = None) -> Outcome:
    """Step ``world`` to ``last_tick`` (with its own tick's record first, if ``first_block``),
    writing each block to ``log`` and handing it to ``sinks``. The log is closed (or removed)
    here. ``progress``: a label for a progress bar on a terminal."""
    stop = _Interrupts()
    prog = _progress(last_tick, progress) if progress else None
    events = 0
    how = "done"
    last = world.tick
    try:
        stop.install()
        blocks = world.blocks(last_tick)
        if first_block:
            blocks = itertools.chain([world.first_block()], blocks)
        for block in blocks:
            msgs = log.write_block(block) if log is not None else []
            events += len(msgs)
            for sink in sinks:
                sink(block, msgs)
            last = block.last_tick
            if prog is not None:
                prog.update(prog.task_ids[0], completed=block.last_tick)
            if stop.asked:
                how = "interrupted"
                break
        stop.busy = True
        if log is not None:
            log.close(complete=how == "done", reason="" if how == "done" else "interrupted")
    except KeyboardInterrupt:  # the second Ctrl-C
        how = "abandoned"
        if log is not None:
            log.abandon()
    except BaseException:
        stop.busy = True
        if log is not None:
            log.abandon()
        raise
    finally:
        if prog is not None:
            prog.stop()
        if on_close is not None:
            on_close()
        stop.restore(exiting=how != "done")
    return Outcome(how, last, events)


class _Interrupts:
    """SIGINT while driving: the first sets ``asked``, a second (unless ``busy`` finishing)
    raises KeyboardInterrupt. Only the main thread can take signals; elsewhere nothing changes."""

    def __init__(self):
        self.count = 0
        self.busy = False
        self._previous = None

    @property
    def asked(self) -> bool:
        return self.count > 0

    def _on_sigint(self, signum, frame) -> None:
        self.count += 1
        if self.count > 1 and not self.busy:
            self.busy = True
            raise KeyboardInterrupt

    def install(self) -> None:
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._on_sigint)

    def restore(self, exiting: bool) -> None:
        if self._previous is None:
            return
        # exiting on Ctrl-C: a late one must not turn exit 130 into death by SIGINT
        signal.signal(signal.SIGINT, signal.SIG_IGN if exiting else self._previous)
        self._previous = None


def _progress(total: int, label: str):
    """A rich progress bar on a terminal; nothing otherwise."""
    if not sys.stdout.isatty():
        return None
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
    prog = Progress(TextColumn(label), BarColumn(), TextColumn("{task.completed}/{task.total} ticks"),
                    TimeRemainingColumn())
    prog.start()
    prog.add_task(label, total=total)
    return prog


def record(scn, path, source: str = "", keyframe_interval: int = 1,
           world: World | None = None) -> Outcome:
    """Run scenario ``scn`` (or ``world``, built from it) to its end into the log at ``path``:
    what ``touchdown record`` does, without its Redis and its messages."""
    from touchdown.logs.header import scenario_message
    writer = LogWriter(path, scenario_message(scn, source or scn.name, keyframe_interval))
    return drive(world if world is not None else World.of(scn), scn.params.sim.n_ticks, writer)
