"""touchdown sweep (issue 23; SPEC.md sections 2 and 6): the cases as one fleet, the same table
whatever the split (in-process chunks, processes, a Dask cluster), a case recorded alone equal to
its row, Latin hypercube samples, Ctrl-C keeping the cases done, usage errors."""
import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

import background
import warmup

from touchdown.cli import main
from touchdown.logs.export import event_rows, tick_rows
from touchdown.logs.reader import LogReader
from touchdown.sim.scenario import load_toml
from touchdown.sweep.cases import Sweep, SweepError, latin_hypercube, parse_vary
from touchdown.sweep.run import run

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]

#: A short sideways touchdown on a slope: stands, slides and tips across the grid below.
BASE = """
name = "env"
duration = 4.0
[body.terrain]
slope_deg = 4.0
slope_azimuth_deg = 90.0
[[ships]]
id = "lander"
[ships.initial]
altitude = 0.2
vertical_speed = -2.0
horizontal_speed = 1.0
heading_deg = 90.0
"""
VARY = ("ships.initial.horizontal_speed=0:6:4", "body.terrain.slope_deg=0:10:3")


def base_doc():
    return load_toml(BASE, "env.toml")


def sweep_of(vary=VARY, samples=None, seed=0):
    return Sweep.of(base_doc(), "env.toml", parse_vary(vary, samples is not None), samples, seed)


@background.job("test_sweep.py::test_the_table_has_spec_6_columns_and_every_outcome_kind")
def _compile_the_sweeps_kernels() -> None:
    """The sweep's kernels into the cache (sweep.fleet.ready in a subprocess), ahead of this
    file's first table in a serial run (tests/background.py)."""
    subprocess.run([sys.executable, "-c", "from touchdown.sweep.fleet import ready; ready()"],
                   capture_output=True, timeout=1800)


@pytest.fixture(scope="module")
def sweep_kernels():
    """The sweep's kernels in the cache and loaded in this process (sweep.fleet.ready): the step
    (record's sim.step.step_ticks, which the warm-up compiled) and the sweep's own reductions
    (tests/suite_kernels.py compiles them in the warm-up; a few seconds of CPU otherwise). Under
    ready's lock in the kernel cache, workers that come to it together compile them once.
    (A serial run: the background job has compiled them; the lock is uncontended.)"""
    from touchdown.sweep.fleet import ready
    background.wait(_compile_the_sweeps_kernels)
    ready()


@pytest.fixture(scope="module")
def whole(sweep_kernels):
    """The grid's table, in this process, one chunk."""
    return run(sweep_of(), workers=1, chunk_cases=10_000).table()


def invoke(*args):
    r = CliRunner().invoke(main, [str(a) for a in args])
    assert r.exception is None or isinstance(r.exception, SystemExit), r.exception
    return r


def test_the_table_has_spec_6_columns_and_every_outcome_kind(whole):
    assert whole.column_names == ["case", "ships.initial.horizontal_speed",
                                  "body.terrain.slope_deg", "outcome", "t_outcome",
                                  "max_tilt_deg", "max_penetration", "peak_normal_force",
                                  "slide_distance", "energy_dissipated_j", "fuel_used"]
    rows = whole.to_pylist()
    assert [r["case"] for r in rows] == list(range(12))
    # the grid: the last key varies fastest
    assert [r["body.terrain.slope_deg"] for r in rows[:3]] == [0.0, 5.0, 10.0]
    assert [r["ships.initial.horizontal_speed"] for r in rows[::3]] == [0.0, 2.0, 4.0, 6.0]
    outcomes = {r["outcome"] for r in rows}
    assert {"landed", "tipped"} <= outcomes
    for r in rows:
        if r["outcome"] in ("landed", "tipped", "crashed"):
            assert 0.0 < r["t_outcome"] <= 4.0
        else:
            assert r["t_outcome"] is None
    upright = rows[0]  # 0 m/s sideways on flat ground: stands, no slide
    assert upright["outcome"] == "landed" and upright["slide_distance"] < 1e-6
    assert max(r["slide_distance"] for r in rows) > 1.0
    meta = whole.schema.metadata
    assert b"touchdown.sweep" in meta and b"touchdown.version" in meta
    assert meta[b"touchdown.complete"] == b"true"


