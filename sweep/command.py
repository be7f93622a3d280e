"""``touchdown sweep``'s work, apart from its options (cli.py)."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from touchdown.sim.errors import UserError, WorkFailed
from touchdown.sim.scenario import ScenarioError
from touchdown.sweep.cases import Sweep, parse_vary


def main(doc: dict, source: str, vary, samples, seed, output, chart, workers, scheduler,
         record_case) -> int:
    """The sweep; a bad definition raises SweepError or ScenarioError (exit 2, one line: cli.py's
    handler of every TouchdownError), a table that cannot be written WorkFailed."""
    sw = Sweep.of(doc, source, parse_vary(vary, samples is not None), samples, seed)
    name = str(doc.get("name", "sweep"))
    if record_case is not None:
        return _record(sw, record_case, output or f"{name}-case-{record_case}.mcap")
    out = Path(output) if output else Path(f"{name}-sweep.parquet")
    if scheduler:
        try:
            import distributed  # noqa: F401
        except ImportError:
            raise UserError("--scheduler needs Dask distributed: pip install -e '.[sweep]'") \
                from None
    if chart:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise UserError("--chart needs matplotlib: pip install -e '.[chart]'") from None
    from touchdown.sweep.run import run
    _compile_first()
    try:
        res = run(sw, workers=workers, scheduler=scheduler, progress=True)
    except ScenarioError as exc:  # values each valid alone, refused together (kinetic > static)
        raise UserError(f"a case of the sweep: {exc}") from None
    except OSError as exc:
        raise WorkFailed(f"--scheduler {scheduler}: {exc}") from None
    try:
        res.write(out, json.dumps(doc, default=str))
    except OSError as exc:
        raise WorkFailed(f"{out}: cannot write: {exc.strerror}") from None
    click.echo(res.summary())
    click.echo(f"{out}: {sw.n_cases:,} rows; {res.wall_s:.1f} s on {res.workers}")
    if chart:
        from touchdown.sweep.chart import draw
        draw(res.table(), chart)
        click.echo(f"{chart}: the envelope")
    if res.interrupted:
        missing = res.counts()["missing"]
        click.echo(f"interrupted: {sw.n_cases - missing:,} cases done are in {out}; "
                   f"{missing:,} are marked missing", err=True)
        return 130
    return 0


def _compile_first(say=None) -> bool:
    """Where the sweep's kernels are not in the cache (the first sweep after an install, or after
    a change to sim/), compile them here, once, before the workers start: each worker would
    otherwise compile the same code silently, all at once, then load them (seconds for the
    sweep's own reductions; minutes, and ~0.9 GB of memory each, for the step itself where
    `touchdown warm` has not compiled it). The command line's compile notice
    (sim.compiled.notify_compilation; ``say``, default: a line on a terminal) then names the
    sweep's kernels and `warm --sweep`.
    Returns whether they were missing."""
    from touchdown.sim.compiled import notify_compilation
    from touchdown.sweep.fleet import kernels_ready, ready
    if kernels_ready():
        return False

    def notice(_text):
        line = ("touchdown sweep: compiling the sweep's kernels for this CPU (once after an "
                "install or a change to sim/: seconds after `touchdown warm`, minutes without it; "
                "`touchdown warm --sweep` does it ahead) ...")
        if say is not None:
            say(line)
        elif sys.stderr.isatty():
            click.echo(line, err=True)
    notify_compilation(notice)
    ready()
    return True


def _record(sw: Sweep, case: int, output: str) -> int:
    """Case ``case`` alone, recorded as ``touchdown record`` records a scenario."""
    from touchdown.logs import LogError
    from touchdown.logs.header import scenario_message
    from touchdown.logs.writer import LogWriter
    from touchdown.service.driver import drive
    from touchdown.sim.world import World
    if case >= sw.n_cases:
        raise UserError(f"--record {case}: the sweep has cases 0..{sw.n_cases - 1}")
    scn = sw.case_scenario(case)
    out = Path(output)
    try:
        writer = LogWriter(out, scenario_message(scn, f"{sw.source} case {case}"))
    except OSError as exc:
        raise UserError(f"{out}: cannot write: {exc.strerror}") from None
    try:
        outcome = drive(World.of(scn), scn.params.sim.n_ticks, writer, progress=f"case {case}")
    except (LogError, OSError):
        raise WorkFailed(f"{out}: cannot write; nothing was kept (no {out})") from None
    if outcome.how != "done":
        click.echo(f"interrupted at tick {outcome.last_tick}", err=True)
        return 130
    values = ", ".join(f"{k} = {v:g}" for k, v in sw.overrides(case).items())
    click.echo(f"{out}: case {case} ({values}), {scn.params.sim.n_ticks + 1} ticks, "
               f"{outcome.events} event(s)")
    return 0
