"""The ``touchdown`` command line (SPEC.md section 2). Exit codes: 0 done, 1 the work failed,
2 bad usage or bad input (one line on stderr naming the file, key or field; no traceback).

Every error a user is told about is a sim.errors.TouchdownError (ScenarioError, LogError,
ServeError, ...), carrying its exit code; the root group's one handler (``Touchdown.invoke``)
prints it. A command catches an exception only to say what it means there (a file that cannot
be written: WorkFailed, "nothing was kept")."""
from __future__ import annotations

import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import click

import touchdown.scenarios as builtin
from touchdown.scenarios import parse_sets
from touchdown.bench.commands import bench
from touchdown.logs import LogError
from touchdown.sim.errors import TouchdownError, UserError, WorkFailed
from touchdown.sim.scenario import load_toml, parse_text
from touchdown.sim.settings import Integrator


class _Told(click.ClickException):
    """A TouchdownError as click shows and exits with it: ``touchdown: MESSAGE``, one line."""

    def __init__(self, exc: TouchdownError):
        super().__init__(str(exc))
        self.exit_code = exc.exit_code

    def show(self, file=None) -> None:
        click.echo(f"touchdown: {self.format_message()}", err=True)


class Touchdown(click.Group):
    """The root group: the one handler of every TouchdownError raised under any command."""

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except TouchdownError as exc:
            raise _Told(exc) from None


def load_scenario(spec: str, sets: tuple[str, ...] = ()):
    """A scenario from a TOML path or a built-in name; returns (scenario, source)."""
    overrides = parse_sets(sets)
    text, source = scenario_text(spec)
    return parse_text(text, source, overrides), source


def scenario_text(spec: str) -> tuple[str, str]:
    """The TOML text of a scenario file or a built-in name, and its source's name."""
    path = Path(spec)
    if path.suffix == ".toml" or path.exists():
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise UserError(f"{spec}: cannot read: {exc.strerror}") from None
        except UnicodeDecodeError:
            raise UserError(f"{spec}: not UTF-8 text") from None
        source = str(path)
    elif spec in builtin.names():
        text, source = builtin.text(spec), spec
    else:
        raise UserError(f"{spec}: no such file or built-in scenario (see `touchdown scenarios`)")
    return text, source


@click.group(cls=Touchdown, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="touchdown", message="%(version)s")
@click.pass_context
def main(ctx: click.Context) -> None:
    """Touchdown: what a spacecraft does in the seconds after it touches a planet's surface."""
    if ctx.invoked_subcommand != "export":  # (export loads compiled code only for some formats)
        _notify_compilation()


def _notify_compilation() -> None:
    from touchdown.sim.compiled import notify_compilation
    notify_compilation()  # one line on stderr while the kernels compile (first run after install)


main.add_command(bench)  # one subcommand per benchmark, each with its own options (bench/commands.py)


@main.command()
@click.option("--sweep", "with_sweep", is_flag=True,
              help="also the sweep's own kernels (its reductions: seconds more)")
def warm(with_sweep: bool) -> None:
    """Compile the physics kernels for this CPU now (or load them from the cache), so that the
    first record, replay or serve after an install starts at once: the README's install line
    runs it. It steps a two-ship shard of the built-in bounce scene with its flight log in a
    temporary folder (service.warm), which calls every kernel `record`, `replay` and `serve`
    call; with --sweep also two envelope cases through the sweep's loop (sweep.fleet.ready),
    whose kernels are compiled apart; says how long it took and where the kernels are kept
    (sim.compiled.cache_dir)."""
    from touchdown.service import warm as warming
    from touchdown.service.serve import default_scenario
    scn = default_scenario()
    seconds = warming.warm(scn.scene, scn.params.sim.dt_s, scn.params.body.name)
    what = "compiled code"
    if with_sweep:
        from touchdown.sweep.fleet import ready
        seconds += ready()
        what = "compiled code, the sweep's too,"
    click.echo(f"touchdown warm: {what} ready in {seconds:.1f} s; kernels in "
               f"{warming.where()}")


@main.command("scenarios")
def scenarios_cmd() -> None:
    """List the built-in scenarios: name and one-line description."""
    names = builtin.names()
    width = max(map(len, names))
    for name in names:
        click.echo(f"{name:<{width}}  {builtin.description(name)}")


@main.command(help="Run SCENARIO (a .toml file or a built-in name) and write its MCAP log. "
                   "Integrators (sim.integrator): " + ", ".join(sorted(Integrator.labels())) + ".")
@click.argument("scenario")
@click.option("-o", "--output", type=click.Path(dir_okay=False), help="log file (default NAME.mcap)")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE",
              help="override a scenario key, e.g. sim.dt=0.02 or ships[0].mass=9000; repeatable")
@click.option("--redis", "redis_url", default=None, metavar="URL",
              help="also publish events to this Redis (e.g. redis://127.0.0.1:6379/0)")
@click.option("--stream", default="galaxy:ships", show_default=True, help="Redis stream name")
@click.option("--keyframe-every", type=click.IntRange(min=1), default=1, show_default=True,
              help="write the full state every N ticks (replay seeks from keyframes)")