def test_any_split_gives_the_same_table_bit_for_bit(whole):
    sw = sweep_of()
    for chunk in (1, 5):
        assert run(sw, workers=1, chunk_cases=chunk).table().equals(whole, check_metadata=True)
    two = run(sw, workers=2, chunk_cases=5)  # worker processes (sweep.run.start_method)
    assert two.workers == "2 processes"
    assert two.table().equals(whole, check_metadata=True)


def test_forked_and_spawned_workers_give_the_same_table(whole, tmp_path):
    """The command line's workers are forked (its process has one thread: sweep.run.start_method);
    a process with another thread spawns them. Both tables are the one-process table."""
    scn = tmp_path / "env.toml"
    scn.write_text(BASE)
    code = ("import sys; from touchdown.cli import main; from touchdown.sweep import run; "
            "print(run.start_method(), file=sys.stderr); sys.argv = ['touchdown'] + sys.argv[1:]; "
            "main()")
    busy = ("import threading; "
            "threading.Thread(target=threading.Event().wait, daemon=True).start(); ")
    tables = {}
    for method, extra in (("fork", ""), ("spawn", busy)):
        out = tmp_path / f"{method}.parquet"
        r = subprocess.run([sys.executable, "-c", extra + code, "sweep", str(scn), "--vary",
                            VARY[0], "--vary", VARY[1], "--workers", "2", "-o", str(out)],
                           capture_output=True, text=True, cwd=tmp_path, timeout=600)
        assert r.returncode == 0, r.stderr
        assert r.stderr.splitlines()[0] == method
        tables[method] = pq.read_table(out)
    assert tables["fork"].equals(tables["spawn"], check_metadata=True)
    assert tables["fork"].equals(whole, check_metadata=False)  # (its source's name differs)


def test_a_dask_local_cluster_of_two_workers_gives_the_same_table(whole):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        res = run(sweep_of(), scheduler=cluster.scheduler_address, chunk_cases=4)
    assert res.workers.endswith("(2 workers)")
    assert res.table().equals(whole, check_metadata=True)


def _row_from_log(path: Path) -> dict:
    """A recorded case's row, from its log alone (its exported ticks and events), computed
    here independently of the sweep's compiled reductions."""
    reader = LogReader(path)
    ticks = list(tick_rows(reader))
    events = list(event_rows(reader))
    final = ticks[-1]["state"]
    last = [e for e in events if e["to_state"] == final]
    t_out = last[-1]["t_event"] if last and final in ("landed", "tipped", "crashed") else None
    slide = 0.0
    prev = None
    com = 3.0  # the default lander's com_height (BASE does not set it)
    for td in reader.ticks():
        a = td.arrays
        p, q = td.vec("pos_m", 3)[0], td.vec("quat", 4)[0]
        st = int(a["surface_state"][0])
        w, x, y, z = (float(v) for v in q)
        ez = (2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y))
        f = tuple(float(p[k]) - com * ez[k] for k in range(3))
        f = (1.0 * f[0] + 0.0 * f[1], 1.0 * f[1] - 0.0 * f[0], f[2])
        if prev is not None and prev[0] == 1 and st == 1:
            d = tuple(f[k] - prev[1][k] for k in range(3))
            along = (d[0] * f[0] + d[1] * f[1] + d[2] * f[2]) / math.sqrt(
                f[0] * f[0] + f[1] * f[1] + f[2] * f[2])
            tang2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - along * along
            if tang2 > 0.0:
                slide += math.sqrt(tang2)
        prev = (st, f)
    return {"outcome": final, "t_outcome": t_out,
            "max_tilt_deg": max(r["tilt_deg"] for r in ticks),
            "max_penetration": max(0.0, max(r["peak_penetration"] for r in ticks)),
            "peak_normal_force": max(r["normal_force"] for r in ticks),
            "slide_distance": slide,
            "energy_dissipated_j": ticks[0]["energy_j"] - ticks[-1]["energy_j"],
            "fuel_used": ticks[0]["fuel_mass"] - ticks[-1]["fuel_mass"]}


