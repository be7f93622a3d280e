"""Logs at fleet scale: ``touchdown bench logs [--quick]``.

Records a fleet log (1,000 ships, 2,001 ticks: 2 million ship-ticks; ``--quick``: 200 ships, 401
ticks), then runs each command on it (the exports, Foxglove's among them, view, verify, doctor)
as a whole command (a fresh process, pinned to one core;
wall time and peak memory, startup included) and prints the figures as ratios against the old
path measured in the same run: the per-row JSON Lines export that ``export`` was before issue 25
(a dict per row, ``json.dumps`` per row, the tick records decoded in Python). Then where the time
of a Parquet export goes (in this process: opening, decoding, converting, writing), and the
bounded reader's refusal of a tick record larger than the fleet can fill.

``python -m touchdown.bench.logs --against REV [--rounds N] [--quick]``: the Parquet export of
this tree beside that of git revision REV (another commit, or main) on the same log, alternating,
each a fresh process pinned to one core: CPU seconds (median of N), rows per CPU second, and
their ratio.
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: the export before issue 25, as it was: rows as dicts, JSON per row, Python decoding
OLD_EXPORT = """
import sys
import touchdown.logs.reader as m
from touchdown.logs.codec import decode_tick_python
from touchdown.logs.export import tick_rows, write_jsonl
m.decode_tick = decode_tick_python  # the decoder export used then
with m.LogReader(sys.argv[1]) as r, open(sys.argv[2], "w") as f:
    write_jsonl(tick_rows(r), f, sys.argv[1])
"""


def _one_core() -> None:
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})


def run(args: list[str], env: dict | None = None) -> tuple[float, float, float]:
    """(wall seconds, CPU seconds, peak resident MB) of a command in a fresh process on one
    core. The CPU seconds (user + system) are the figure on a shared machine: the wall time
    also counts the time others held the core."""
    with tempfile.TemporaryFile() as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen([sys.executable, *args], cwd=ROOT, stdout=subprocess.DEVNULL,
                                stderr=err, preexec_fn=_one_core, env=env)
        _pid, status, usage = os.wait4(proc.pid, 0)
        took = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            err.seek(0)
            raise RuntimeError(f"{' '.join(args[:3])}: exit {proc.returncode}: "
                               f"{err.read().decode(errors='replace')[-500:]}")
    return took, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0


def record_fleet(path: str, ships: int, ticks: int) -> float:
    from touchdown.bench.speed import fleet_doc
    from touchdown.service import driver
    from touchdown.sim.scenario import parse
    scn = parse(fleet_doc(ships, ticks * 0.05), "bench")
    t0 = time.perf_counter()
    driver.record(scn, path, "bench")
    return time.perf_counter() - t0


def breakdown(log: str, out: str) -> dict[str, float]:
    """Where a Parquet export's time goes, in this process (its modules imported already)."""
    from touchdown.logs import export as ex
    from touchdown.logs.reader import LogReader
    from touchdown.logs.rebuild import log_params
    t = {}
    clock = time.process_time
    block = 64 << 20  # as the command reads them (a row group each)
    t0 = clock()
    with LogReader(log) as r:
        r.ship_table()
        ex.table_info(r)
        t["open the log, its ships"] = clock() - t0
        t0 = clock()
        log_params(r)
        t["its scenario checked, its parameters"] = clock() - t0
        t0 = clock()
        for _ in r.blocks(wanted=ex.SOURCE_FIELDS, block_bytes=block, reuse=True):
            pass
        t["read and decode"] = clock() - t0
        t0 = clock()
        for _ in ex.tick_blocks(r, ex.Selection(), block):
            pass
        t["... and derive the columns"] = clock() - t0
        t0 = clock()
        ex.write_parquet(ex.tick_blocks(r, ex.Selection(), block), ex.table_info(r), out)
        t["... and write Parquet"] = clock() - t0
    return t