@click.option("--zstd-level", type=click.IntRange(min=-100, max=22), default=-3,
              show_default=True,
              help="zstd level of the log's chunks (1 writes 14%% fewer bytes than -3 for 1.6x "
                   "zstd's CPU on a large fleet, 3, the MCAP library's, fewer still for 2.1x "
                   "the CPU of 1; any level reads the same)")
@click.option("--view", "show", is_flag=True, help="open the Rerun viewer on the log when done")
def record(scenario: str, output: str | None, sets: tuple[str, ...], redis_url: str | None,
           stream: str, keyframe_every: int, zstd_level: int, show: bool) -> None:
    from touchdown.logs.header import scenario_message
    from touchdown.logs.writer import LogWriter
    from touchdown.service.driver import drive
    from touchdown.sim.world import World

    scn, source = load_scenario(scenario, sets)
    out = Path(output) if output else Path(f"{scn.name}.mcap")
    publisher = None
    if redis_url:
        from touchdown.logs.redis_stream import EventPublisher
        publisher = EventPublisher(redis_url, stream)
    n_ticks = scn.params.sim.n_ticks
    try:
        writer = LogWriter(out, scenario_message(scn, source, keyframe_every),
                           zstd_level=zstd_level)
    except OSError as exc:
        raise UserError(f"{out}: cannot write: {exc.strerror}") from None
    sinks = [lambda block, msgs: publisher.publish(msgs)] if publisher is not None else []
    try:
        outcome = drive(World.of(scn), n_ticks, writer, sinks, progress=scn.name,
                        on_close=publisher.close if publisher is not None else None)
    except (LogError, OSError) as exc:
        what = f"{out}: cannot write: {exc.strerror}" if isinstance(exc, OSError) else str(exc)
        raise WorkFailed(f"{what}; nothing was kept (no {out})") from None
    if outcome.how == "interrupted":
        click.echo(f"interrupted at tick {outcome.last_tick}; the log holds ticks "
                   f"0..{outcome.last_tick} and is finished: {out}", err=True)
        if show:
            _show([str(out)])
        sys.exit(130)
    if outcome.how == "abandoned":
        click.echo(f"interrupted twice: stopped at once; nothing was kept (no {out})", err=True)
        sys.exit(130)
    click.echo(f"{out}: {n_ticks + 1} ticks, {len(writer.ships)} ship(s), {outcome.events} "
               f"event(s)")
    if show:
        _show([str(out)])


def _range(text: str | None, flag: str, kind):
    """``A:B`` (either end may be left out) as (A or None, B or None)."""
    if text is None:
        return None, None
    if ":" not in text:
        raise UserError(f"{flag} {text!r}: expected A:B (either end may be left out)")
    a, b = text.split(":", 1)
    try:
        lo = kind(a) if a.strip() else None
        hi = kind(b) if b.strip() else None
    except ValueError:
        raise UserError(f"{flag} {text!r}: A and B must be "
                        f"{'whole numbers' if kind is int else 'numbers'}") from None
    for x in (lo, hi):
        if x is not None and not (0 <= x < 1e15):
            raise UserError(f"{flag} {text!r}: out of range")
    if lo is not None and hi is not None and hi < lo:
        raise UserError(f"{flag} {text!r}: B is before A")
    return lo, hi


class _TextSink:
    """A binary writer onto a text stream without a buffer (a caller's StringIO)."""

    closed = False

    def __init__(self, text):
        self.text = text

    def write(self, data) -> int:
        self.text.write(bytes(data).decode("utf-8"))
        return len(data)

    def writable(self) -> bool:
        return True

    def flush(self) -> None:
        self.text.flush()


def _binary_stdout():
    return getattr(sys.stdout, "buffer", None) or _TextSink(sys.stdout)


@main.command()
@click.argument("log", type=click.Path(dir_okay=False))
@click.option("--events", is_flag=True, help="one row per state transition instead of per tick")
@click.option("--format", "fmt", type=click.Choice(["jsonl", "csv", "parquet", "foxglove"]),
              default="jsonl", show_default=True,
              help="JSON Lines, CSV, Parquet (columnar, zstd; needs -o), or foxglove (an MCAP "
                   "file of Foxglove's schemas: poses, landers, events, values by ship id; "
                   "needs -o)")
@click.option("--ship", "ships", multiple=True, metavar="ID", help="only this ship (repeatable)")
@click.option("--ticks", default=None, metavar="A:B", help="only ticks A..B (inclusive)")
@click.option("--time", "time_range", default=None, metavar="A:B",
              help="only the ticks at simulated seconds A..B (inclusive)")
@click.option("--fields", default=None, metavar="F1,F2,...",
              help="only these fields (in the table's order)")
