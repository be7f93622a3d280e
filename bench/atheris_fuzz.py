"""Coverage-guided fuzzing of the log reader and the scenario parser (atheris, libFuzzer's engine).

    pip install -e '.[fuzz]'
    python -m touchdown.bench.atheris_fuzz reader   -max_total_time=600 -timeout=20 -rss_limit_mb=1536
    python -m touchdown.bench.atheris_fuzz scenario -max_total_time=600 -timeout=20 -rss_limit_mb=1536

Not part of the suite: it runs until its time is up or it finds a failure, which libFuzzer writes
to ``crash-*`` / ``timeout-*`` / ``oom-*`` files for ``python -m touchdown.bench.atheris_fuzz TARGET FILE``
to re-run. Where ``bench/fuzz.py`` generates a fixed corpus from what we know can go wrong, this
mutates inputs toward code it has not reached yet. The seed corpus (written to
``.fuzz-corpus/TARGET`` on first use) is the fixed corpus's seed logs and bombs, and the built-in
scenarios.

A failure is anything but the documented refusal (``LogError`` for a log, ``ScenarioError`` for a
scenario): an escaped exception, a non-finite number in what an accepted input produced, more
than ``-timeout`` seconds on one input, more than ``-rss_limit_mb`` of memory.
"""
from __future__ import annotations

import io
import math
import sys
import tempfile
from pathlib import Path

import atheris

# only our own code is instrumented (numpy, mcap, zstd and protobuf are someone else's to fuzz,
# and instrumenting them makes every run several times slower)
with atheris.instrument_imports(include=["logs", "sim", "replay", "proto", "scenarios"]):
    from touchdown.logs import LogError
    from touchdown.logs.export import tick_rows, write_jsonl
    from touchdown.logs.reader import LogReader
    from touchdown.logs.rebuild import scenario_of
    from touchdown.sim.scenario import ScenarioError, parse_text

CORPUS = Path(".fuzz-corpus")
_LOG = Path(tempfile.mkdtemp(prefix="touchdown-atheris-")) / "input.mcap"
MAX_TICKS = 3  # an accepted scenario is stepped this far: enough to reach contact and the writer


def reader_one(data: bytes) -> None:
    """Open, check, decode and export a log; replay its first ticks."""
    _LOG.write_bytes(data)
    try:
        with LogReader(_LOG) as reader:
            scenario_of(reader)
            for td in reader.ticks(0, MAX_TICKS):
                td.arrays  # decoded and checked
            for _ in reader.events():
                pass
            reader.read_summary()
            write_jsonl(tick_rows(reader), io.StringIO(), str(_LOG))
    except LogError:
        return


def scenario_one(data: bytes) -> None:
    """Parse a scenario; run an accepted one for a few ticks and require finite numbers."""
    from touchdown.sim.run import run

    text = data.decode("utf-8", errors="replace")
    try:
        scn = parse_text(text, "fuzz")
    except ScenarioError:
        return
    for rec in run(scn, last_tick=min(MAX_TICKS, scn.params.sim.n_ticks)):
        for name, a in rec.state.arrays().items():
            if a.dtype.kind == "f" and not all(map(math.isfinite, a.ravel().tolist())):
                raise AssertionError(f"an accepted scenario gave non-finite {name} at tick "
                                     f"{rec.tick}")


def seed_corpus(target: str) -> Path:
    """The seed inputs, written once."""
    out = CORPUS / target
    if out.is_dir() and any(out.iterdir()):
        return out
    out.mkdir(parents=True, exist_ok=True)
    if target == "reader":
        from touchdown.bench import fuzz
        with tempfile.TemporaryDirectory() as d:
            seeds = fuzz.seed_logs_recorded(Path(d))  # the library's record, not cli.py
        for name, data in seeds.items():
            (out / f"{name}.mcap").write_bytes(data)
        for name, data in fuzz.bombs(seeds["bounce"]):
            # the bombs that are refused from their headers (the others cost a second a run)
            if name.startswith(("zstd-claims-1000", "zstd-claims-2^62", "none-", "lz4-")):
                (out / f"bomb-{name}.mcap").write_bytes(data)
    else:
        from touchdown import scenarios
        for name in scenarios.names():
            (out / f"{name}.toml").write_text(scenarios.text(name))
    return out


def main(argv: list[str]) -> None:
    if len(argv) < 2 or argv[1] not in ("reader", "scenario"):
        sys.exit("usage: python -m touchdown.bench.atheris_fuzz reader|scenario "
                 "[FILE | libFuzzer options]")
    target = argv[1]
    one = reader_one if target == "reader" else scenario_one
    rest = argv[2:]
    if rest and Path(rest[0]).is_file():  # re-run one saved input
        one(Path(rest[0]).read_bytes())
        print("no failure")
        return
    corpus = seed_corpus(target)
    atheris.Setup([argv[0], *rest, str(corpus)], one)
    atheris.Fuzz()


if __name__ == "__main__":
    main(sys.argv)