def against(ref: str, rounds: int = 5, quick: bool = False) -> None:
    """The Parquet export of this tree and of git revision ``ref`` (git archive into a
    temporary directory, imported as the package ``touchdown`` there through PYTHONPATH) on one
    log, alternating, each a fresh process on one core: the median CPU seconds of ``rounds``
    each (after one of each not counted: ``ref``'s kernels compile there), rows per CPU second,
    the ratio. Startup and imports included, as a user runs the command."""
    import statistics
    from touchdown.bench.speed import machine
    ships, ticks = (200, 400) if quick else (1000, 2000)
    rows = ships * (ticks + 1)
    with tempfile.TemporaryDirectory(prefix="touchdown-bench-against-") as tmp:
        tree = Path(tmp) / "ref"
        tree.mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", ref], check=True,
                                 capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(tree)], input=archive, check=True)
        (Path(tmp) / "pkg").mkdir()
        (Path(tmp) / "pkg" / "touchdown").symlink_to(tree)
        log = os.path.join(tmp, "fleet.mcap")
        record_fleet(log, ships, ticks)
        env_ref = {**os.environ, "PYTHONPATH": str(Path(tmp) / "pkg")}
        sides = {ref: (str(tree / "cli.py"), env_ref), "this tree": (str(ROOT / "cli.py"), None)}
        cpu: dict[str, list[float]] = {name: [] for name in sides}
        sizes = {}
        print(f"machine: {machine()}; {rows:,} rows ({ships:,} ships x {ticks + 1:,} ticks), "
              f"`export LOG --format parquet -o OUT`, fresh processes on one core, alternating")
        for k in range(rounds + 1):
            order = list(sides.items()) if k % 2 == 0 else list(sides.items())[::-1]
            for name, (cli, env) in order:
                out = os.path.join(tmp, "out.parquet")
                for path in (out, os.path.join(tmp, "out.events.parquet")):
                    if os.path.exists(path):
                        os.unlink(path)
                _wall, c, _mem = run([cli, "export", log, "--format", "parquet", "-o", out], env)
                sizes[name] = os.path.getsize(out)
                if k:
                    cpu[name].append(c)
        for name, xs in cpu.items():
            med = statistics.median(xs)
            print(f"  {name:12} {med:6.3f} CPU s (median of {len(xs)}: "
                  f"{', '.join(f'{x:.2f}' for x in sorted(xs))}) {rows / med:11,.0f} rows/CPU s"
                  f"  {sizes[name] / 1e6:5.1f} MB")
        a, b = (statistics.median(cpu[n]) for n in (ref, "this tree"))
        print(f"  this tree: {a / b:.2f}x the rows per CPU second of {ref}")


def bounded_refusal(tmp: str) -> float:
    """Seconds to refuse a log declaring one 100 MiB tick record (a few kB on disk)."""
    from touchdown.bench import fuzz
    from touchdown.logs import LogError
    from touchdown.replay.verify import verify
    src = os.path.join(tmp, "small.mcap")
    record_fleet(src, 2, 20)

    n = 100 << 20
    varint = bytes([(n >> (7 * k)) & 0x7F | (0x80 if n >> (7 * (k + 1)) else 0)
                    for k in range(4)])

    def edit(topic, data):
        if topic == "/touchdown/ticks" and data[:2] == b"\x08\x01":
            data = b"\x08\x01\x2a" + varint + bytes(n)  # one packed field of 100 MiB
        return [(topic, data)]
    bad = os.path.join(tmp, "bomb.mcap")
    Path(bad).write_bytes(fuzz.rewrite_log(Path(src).read_bytes(), edit))
    t0 = time.perf_counter()
    try:
        verify(bad)
    except LogError:
        pass
    return time.perf_counter() - t0, os.path.getsize(bad)