@click.option("-o", "--output", type=click.Path(dir_okay=False), help="write to FILE, not stdout")
def export(log: str, events: bool, fmt: str, ships: tuple[str, ...], ticks: str | None,
           time_range: str | None, fields: str | None, output: str | None) -> None:
    """One row per ship per tick of LOG (or per event with --events): JSON Lines, CSV or
    Parquet. Parquet keeps each field's unit in its metadata; a tick table in Parquet is written
    with its events beside it (OUT.events.parquet). With --format foxglove: an MCAP file for
    Foxglove (each ship's pose as a transform from the frame `site`, the landers drawn in their
    state's colour, the events as a log, every value by ship id; docs/foxglove-layout.json)."""
    from touchdown.logs import export as ex
    from touchdown.logs.reader import LogReader

    if fmt in ("parquet", "foxglove") and not output:
        raise UserError(f"--format {fmt} writes a file: give -o OUT."
                        f"{'parquet' if fmt == 'parquet' else 'mcap'}")
    if fmt == "foxglove" and (events or fields):
        raise UserError("--format foxglove writes every value and the events: no --events or "
                        "--fields")
    if ticks is not None and time_range is not None:
        raise UserError("--ticks and --time both given: choose one")
    first, last = _range(ticks, "--ticks", int)
    t_lo, t_hi = _range(time_range, "--time", float)
    try:
        columns = ex.parse_fields(fields, ex.EVENT_NAMES if events else ex.TICK_NAMES)
    except ValueError as exc:  # an unknown field
        raise UserError(str(exc)) from None
    tmp = Path(output + ".partial") if output else None
    beside = None
    if output and fmt == "parquet" and not events:
        beside = Path(output).with_suffix(".events.parquet")
    tmp_beside = Path(f"{beside}.partial") if beside else None
    try:
        with LogReader(log) as reader:
            if time_range is not None:
                dt = reader.scenario.dt_s
                first = None if t_lo is None else int(math.ceil(t_lo / dt - 1e-9))
                last = None if t_hi is None else int(math.floor(t_hi / dt + 1e-9))
            sel = ex.Selection(ships or None, first, last, columns)
            info = ex.table_info(reader, columns)
            last_tick = {"tick": None}
            # the events beside a Parquet table: read with the ticks, in the same pass
            read_events = [] if beside is not None else None

            def seen(blocks):
                for blk in blocks:
                    last_tick["tick"] = blk.last_tick
                    yield blk

            def write(out) -> None:
                if fmt in ("foxglove", "jsonl") and not events:  # compiled (Parquet, CSV: none)
                    _notify_compilation()
                if fmt == "foxglove":
                    from touchdown.view import foxglove_log
                    done = foxglove_log.write(reader, out, sel)
                    last_tick["tick"] = done.last_tick
                    return
                if events:
                    ex.write_events(ex.event_table(reader, sel.ships, first, last), info, fmt,
                                    out)
                    return
                # Parquet: a row group per block (large); the text formats: smaller blocks,
                # as each block's text is held whole while it is formatted
                blocks = seen(ex.tick_blocks(reader, sel, 64 << 20 if fmt == "parquet"
                                             else 16 << 20, events=read_events))
                if fmt == "parquet":
                    ex.write_parquet(blocks, info, out)
                elif fmt == "csv":
                    ex.write_csv(blocks, info, out)
                else:
                    ex.write_jsonl_blocks(blocks, info, out)

            if tmp is not None:
                if fmt in ("parquet", "foxglove"):
                    write(str(tmp))
                else:
                    with open(tmp, "wb") as f:
                        write(f)
                if beside is not None:
                    ex.write_events(ex.event_table(reader, sel.ships, first, last, read_events),
                                    ex.table_info(reader, ex.EVENT_NAMES), "parquet",
                                    str(tmp_beside))
                    tmp_beside.replace(beside)
                tmp.replace(output)
            else:
                write(_binary_stdout())
                sys.stdout.flush()
            note = ex.what_was_read(reader, last_tick["tick"], events)
            damage = reader.structure_note()
            if damage:
                note = (f"{note}\ntouchdown: " if note else "") + f"{log}: {damage}"
    except OSError as exc:
        if isinstance(exc, BrokenPipeError):
            sys.stderr.close()
            return
        raise WorkFailed(f"{output or 'stdout'}: cannot write: {exc.strerror or exc}; nothing "
                         f"was kept" + (f" (no {output})" if output else "")) from None
    finally:
        for p in (tmp, tmp_beside):
            if p is not None:
                p.unlink(missing_ok=True)  # after a failure; after success it was renamed
    if note:
        click.echo(f"touchdown: {note}", err=True)


@main.command()
@click.argument("log", type=click.Path(dir_okay=False))
@click.option("--verify", is_flag=True, help="re-run and compare every tick bit for bit")
@click.option("--from-tick", type=click.IntRange(min=0), default=None,
              help="start from the keyframe at this tick")
@click.option("--to-tick", type=click.IntRange(min=0), default=None, help="stop at this tick")
@click.option("--ship", "ship_id", default=None, help="re-run this ship alone")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE",
              help="what-if: change a setting (e.g. sim.integrator=semi_implicit_euler)")
@click.option("-o", "--output", type=click.Path(dir_okay=False), help="what-if: write the new log")
@click.option("--view", "show", is_flag=True,
              help="open the Rerun viewer: the log, or (what-if) the log beside the new run")
@click.option("--require-complete", is_flag=True,
              help="--verify: exit 1 unless the whole log was read (not cut or recovered) and "
                   "its summary says it is complete, as well as identical")
