"""``touchdown bench``: one click subcommand per benchmark, each with its own options only.

Each subcommand imports its benchmark when it runs (``touchdown --help`` stays quick). The group is
added to the command line by cli.py; nothing here imports cli.py (``bench fuzz`` hands the root
command it was called from to the campaign, which drives it in-process)."""
from __future__ import annotations

import sys

import click

QUICK = click.option("--quick", is_flag=True,
                     help="smaller runs (a smoke test of the benchmark itself)")


@click.group()
def bench() -> None:
    """Benchmarks, printed with units and the machine (`touchdown bench NAME --help`)."""


@bench.command()
@QUICK
@click.option("--against", multiple=True, metavar="PYTHON",
              help="another install's interpreter (e.g. 0.7.0's checkout's .venv/bin/python): "
                   "the per-state table beside it, alternating runs, with ratios (repeatable)")
def speed(quick: bool, against: tuple[str, ...]) -> None:
    """Recording and stepping rates, and the cost per ship-tick by state and model (with the
    `bench` extra, MuJoCo on the same landers)."""
    from touchdown.bench import speed as bench_speed
    bench_speed.main(quick=quick, against=list(against))


@bench.command()
@QUICK
def replay(quick: bool) -> None:
    """Verify against record speed, seeking in a long log, what keyframes cost."""
    from touchdown.bench import replay_speed
    replay_speed.main(quick=quick)


@bench.command()
@QUICK
@click.option("--out", "out_dir", default="docs", show_default=True,
              type=click.Path(file_okay=False), help="where the chart and tables go")
def accuracy(quick: bool, out_dir: str) -> None:
    """The work-precision chart and tables: each method's error against the references over the
    tick, against its cost (needs the `bench` extra)."""
    from touchdown.bench import accuracy as bench_accuracy
    bench_accuracy.main(quick=quick, out_dir=out_dir)


@bench.command()
@QUICK
def stability(quick: bool) -> None:
    """Each method's largest stable step, measured against theory."""
    from touchdown.bench import stability as bench_stability
    bench_stability.main(quick=quick)


@bench.command()
@QUICK
def physics(quick: bool) -> None:
    """Scenes off the well-walked paths (turning bodies, tumbles, falls onto the side, spins,
    hills, slopes, impossible starts), each figure beside what physics says; and issue 35's
    scenes at the edges beside the 3-D per-foot reference (bench.edges3d)."""
    from touchdown.bench import physics as bench_physics
    bench_physics.main(quick=quick)


@bench.command()
@click.option("--seed", type=int, default=101, show_default=True,
              help="the sample's seed (the suite checks seed 35's)")
@click.option("--starts", type=click.IntRange(min=1), default=200, show_default=True,
              help="how many starts the sample draws")
@click.option("--only", multiple=True, type=click.IntRange(min=0), metavar="K",
              help="run only start K of the sample (repeatable)")
@click.option("--rel", type=click.FloatRange(min=0.0), default=0.01, show_default=True,
              help="how close a start must end to the reference, as a fraction of its way and "
                   "of its largest tilt")
@click.option("--floor-m", type=click.FloatRange(min=0.0), default=0.01, show_default=True,
              help="a start also follows where it ends within this distance of the reference's "
                   "end, whatever its way")
@click.option("--floor-deg", type=click.FloatRange(min=0.0), default=0.1, show_default=True,
              help="... and where its largest tilt is within this of the reference's")
@click.option("--set", "settings", multiple=True, metavar="KEY=VALUE",
              help="a sim.* or contact.* scenario key for the runs, e.g. sim.stiff_substep=0.0002 "
                   "(repeatable; the default settings otherwise)")
@click.option("--workers", type=click.IntRange(min=1), default=2, show_default=True,
              help="processes the starts are shared among")
@click.option("--no-diagnosis", is_flag=True, help="do not re-run the starts that miss")
@click.pass_context
def starts3d(ctx: click.Context, seed: int, starts: int, only: tuple[int, ...], rel: float,
             floor_m: float, floor_deg: float, settings: tuple[str, ...], workers: int,
             no_diagnosis: bool) -> None:
    """3-D touchdowns beside the 3-D per-foot reference over a seeded sample of starts (the
    suite's check on another sample), each start that misses re-run four ways that point at a
    cause (bench.starts3d). Exit 1 where a start misses."""
    from touchdown.bench import starts3d as bench_starts3d
    from touchdown.scenarios import parse_sets
    table = parse_sets(settings)
    missed = bench_starts3d.main(seed, starts, only,
                                 bench_starts3d.Bound(rel, floor_deg, floor_m), table, workers,
                                 not no_diagnosis)
    ctx.exit(1 if missed else 0)