def test_a_case_recorded_alone_equals_its_row_and_verifies(whole, tmp_path):
    scn = tmp_path / "env.toml"
    scn.write_text(BASE)
    rows = whole.to_pylist()
    picks = {rows[0]["outcome"]: 0}
    for r in rows:
        picks.setdefault(r["outcome"], r["case"])
    picks["slid"] = max(rows, key=lambda r: r["slide_distance"])["case"]
    for case in sorted(set(picks.values())):
        out = tmp_path / f"case{case}.mcap"
        args = ["sweep", scn, "--record", case, "-o", out]
        for v in VARY:
            args += ["--vary", v]
        r = invoke(*args)
        assert r.exit_code == 0, r.output
        assert invoke("replay", out, "--verify").exit_code == 0
        got = _row_from_log(out)
        want = {k: rows[case][k] for k in got}
        assert got == want, (case, got, want)  # exactly: the same bits


def test_latin_hypercube_is_one_point_per_slice_and_repeatable():
    u = latin_hypercube(50, 3, seed=7)
    for d in range(3):
        assert sorted(np.floor(u[:, d] * 50).astype(int).tolist()) == list(range(50))
    assert np.array_equal(u, latin_hypercube(50, 3, seed=7))
    assert not np.array_equal(u, latin_hypercube(50, 3, seed=8))
    sw = sweep_of(("ships.initial.horizontal_speed=0:6", "body.terrain.slope_deg=0:10"),
                  samples=6, seed=3)
    assert sw.n_cases == 6
    assert np.all((sw.values[:, 0] >= 0) & (sw.values[:, 0] <= 6))
    assert len(sw.groups(range(6))) == 6  # every sample its own slope: its own scene


def test_an_interrupted_sweep_keeps_the_cases_done_and_marks_the_rest(sweep_kernels, monkeypatch):
    import touchdown.sweep.run as R
    sw = sweep_of()
    calls = []

    class Once(R._Interrupt):
        @property
        def asked(self):
            return len(calls) > 0

        @asked.setter
        def asked(self, value):
            pass

    from touchdown.sweep import fleet
    original = fleet.run_part

    def part(*args, **kw):
        out = original(*args, **kw)
        calls.append(1)
        return out

    monkeypatch.setattr(R, "_Interrupt", Once)
    monkeypatch.setattr(fleet, "run_part", part)
    res = run(sw, workers=1, chunk_cases=4)
    tab = res.table()
    outcome = tab.column("outcome").to_pylist()
    assert sum(o is not None for o in outcome) == 4
    assert sum(o is None for o in outcome) == 8
    assert tab.column("max_tilt_deg").null_count == 8
    assert tab.schema.metadata[b"touchdown.complete"] == b"false"
    assert "missing 8 (interrupted)" in res.summary()