def replay(log: str, verify: bool, from_tick: int | None, to_tick: int | None,
           ship_id: str | None, sets: tuple[str, ...], output: str | None, show: bool,
           require_complete: bool) -> None:
    """Re-run LOG from its own recorded scenario and inputs.

    With --verify: compare with the recording bit for bit (exit 0 identical, 1 diverged; a log
    read only in part, cut or stopped, exits 0 and says which part: with --require-complete it
    exits 1). With --set: the same inputs under changed settings; prints how far it departs."""
    from touchdown.replay.verify import verify as run_verify
    from touchdown.replay.whatif import what_if

    if verify and sets:
        raise UserError("--verify re-runs the log as recorded; it does not take --set")
    if require_complete and not verify:
        raise UserError("--require-complete goes with --verify")
    if require_complete and (from_tick is not None or to_tick is not None or ship_id):
        raise UserError("--require-complete checks a whole log: not with --from-tick, "
                        "--to-tick or --ship")
    if from_tick is not None and to_tick is not None and to_tick < from_tick:
        raise UserError(f"--to-tick {to_tick} is before --from-tick {from_tick}")
    try:
        if sets or output:
            with tempfile.TemporaryDirectory(prefix="touchdown-whatif-") as tmp:
                new_log = output or (str(Path(tmp) / f"{Path(log).stem}-what-if.mcap")
                                     if show else None)
                res = what_if(log, parse_sets(sets), new_log, ship_id)
                click.echo(res.report())
                if show:
                    _show([log, new_log], ship_id)
            return
        res = run_verify(log, from_tick, to_tick, ship_id)
    except OSError as exc:  # the what-if log (-o) could not be written; its partial is gone
        raise WorkFailed(f"{output}: cannot write: {exc.strerror}; nothing was kept "
                         f"(no {output})") from None
    click.echo(res.report())
    if show:
        _show([log], ship_id)
    if verify and not res.identical:
        sys.exit(1)
    if require_complete and not res.verified_whole:
        click.echo(f"not complete: {res.incomplete_why} (--require-complete)")
        sys.exit(1)


@main.command()
@click.argument("log", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="the recovered log (written whole, or not at all)")
def recover(log: str, output: str) -> None:
    """Rewrite the readable part of LOG (a killed writer's .partial file, a cut or damaged log)
    as a complete, indexed MCAP file: every record up to the first damage, with a summary,
    chunk indexes and every CRC. A Touchdown log keeps its whole ticks and gains a summary
    (reason "recovered"), so that `touchdown replay OUT --verify` checks all of it. Exit 0
    written, 2 nothing readable."""
    from touchdown.logs.recover import recover as run_recover

    if not Path(log).is_file():
        raise UserError(f"{log}: cannot open: no such file")
    if Path(output).resolve() == Path(log).resolve():
        raise UserError(f"-o {output}: the same file as LOG; write the recovered log elsewhere")
    res = run_recover(log, output)
    what = (f"ticks {res.first_tick}..{res.last_tick}, {res.events:,} event(s)"
            if res.touchdown else f"{res.channels} channel(s)")
    click.echo(f"{output}: {res.messages:,} message(s) ({what}), {res.schemas} schema(s), "
               f"{res.metadata} metadata and {res.attachments} attachment(s); chunked, indexed, "
               f"with its summary and CRCs")
    if res.damage:
        click.echo(f"read up to byte {res.damage_at:,} of {log}: {res.damage}")
    if res.dropped:
        click.echo(f"the last tick read ({res.dropped} message(s)) was left out: its events may "
                   f"have been in the part that was lost")
    if res.summary_added:
        click.echo(f"a summary was added (complete = false, reason \"recovered\"): "
                   f"`touchdown replay {output} --verify` checks every tick kept")
    for note in res.notes:
        click.echo(f"note: {note}")


def _show(logs: list[str], ship_id: str | None = None, output: str | None = None,
          png: str | None = None, at_s: float | None = None) -> None:
    """Draw logs in Rerun: to an .rrd file, to a PNG (headless), or in the native viewer."""
    import time

    from touchdown.view import rerun_view as rv

    t0 = time.perf_counter()
    runs, notes = rv.load_runs(logs, ship_id)
    for note in notes:
        click.echo(f"touchdown: {note}", err=True)
    try:
        if output or png:
            with tempfile.TemporaryDirectory(prefix="touchdown-view-") as tmp:
                rrd = rv.write_rrd(runs, output or Path(tmp) / "view.rrd")
                took = time.perf_counter() - t0
                ticks = sum(len(t.tick) for r in runs for t in r.ships)
                if output:
                    click.echo(f"{rrd}: {len(runs)} run(s), "
                               f"{sum(len(r.ships) for r in runs)} ship(s), {ticks:,} ship-ticks "
                               f"in {took:.1f} s")
                if png:
                    rv.screenshot(rrd, Path(png), at_s)
                    click.echo(f"{png}: screenshot of the view")
        else:
            rv.spawn_viewer(runs)
    except OSError as exc:
        where = output or png or "the viewer"
        raise WorkFailed(f"{where}: {exc.strerror or exc}; nothing was kept") from None


@main.command()
@click.argument("logs", nargs=-1, type=click.Path(dir_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False),
              help="write an .rrd file instead of opening the viewer")
@click.option("--ship", "ship_id", default=None, help="show this ship alone")
@click.option("--screenshot", "png", type=click.Path(dir_okay=False), default=None,
              help="render the view to a PNG without a display (Rerun's headless viewer)")