@bench.command()
@click.option("--quick", is_flag=True, help="200 files (a smoke test of the campaign itself)")
@click.option("--files", type=click.IntRange(min=1), default=2000, show_default=True,
              help="how many hostile files to generate and run")
@click.option("--seconds", type=click.FloatRange(min=0.1), default=20.0, show_default=True,
              help="the time bound per file")
@click.option("--memory-gib", type=click.FloatRange(min=0.5), default=1.5, show_default=True,
              help="the address-space cap of the whole campaign")
@click.option("--seed", type=int, default=20261123, show_default=True, help="the corpus seed")
@click.option("--json", "as_json", is_flag=True,
              help="print the counts as one JSON line (what the suite's fuzz test reads)")
@click.pass_context
def fuzz(ctx: click.Context, quick: bool, files: int, seconds: float, memory_gib: float,
         seed: int, as_json: bool) -> None:
    """A campaign of generated hostile logs and scenarios against verify, export and record, in
    this process, counted per class and outcome (exit 1 if any hang, traceback, memory blow-up or
    silent result)."""
    from touchdown.bench import fuzz as bench_fuzz
    tally = bench_fuzz.main(ctx.find_root().command, files=200 if quick else files,
                            seconds=seconds, memory_gib=memory_gib, as_json=as_json, seed=seed)
    if tally.bad():
        sys.stdout.flush()
        sys.exit(1)


@bench.command()
@QUICK
@click.option("--redis", "redis_url", default="redis://127.0.0.1:6379/0", show_default=True,
              metavar="URL", help="the Redis the benchmark's workers use")
@click.option("--cluster", is_flag=True,
              help="on a private Redis Cluster of three masters started for the bench "
                   "(needs redis-server and redis-cli on PATH)")
@click.option("--private-redis", is_flag=True,
              help="on a redis-server of the bench's own (no persistence), pinned to a CPU no "
                   "worker has when there is one")
@click.option("--redis-cpus", default=None, metavar="LIST",
              help="pin the private Redis (or the cluster's masters) to these CPUs "
                   "(e.g. 1 or 0,1; 'none': not pinned; default: a CPU free of workers)")
@click.option("--workers", "workers", default="1,2", show_default=True,
              help="the worker counts to find the largest fleet for")
@click.option("--seconds", type=click.FloatRange(min=3.0), default=None,
              help="each search trial (default 20, --quick 6)")
@click.option("--confirm-seconds", type=click.FloatRange(min=0.0), default=300.0,
              show_default=True, help="the confirming run at the size found (0: none)")
@click.option("--start", type=click.IntRange(min=1), default=None,
              help="the first fleet tried (default 12,500)")
@click.option("--max-late", type=click.IntRange(min=0), default=0, show_default=True,
              help="late ticks a kept fleet may have (a tick begun a whole period late)")
@click.option("--retries", type=click.IntRange(min=0), default=1, show_default=True,
              help="times a search trial not kept is run again before its size counts as too "
                   "many (the confirmation still decides)")
@click.option("--burst", "burst_spawns", type=click.IntRange(min=0), default=None,
              help="spawns sent at once to two idle workers at the end (default 50,000; "
                   "0: no burst)")
@click.option("--worker-python", default=None, metavar="PYTHON",
              help="run the workers with this Python (another checkout's venv)")
@click.option("--worker-cwd", default=None, metavar="DIR",
              help="run DIR/cli.py serve (another checkout: the version before, measured in "
                   "the same session)")
@click.option("--label", default="", help="a name for the workers measured, printed")
def serve(quick: bool, redis_url: str, cluster: bool, private_redis: bool,
          redis_cpus: str | None, workers: str, seconds: float | None, confirm_seconds: float,
          start: int | None, max_late: int, retries: int, burst_spawns: int | None,
          worker_python: str | None, worker_cwd: str | None, label: str) -> None:
    """The most ships one `touchdown serve` worker (and two) keeps at a 10 Hz tick in real time
    (tick p99 under 100 ms, no late tick; bisected, then confirmed by a 5-minute run), with
    tick-time percentiles, CPU per ship-tick, events per second and Redis memory and traffic
    per 10,000 ships (needs a Redis; `--cluster`: a private three-master Redis Cluster)."""
    from touchdown.bench import serve as bench_serve
    counts = tuple(int(x) for x in workers.split(",") if x.strip())
    bench_serve.main(quick=quick, url=redis_url, cluster=cluster, seconds=seconds,
                     confirm_s=confirm_seconds, start=start, workers=counts,
                     burst_spawns=burst_spawns, private_redis=private_redis,
                     redis_cpus=redis_cpus, worker_python=worker_python,
                     worker_cwd=worker_cwd, max_late=max_late, label=label, retries=retries)