def main(quick: bool = False) -> None:
    from touchdown.bench.speed import machine
    ships, ticks = (200, 400) if quick else (1000, 2000)
    rows = ships * (ticks + 1)
    print(f"machine: {machine()}; each command a fresh process on one core (startup included)")
    with tempfile.TemporaryDirectory(prefix="touchdown-bench-logs-") as tmp:
        log = os.path.join(tmp, "fleet.mcap")
        took = record_fleet(log, ships, ticks)
        print(f"log: {ships:,} ships x {ticks + 1:,} ticks = {rows:,} rows, "
              f"{os.path.getsize(log) / 1e6:.0f} MB, recorded in {took:.1f} s")
        cli = str(ROOT / "cli.py")
        old_out = os.path.join(tmp, "old.jsonl")
        w_old, c_old, m_old = run(["-c", OLD_EXPORT, log, old_out])
        size_old = os.path.getsize(old_out)
        os.unlink(old_out)
        print(f"{'':36} {'wall s':>7} {'CPU s':>7} {'rows/CPU s':>11} {'out MB':>7} "
              f"{'peak MB':>8}  against the old export (CPU)")
        print(f"{'old export (JSON Lines, per row)':36} {w_old:7.2f} {c_old:7.2f} "
              f"{rows / c_old:11,.0f} {size_old / 1e6:7.0f} {m_old:8.0f}  1")
        for fmt in ("parquet", "csv", "jsonl"):
            out = os.path.join(tmp, f"out.{fmt}")
            w, c, m = run([cli, "export", log, "--format", fmt, "-o", out])
            size = os.path.getsize(out)
            os.unlink(out)
            print(f"{'export --format ' + fmt:36} {w:7.2f} {c:7.2f} {rows / c:11,.0f} "
                  f"{size / 1e6:7.0f} {m:8.0f}  {c_old / c:.1f}x faster, {size_old / size:.1f}x "
                  f"smaller")
        w, c, m = run([cli, "view", log, "-o", os.path.join(tmp, "view.rrd")])
        print(f"{'view -o OUT.rrd (16 ships + fleet)':36} {w:7.2f} {c:7.2f} {'':>11} "
              f"{os.path.getsize(os.path.join(tmp, 'view.rrd')) / 1e6:7.0f} {m:8.0f}  "
              f"(aim: under 5 s and 400 MB for 1,000 ships)")
        for name, args in (("replay --verify", ["replay", log, "--verify"]),
                           ("doctor", ["doctor", log])):
            w, c, m = run([cli, *args])
            print(f"{name:36} {w:7.2f} {c:7.2f} {rows / c:11,.0f} {'':>7} {m:8.0f}")
        fox = os.path.join(tmp, "foxglove.mcap")  # Foxglove's schemas (issue 37)
        w, c, m = run([cli, "export", log, "--format", "foxglove", "-o", fox])
        print(f"{'export --format foxglove':36} {w:7.2f} {c:7.2f} {rows / c:11,.0f} "
              f"{os.path.getsize(fox) / 1e6:7.0f} {m:8.0f}")
        os.unlink(fox)
        w, c, m = run(["-c", "import cli"])
        print(f"{'(python, import cli: startup)':36} {w:7.2f} {c:7.2f} {'':>11} {'':>7} {m:8.0f}")
        print("a Parquet export, in this process (CPU seconds; each line includes the ones above "
              "it but the first):")
        for what, s in breakdown(log, os.path.join(tmp, "in.parquet")).items():
            print(f"  {what:34} {s:6.2f} s  {rows / s:11,.0f} rows/s")
        s, size = bounded_refusal(tmp)
        print(f"a {size / 1e3:.0f} kB log declaring a 100 MiB tick record: refused in {s:.3f} s "
              f"(verify, in this process)")


if __name__ == "__main__":
    if "--against" in sys.argv:
        i = sys.argv.index("--against")
        n = int(sys.argv[sys.argv.index("--rounds") + 1]) if "--rounds" in sys.argv else 5
        against(sys.argv[i + 1], n, quick="--quick" in sys.argv)
    else:
        main(quick="--quick" in sys.argv)