@click.option("--at", "at_s", type=click.FloatRange(min=0.0), default=None, metavar="SECONDS",
              help="--screenshot: the moment shown (default: the end of the run)")
@click.option("--redis", "redis_url", default=None, metavar="URL",
              help="instead of logs: the running service's fleet, live, from its telemetry "
                   "stream (the URL may come from TOUCHDOWN_REDIS_URL with --redis env)")
@click.option("--prefix", default="galaxy", show_default=True,
              help="--redis: the service's key prefix")
@click.option("--seconds", type=click.FloatRange(min=0.1), default=None,
              help="--redis: follow the fleet this long (default: until Ctrl-C; 5 s with -o or "
                   "--screenshot)")
@click.option("--foxglove", "foxglove_port", type=click.IntRange(min=0, max=65535), default=None,
              metavar="PORT",
              help="--redis: serve the fleet to Foxglove over its WebSocket protocol on "
                   "ws://127.0.0.1:PORT instead of drawing it in Rerun (docs/foxglove-layout.json)")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="--foxglove: the address to listen on")
def view(logs: tuple[str, ...], output: str | None, ship_id: str | None, png: str | None,
         at_s: float | None, redis_url: str | None, prefix: str,
         seconds: float | None, foxglove_port: int | None, host: str) -> None:
    """Show LOG in Rerun: the 3D scene in the landing-site frame, plots over time, the status
    and the events. Two logs (A.mcap B.mcap) are shown together, on the same axes. With
    --redis URL: the running service's fleet, live (ships by state in the landing-site frame,
    counts per state over time, the event log); with --foxglove PORT as well, served to
    Foxglove (the channels of `export --format foxglove`) until Ctrl-C or --seconds."""
    if foxglove_port is not None and redis_url is None:
        raise UserError("--foxglove serves a live service: give --redis URL (a log goes to "
                        "Foxglove as `touchdown export LOG --format foxglove -o OUT.mcap`)")
    if redis_url is not None:
        if logs:
            raise UserError("view: give logs or --redis URL, not both")
        if foxglove_port is not None:
            if output or png:
                raise UserError("--foxglove serves the fleet: no -o or --screenshot")
            if redis_url == "env":
                redis_url = os.environ.get("TOUCHDOWN_REDIS_URL", "")
            from touchdown.view import foxglove_live

            def ready(port: int) -> None:
                click.echo(f"serving the fleet to Foxglove at ws://{host}:{port} (Foxglove: Open "
                           f"connection, Foxglove WebSocket; layout docs/foxglove-layout.json); "
                           f"Ctrl-C stops", err=True)
            done = foxglove_live.serve(redis_url, prefix, foxglove_port, seconds, host=host,
                                       ready=ready)
            click.echo(f"served {done.samples:,} telemetry samples and {done.events:,} events "
                       f"as {done.messages:,} Foxglove messages; {done.ships} ship(s)")
            return
        if output and not output.endswith(".rrd"):
            raise UserError(f"{output}: the output of view is an .rrd file")
        if redis_url == "env":
            redis_url = os.environ.get("TOUCHDOWN_REDIS_URL", "")
        _show_live(redis_url, prefix, seconds, output, png)
        return
    if not logs:
        raise UserError("view: give a log (or several), or --redis URL")
    if len(logs) > 4:
        raise UserError(f"view takes at most 4 logs, not {len(logs)}")
    if output and not output.endswith(".rrd"):
        raise UserError(f"{output}: the output of view is an .rrd file")
    _show(list(logs), ship_id, output, png, at_s)


def _show_live(url: str, prefix: str, seconds: float | None, output: str | None,
               png: str | None) -> None:
    from touchdown.view import live
    from touchdown.view import rerun_view as rv

    if output or png:
        with tempfile.TemporaryDirectory(prefix="touchdown-view-") as tmp:
            rrd = Path(output or Path(tmp) / "live.rrd")
            n = live.record(url, prefix, seconds or 5.0, rrd)
            if output:
                click.echo(f"{rrd}: {n:,} telemetry samples of the live fleet")
            if png:
                rv.screenshot(rrd, Path(png), None)
                click.echo(f"{png}: screenshot of the live view")
    else:
        live.live(url, prefix, seconds)


@main.command()
@click.argument("log", type=click.Path(dir_okay=False))
def doctor(log: str) -> None:
    """Check LOG's MCAP structure the way `mcap doctor` does (records, chunks, message indexes
    and their entries, summary, footer), and beside it what Touchdown checks of its content
    (scenario, every tick record decoded and checked, events, summary). Exit 0 sound, 1 damaged
    (what and where), 2 not a readable file."""
    from touchdown.logs import doctor as log_doctor

    if not Path(log).is_file():
        raise UserError(f"{log}: cannot open: no such file")
    try:
        lines, bad = log_doctor.report(log)
    except OSError as exc:
        raise UserError(f"{log}: cannot read: {exc.strerror}") from None
    click.echo("\n".join(lines))
    if bad:
        sys.exit(1)