@bench.command()
@QUICK
def envelope(quick: bool) -> None:
    """The stand / tip boundary over sideways speed and slope from Touchdown, the planar
    reference and MuJoCo (the `bench` extra)."""
    from touchdown.bench import envelope as bench_envelope
    bench_envelope.main(quick=quick)


@bench.command()
@QUICK
@click.option("--cases", type=click.IntRange(min=2), default=None,
              help="envelope cases a setting (default 2,000; 60 with --quick)")
@click.option("--rounds", type=click.IntRange(min=1), default=2, show_default=True,
              help="runs of each setting, the least CPU taken (the reference runs once)")
@click.option("--out", "out_dir", default="docs", show_default=True,
              type=click.Path(file_okay=False), help="where the table and the chart go")
def sweep(quick: bool, cases: int | None, rounds: int, out_dir: str) -> None:
    """The sweep's cost against its accuracy: the issue's envelope at the default settings and
    at coarser and finer ones, CPU a case and outcomes unlike the finest's."""
    from touchdown.bench import sweep_precision
    sweep_precision.main(quick=quick, cases=cases, rounds=rounds, out_dir=out_dir)


@bench.command()
@QUICK
def logs(quick: bool) -> None:
    """Export (Parquet, CSV, JSON Lines), view, verify and doctor of a 1,000-ship log as whole
    commands on one core, as ratios against the old per-row JSON Lines export."""
    from touchdown.bench import logs as bench_logs
    bench_logs.main(quick=quick)


@bench.command()
@click.option("--fault", "faults", multiple=True, metavar="FAULT",
              help="a fault to inject (repeatable): worker-kill, pause-S (Redis SIGSTOPped S "
                   "seconds), takeover-kill (a worker killed, then the one taking its shards "
                   "over), aof-restart, empty-restart, rollback-S (restarted from a snapshot "
                   "S seconds old), stale-rollback (a worker frozen through a rollback, "
                   "its shards taken, then killed), failover, reshard; default: worker-kill, "
                   "takeover-kill, pause-5, pause-30, aof-restart, empty-restart, rollback-2, "
                   "stale-rollback, failover, reshard, each once")
@click.option("--minutes", type=click.FloatRange(min=0.0), default=None,
              help="sessions of three faults drawn from the seed until this much time has "
                   "passed (default: each fault once)")
@click.option("--seed", type=int, default=None,
              help="the seed the faults and the traffic are drawn from (default: from the "
                   "clock; always printed)")
@click.option("--seconds", type=click.FloatRange(min=2.0), default=16.0, show_default=True,
              help="traffic around each fault (half before it, half after)")
@click.option("--rate", type=click.FloatRange(min=1.0), default=150.0, show_default=True,
              help="command entries a second the gateways write")
@click.option("--keep", "keep_dir", default=None, type=click.Path(file_okay=False),
              help="keep each session's servers' data, flight logs and workers' lines here")
@click.option("--worker-python", default=None, metavar="PYTHON",
              help="run the workers with this Python (another checkout's venv)")
@click.option("--worker-cwd", default=None, metavar="DIR",
              help="run DIR/cli.py serve (another checkout: the version before, measured in "
                   "the same session)")
def chaos(faults: tuple[str, ...], minutes: float | None, seed: int | None, seconds: float,
          rate: float, keep_dir: str | None, worker_python: str | None,
          worker_cwd: str | None) -> None:
    """Every command accounted for under faults: gateways write uniquely-valued commands
    while workers are killed and private redis-servers are paused, killed, emptied, rolled
    back, failed over and resharded; each entry Redis accepted must be found applied once in
    the flight logs or rejected once to its sender (exit 1 otherwise). Needs redis-server and
    redis-cli."""
    import time as _time

    from touchdown.bench import chaos as bench_chaos
    seed = seed if seed is not None else int(_time.time()) % 1_000_000
    chosen = list(faults) or list(bench_chaos.FAULTS)
    for f in chosen:
        if not bench_chaos.known(f):
            raise click.BadParameter(f"{f}: not a fault (see --help)", param_hint="--fault")
    if worker_cwd:
        bench_chaos.ROOT = __import__("pathlib").Path(worker_cwd).resolve()
    sys.exit(bench_chaos.main(chosen, seconds, rate, seed, minutes, keep_dir,
                              python=worker_python or sys.executable))