def _wait_for_a_child(proc: subprocess.Popen, timeout_s: float) -> None:
    """Until ``proc`` has a child process (Linux /proc: each process's parent id)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()[1]
        for stat in Path("/proc").glob("[0-9]*/stat"):
            try:
                ppid = int(stat.read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            if ppid == proc.pid:
                return
        time.sleep(0.1)
    raise AssertionError(f"the sweep started no worker in {timeout_s:g} s")


def test_ctrl_c_writes_the_table_of_the_cases_done(sweep_kernels, tmp_path):
    scn = tmp_path / "long.toml"
    # a turning body: no ship comes to a fixed point, every tick of every case is stepped
    scn.write_text(BASE.replace("duration = 4.0", "duration = 300.0").replace(
        "[body.terrain]", "[body]\nrotation_period = 2360591.5\n[body.terrain]"))
    out = tmp_path / "t.parquet"
    proc = subprocess.Popen([sys.executable, str(ROOT / "cli.py"), "sweep", str(scn), "--vary",
                             "ships.initial.horizontal_speed=0:6:4000", "--workers", "2",
                             "-o", str(out)], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    # the sweep takes Ctrl-C from before it starts its workers (sweep.run._Interrupt); wait for
    # them, not a fixed time: at load 5-7 a 5 s sleep sent SIGINT before the handler was there
    _wait_for_a_child(proc, timeout_s=120.0)
    time.sleep(2.0)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "marked missing" in stderr
    tab = pq.read_table(out)
    assert tab.num_rows == 4000
    assert 0 < tab.column("outcome").null_count <= 4000
    assert tab.schema.metadata[b"touchdown.complete"] == b"false"


@pytest.mark.parametrize("vary, says", [
    ("ships.initial.nonsense=0:1:3", "ships.initial.nonsense"),
    ("sim.dt=0.01:0.05:3", "sim.dt"),
    ("ships.initial.vertical_speed=0:1", "expected"),
    ("ships.initial.tilt_deg=0:500:3", "tilt_deg"),
    ("ships.id=0:1:2", "ships.id"),
])
def test_a_bad_axis_is_refused_in_one_line_naming_it(vary, says, tmp_path):
    scn = tmp_path / "env.toml"
    scn.write_text(BASE)
    r = invoke("sweep", scn, "--vary", vary, "-o", tmp_path / "x.parquet")
    assert r.exit_code == 2, r.output
    assert says in r.output and len(r.output.strip().splitlines()) == 1
    assert not (tmp_path / "x.parquet").exists()


def test_the_cli_summary_and_the_table(sweep_kernels, tmp_path):
    scn = tmp_path / "env.toml"
    scn.write_text(BASE)
    out = tmp_path / "t.parquet"
    r = invoke("sweep", scn, "--vary", "ships.initial.horizontal_speed=0:6:3", "--samples", "3",
               "--seed", "1", "-o", out, "--workers", "1")
    assert r.exit_code == 0, r.output
    assert r.output.startswith("3 cases: ")
    assert pq.read_table(out).num_rows == 3


def test_bad_values_of_an_axis_are_refused():
    with pytest.raises(SweepError, match="horizontal_speed"):
        sweep_of(("ships.initial.horizontal_speed=0:1e9:3",))


def test_charts_of_a_grid_and_of_random_samples(whole, tmp_path):
    pytest.importorskip("matplotlib")
    from touchdown.sweep.chart import CODE, draw, regions
    draw(whole, tmp_path / "grid.png")
    assert (tmp_path / "grid.png").stat().st_size > 10_000
    codes = regions(whole.column("outcome").to_pylist(),
                    whole.column("slide_distance").to_numpy())
    assert CODE["stands"] in codes and CODE["tips over"] in codes
    sampled = run(sweep_of(("ships.initial.horizontal_speed=0:6", "body.terrain.slope_deg=0:10"),
                           samples=40, seed=2), workers=1).table()
    draw(sampled, tmp_path / "p.png")
    assert (tmp_path / "p.png").stat().st_size > 10_000


def test_values_refused_together_are_one_line_naming_the_key(tmp_path):
    """A landed ship tilted 30 deg stands toward a foot (yaw 0 or 90: critical 37 deg) but not
    toward the edge between two (yaw 45: 28 deg): the grid's ends pass, its middle is refused,
    in a worker process, as one line."""
    scn = tmp_path / "landed.toml"
    scn.write_text('''name = "landed"
duration = 1.0
[[ships]]
id = "a"
[ships.initial]
state = "landed"
altitude = 0.0
tilt_deg = 30.0
''')
    r = invoke("sweep", scn, "--vary", "ships.initial.yaw_deg=0:90:3", "-o", tmp_path / "x.parquet")
    assert r.exit_code == 2, r.output
    assert "tilt_deg" in r.output and len(r.output.strip().splitlines()) == 1, r.output
    assert not (tmp_path / "x.parquet").exists()


def test_every_column_of_the_table_carries_its_unit_and_description(sweep_kernels, tmp_path):
    """As the export's Parquet does (issue 37): each field's metadata holds its unit and what
    it is; a varied key's unit is its scenario setting's (sim.settings)."""
    scn = tmp_path / "env.toml"
    scn.write_text(BASE)
    out = tmp_path / "t.parquet"
    r = invoke("sweep", scn, "--vary", VARY[0], "--vary", VARY[1], "--workers", "1", "-o", out)
    assert r.exit_code == 0, r.output
    schema = pq.read_schema(out)
    units = {f.name: f.metadata[b"unit"].decode() for f in schema}
    assert units == {"case": "", "ships.initial.horizontal_speed": "m/s",
                     "body.terrain.slope_deg": "deg", "outcome": "", "t_outcome": "s",
                     "max_tilt_deg": "deg", "max_penetration": "m", "peak_normal_force": "N",
                     "slide_distance": "m", "energy_dissipated_j": "J", "fuel_used": "kg"}
    assert all(f.metadata[b"description"] for f in schema)
    assert b"horizontal_speed" in schema.field("ships.initial.horizontal_speed").metadata[
        b"description"]
    import duckdb
    got = duckdb.sql(f"select count(*), count(outcome) from read_parquet('{out}')").fetchall()
    assert got == [(12, 12)]


# -- the sweep's own compile --------------------------------------------------------------------
def _in_fresh_process(script: str, **env) -> str:
    import os
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                       timeout=600, env={**os.environ, **env})
    assert r.returncode == 0, r.stderr
    return r.stdout


def test_warm_with_sweep_readies_the_sweeps_kernels_and_plain_warm_does_not(sweep_kernels):
    """`touchdown warm --sweep` loads (here: the fixture put them in the cache) the kernels a
    sweep calls, compiling nothing more, and says so; plain `warm` leaves them to the first
    sweep. In a fresh process each time, counting what numba compiles and what is loaded."""
    script = warmup.COUNT_COMPILES + '''
from touchdown.cli import main
main(["warm"{flag}], standalone_mode=False)
from touchdown.sweep.fleet import SWEEP_KERNELS
print("LOADED", sum(len(k.twin().overloads) for k in SWEEP_KERNELS), "COMPILED", len(compiled))
'''
    with_sweep = _in_fresh_process(script.replace("{flag}", ', "--sweep"'))
    assert "the sweep's too" in with_sweep and "LOADED 3 COMPILED 0" in with_sweep, with_sweep
    plain = _in_fresh_process(script.replace("{flag}", ""))
    assert "the sweep's" not in plain and "LOADED 0 COMPILED 0" in plain, plain


def test_a_sweep_compiles_its_kernels_first_only_where_the_cache_lacks_them(sweep_kernels,
                                                                            tmp_path):
    from touchdown.sweep.command import _compile_first
    from touchdown.sweep.fleet import kernels_ready
    said = []
    assert kernels_ready() and _compile_first(said.append) is False and said == []
    # an empty cache (NUMBA_CACHE_DIR): not ready, which the parent then compiles, saying so
    # (not run here: minutes of CPU; the workers' own compile is what it replaces)
    out = _in_fresh_process("from touchdown.sweep.fleet import kernels_ready; "
                            "print('READY', kernels_ready())", NUMBA_CACHE_DIR=str(tmp_path))
    assert "READY False" in out, out