@main.command()
@click.argument("logs", nargs=-1, required=True, type=click.Path())
@click.option("--ship", "ship_id", default=None, metavar="ID", help="the ship to cut (required)")
@click.option("--around", default=None, metavar="TICK", help="the incident's tick (required)")
@click.option("--before", default="5", show_default=True, metavar="SECONDS",
              help="how long before TICK the cut starts (from the keyframe at or before it)")
@click.option("--after", default="5", show_default=True, metavar="SECONDS",
              help="how long after TICK the cut ends")
@click.option("-o", "--output", default=None, metavar="OUT.mcap", help="the cut log (required)")
def incident(logs: tuple[str, ...], ship_id: str | None, around: str | None, before: str,
             after: str, output: str | None) -> None:
    """Cut a standalone log of one ship around an incident from LOG (several files, or a
    directory of rotated files, of one run): ticks TICK - before .. TICK + after, clipped to what
    the logs hold, from the keyframe at or before the start. The cut is re-run from the logs' own
    records and checked against them tick by tick as it is written (exit 1, nothing written, if
    they differ); `touchdown replay OUT --verify` passes on it."""
    from touchdown.replay.incident import Diverged, incident as cut

    if not ship_id:
        raise UserError("--ship: the ship to cut is required (--ship ID)")
    if around is None:
        raise UserError("--around: the incident's tick is required (--around TICK)")
    if not output:
        raise UserError("-o: the output file is required (-o OUT.mcap)")
    if not output.endswith(".mcap"):
        raise UserError(f"-o {output}: the cut is an .mcap file")
    try:
        tick = int(around)
    except ValueError:
        tick = -1
    if tick < 0:
        raise UserError(f"--around {around!r}: must be a tick, a whole number >= 0")
    seconds = {}
    for flag, raw in (("--before", before), ("--after", after)):
        try:
            seconds[flag] = float(raw)
        except ValueError:
            seconds[flag] = float("nan")
        if not (seconds[flag] >= 0.0 and seconds[flag] < 1e7):
            raise UserError(f"{flag} {raw!r}: must be seconds, a number >= 0")
    try:
        res = cut(list(logs), ship_id, tick, seconds["--before"], seconds["--after"], output)
    except Diverged as exc:
        raise WorkFailed(f"{str(exc)} (no {output})") from None
    except OSError as exc:
        raise WorkFailed(f"{output}: cannot write: {exc.strerror}; nothing was kept "
                         f"(no {output})") from None
    click.echo(res.report())


@main.command()
@click.option("--redis", "redis_url", default="redis://127.0.0.1:6379/0", show_default=True,
              metavar="URL", envvar="TOUCHDOWN_REDIS_URL",
              help="the Redis the service works through (or the environment variable "
                   "TOUCHDOWN_REDIS_URL, which keeps a password out of the process list); "
                   "redis://, rediss:// (TLS: ?ssl_ca_certs=CA&ssl_certfile=...), unix://")
@click.option("--redis-cluster", "cluster_url", default=None, metavar="URL",
              envvar="TOUCHDOWN_REDIS_CLUSTER_URL",
              help="run on a Redis Cluster instead, reached through this node (redis:// or "
                   "rediss://; or TOUCHDOWN_REDIS_CLUSTER_URL): one event stream per shard, "
                   "PREFIX:ships:{k}, and clients write the shards' command streams "
                   "(docs/SERVICE.md, Redis Cluster)")
@click.option("--redis-password-file", default=None, type=click.Path(dir_okay=False),
              help="read the Redis password from this file (its first line)")
@click.option("--scenario", "scenario", default=None, metavar="FILE",
              help="start with this scenario's ships (a .toml file or a built-in name)")
@click.option("--ticks", type=click.IntRange(min=1), default=None,
              help="stop after N ticks (default: when stopped by SIGTERM or Ctrl-C)")
@click.option("--rate", type=click.FloatRange(min=0.0), default=None,
              help="ticks per wall-clock second (default 1/dt: real time; 0: as fast as it can)")
@click.option("--log-dir", default="flight", show_default=True, type=click.Path(file_okay=False),
              help="where the flight logs go (rotating MCAP files, one folder per shard)")
@click.option("--prefix", default="galaxy", show_default=True,
              help="the service's Redis keys begin with this (PREFIX:ships, PREFIX:commands, ...)")
@click.option("--stream", "events_stream", default=None,
              help="the event stream (default PREFIX:ships)")
@click.option("--commands", "commands_stream", default=None,
              help="the command stream (default PREFIX:commands; shard k's is STREAM:{k})")
@click.option("--shards", type=click.IntRange(min=1, max=4096), default=4, show_default=True,
              help="how the ships are divided among workers (every worker must agree)")
@click.option("--lease", "lease_s", type=click.FloatRange(min=0.1), default=2.0,
              show_default=True, help="seconds before a dead worker's shards are taken over")
@click.option("--checkpoint-every", type=click.IntRange(min=1), default=50, show_default=True,
              help="ticks between a shard's checkpoints in Redis")
@click.option("--telemetry-hz", type=click.FloatRange(min=0.0), default=1.0, show_default=True,
              help="telemetry samples per simulated second (0: none)")
@click.option("--telemetry-maxlen", type=click.IntRange(min=1), default=None,
              help="the telemetry stream is trimmed to about this many entries, each one "
                   "shard's slice of a tick (default: 10 simulated seconds of them, 100 per "
                   "shard at dt 0.1 s: about 1 kB of Redis a ship)")
@click.option("--events-maxlen", type=click.IntRange(min=0), default=1_000_000,
              show_default=True, help="the event stream is trimmed to about this many entries "
                                      "(0: never)")
@click.option("--results-maxlen", type=click.IntRange(min=1), default=10_000, show_default=True,
              help="each shard's results stream PREFIX:shard:{k}:results (what each command "
                   "came to, a tick's entry) is trimmed to about this many entries")
@click.option("--log-max-mb", type=click.FloatRange(min=0.01), default=1024.0, show_default=True,
              help="a flight log file is closed and the next begun past this size (each "
                   "shard's first file at (k+1)/S of it: the shards' rotations staggered)")
@click.option("--log-keep-mb", type=click.FloatRange(min=0.0), default=2048.0, show_default=True,
              help="a shard's flight logs are kept under this total, oldest finished files "
                   "removed (0: all kept, for ever): 8 GiB for the default four shards; at "
                   "3,000 ships (3.4 MB/s) about 40 minutes of flight")
@click.option("--log-keep-hours", type=click.FloatRange(min=0.0), default=0.0,
              show_default=True, help="flight-log files older than this are removed (0: kept)")
@click.option("--log-min-free-mb", type=click.FloatRange(min=0.0), default=64.0,
              show_default=True, help="the flight log pauses below this much free disk")
@click.option("--log-keep-cache", is_flag=True,
              help="leave the flight logs' written pages in the page cache (by default each "
                   "8 MB written is synced and dropped from it: docs/SERVICE.md)")
@click.option("--max-ships", "max_ships", type=click.IntRange(min=0), default=20_000,
              show_default=True, help="ships a shard takes; a spawn past it is rejected (0: any)")
@click.option("--max-commands-per-ship", type=click.IntRange(min=0), default=4,
              show_default=True, help="commands for one ship in one tick; the rest rejected")
@click.option("--max-spawns-per-tick", type=click.IntRange(min=1), default=200,
              show_default=True, help="spawns a shard applies a tick; the rest wait a tick")
@click.option("--max-commands-per-tick", type=click.IntRange(min=1), default=2000,
              show_default=True, help="commands a shard applies a tick; the rest wait a tick")
@click.option("--max-shards", type=click.IntRange(min=1), default=None,
              help="own at most this many shards (default: a fair share of the live workers)")
@click.option("--worker-id", default="", help="this worker's name (default HOST-PID)")
@click.option("--metrics-port", type=click.IntRange(min=1, max=65535), default=None,
              help="serve the worker's figures at http://127.0.0.1:PORT/metrics (Prometheus)")
@click.option("--stats-every", type=click.FloatRange(min=0.1), default=5.0, show_default=True,
              help="seconds between stats lines (and the stats hash's refresh)")
@click.option("--warm-only", is_flag=True,
              help="compile (or load from the cache) the kernels a worker runs, say where the "
                   "cache is, and exit: an image's build step (docs/SERVICE.md); a worker "
                   "always does this before it takes a shard")
@click.option("--stats-json", default=None, hidden=True, type=click.Path(dir_okay=False),
              help="(bench serve) write each tick's working time and the counts here at exit")
def serve(redis_url: str, cluster_url: str | None, redis_password_file: str | None,
          scenario: str | None,
          ticks: int | None, rate: float | None, log_dir: str, prefix: str,
          events_stream: str | None, commands_stream: str | None, shards: int, lease_s: float,
          checkpoint_every: int, telemetry_hz: float, telemetry_maxlen: int | None,
          events_maxlen: int, log_max_mb: float,
          log_keep_mb: float, log_keep_hours: float, log_min_free_mb: float, log_keep_cache: bool,
          max_ships: int,
          max_commands_per_ship: int, max_spawns_per_tick: int, max_commands_per_tick: int,
          max_shards: int | None, worker_id: str, metrics_port: int | None, stats_every: float,
          stats_json: str | None, results_maxlen: int, warm_only: bool) -> None:
    """The live service: step the ships of a scenario and those spawned by commands, read
    commands from Redis, publish events, keep each ship's state in Redis, write flight logs
    (SPEC.md section 5; docs/SERVICE.md)."""
    from touchdown.service.serve import STEADY_LOOP, ServeConfig, Worker, install_stop
    from touchdown.service.shard import Limits

    if warm_only:
        from touchdown.service import warm
        from touchdown.service.serve import default_scenario
        scn = load_scenario(scenario)[0] if scenario else default_scenario()
        seconds = warm.warm(scn.scene, scn.params.sim.dt_s, scn.params.body.name)
        click.echo(f"touchdown serve --warm-only: compiled code ready in {seconds:.1f} s; "
                   f"kernels in {warm.where()}")
        return

    password = None
    if redis_password_file:
        try:
            password = Path(redis_password_file).read_text().splitlines()[0].strip()
        except (OSError, IndexError, UnicodeDecodeError) as exc:
            raise UserError(f"--redis-password-file {redis_password_file}: cannot read a "
                            f"password ({getattr(exc, 'strerror', None) or 'empty'})") from None
    scn, source = load_scenario(scenario) if scenario else (None, "")
    cfg = ServeConfig(url=cluster_url or redis_url, cluster=cluster_url is not None,
                      password=password, scenario=scn, source=source, ticks=ticks,
                      rate_hz=rate, log_dir=Path(log_dir), prefix=prefix,
                      events_stream=events_stream, commands_stream=commands_stream,
                      shards=shards, lease_s=lease_s, checkpoint_every=checkpoint_every,
                      telemetry_hz=telemetry_hz, telemetry_maxlen=telemetry_maxlen,
                      events_maxlen=events_maxlen, results_maxlen=results_maxlen,
                      log_max_bytes=int(log_max_mb * (1 << 20)),
                      log_max_total_bytes=int(log_keep_mb * (1 << 20)),
                      log_max_age_s=log_keep_hours * 3600.0,
                      log_min_free_bytes=int(log_min_free_mb * (1 << 20)), worker_id=worker_id,
                      log_drop_cache=not log_keep_cache,
                      max_shards=max_shards, max_spawns_per_tick=max_spawns_per_tick,
                      max_commands_per_tick=max_commands_per_tick,
                      limits=Limits(max_ships=max_ships,
                                    max_commands_per_ship=max_commands_per_ship),
                      metrics_port=metrics_port, stats_every_s=stats_every)
    worker = Worker(cfg)  # a ServeError (exit 2) on a bad URL or a refused start
    install_stop(worker)
    t0 = time.perf_counter()
    stats = worker.run()  # or on a shard's checkpoint written by another version
    if stats_json:
        Path(stats_json).write_text(json.dumps({
            "tick_s": list(stats.tick_s), "start_late_s": list(stats.start_late_s),
            "phases": stats.phases, "cpu_s": time.process_time(),
            "cpu_s_at_tick": list(stats.cpu_s),
            "loop_cpu_s_at_tick": list(stats.loop_cpu_s),
            "phases_at_steady": [STEADY_LOOP, stats.phases_at_steady],
            "loop_cpu_s": time.thread_time(),
            "late": stats.late,
            "entries_sent": stats.entries_sent, "figures": worker.last_figures,
            "recent": [[round(t, 4), d] for t, d in stats.recent],
            "entries_dropped": stats.entries_dropped, "wall_s": time.perf_counter() - t0,
            "slowest": worker.slow.slowest(), "late_starts": list(stats.late_starts)}))
    times = sorted(stats.tick_s) or [0.0]
    pct = lambda q: times[min(len(times) - 1, int(q * len(times)))] * 1e3  # noqa: E731
    click.echo(f"touchdown serve: {stats.ticks} ticks; tick time p50 {pct(0.5):.2f} ms, "
               f"p99 {pct(0.99):.2f} ms, max {times[-1] * 1e3:.2f} ms; {stats.entries_sent:,} "
               f"entries delivered, {stats.entries_dropped:,} dropped; {stats.commands_read:,} "
               f"commands read; {stats.late} tick(s) late; logs in {log_dir}", err=True)


@main.command()
@click.argument("scenario")
@click.option("--vary", "vary", multiple=True, metavar="KEY=LO:HI:N",
              help="an axis: N values from LO to HI of a numeric key of the first ship "
                   "(ships.initial.horizontal_speed), the contact model, the body or the slope "
                   "(body.terrain.slope_deg); with --samples, KEY=LO:HI; repeatable")
@click.option("--samples", type=click.IntRange(min=1), default=None,
              help="N random cases (a Latin hypercube over the ranges) instead of the grid")
@click.option("--seed", type=int, default=0, show_default=True, help="the samples' seed")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default=None,
              help="the table (Parquet; default NAME-sweep.parquet), or with --record the log")
@click.option("--chart", type=click.Path(dir_okay=False), default=None, metavar="PNG",
              help="also draw the envelope (needs matplotlib: the chart extra)")
@click.option("--workers", type=click.IntRange(min=1), default=2, show_default=True,
              help="processes on this machine")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="run the cases on this Dask scheduler (tcp://host:8786; the sweep extra)")
@click.option("--record", "record_case", type=click.IntRange(min=0), default=None, metavar="CASE",
              help="write case CASE's full log to -o instead of sweeping")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE",
              help="override a scenario key for every case; repeatable")
def sweep(scenario: str, vary: tuple[str, ...], samples: int | None, seed: int,
          output: str | None, chart: str | None, workers: int, scheduler: str | None,
          record_case: int | None, sets: tuple[str, ...]) -> None:
    """The touchdown envelope: one case per point of the grid of the varied keys (or N random
    samples of their ranges), each case the scenario's first ship with those values, stepped
    together as one fleet; a table of outcomes (SPEC.md section 6), the count per outcome, and
    optionally a chart. Ctrl-C keeps the cases done (the others are marked missing, exit 130)."""
    from touchdown.sweep.command import main as sweep_main
    text, source = scenario_text(scenario)
    doc = load_toml(text, source)
    if sets:
        from touchdown.sim.scenario import apply_overrides
        doc = apply_overrides(doc, parse_sets(sets), source)
    code = sweep_main(doc, source, vary, samples, seed, output, chart, workers, scheduler,
                      record_case)
    if code:
        sys.exit(code)


if __name__ == "__main__":
    main()
