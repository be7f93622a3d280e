"""Running a sweep: the cases split into parts, stepped in this process, in worker processes
(both cores by default) or on a Dask cluster, and gathered into one table in case order.

A case's row depends on that case alone (sweep.fleet), so any split gives the same table bit for
bit. Parts are the cases dealt round-robin into chunks (a grid's heavy corner is spread over every
worker), each chunk one fleet.

Ctrl-C: the first asks every worker to stop after the block of ticks in hand; the cases stepped
to the end are kept, the others are in the table as missing (``outcome`` empty). Workers ignore
SIGINT themselves (a terminal sends it to the whole process group): only the parent decides.
"""
from __future__ import annotations

import json
import math
import os
import signal
import sys
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, field

import numpy as np

from touchdown.sim.enums import SurfaceState
from touchdown.sweep.cases import Sweep

#: Result columns (SPEC.md section 6), after ``case`` and the varied keys: (name, unit, what it
#: is), each written with its unit and description in its Parquet field's metadata, as the
#: export's columns are (logs.export.arrow_schema)
RESULT_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("outcome", "", "the state at the end: landed, tipped, crashed, contact or flying "
                    "(empty: the case was not run, the sweep was interrupted)"),
    ("t_outcome", "s", "when the case entered its outcome (empty for contact and flying)"),
    ("max_tilt_deg", "deg", "the largest tilt of the long axis from local vertical"),
    ("max_penetration", "m", "the deepest a foot went into the ground"),
    ("peak_normal_force", "N", "the largest push of the ground"),
    ("slide_distance", "m", "how far the footprint travelled along the ground while touching it"),
    ("energy_dissipated_j", "J", "the mechanical energy (energy_j, MODEL-NOTES 28) at the "
                                 "first tick less at the last"),
    ("fuel_used", "kg", "fuel burnt"),
)
RESULTS = tuple(name for name, _, _ in RESULT_COLUMNS)
CASE_COLUMN = ("case", "", "the case's number (0-based), its place in the grid or the samples")
OUTCOMES = tuple(s.label for s in SurfaceState)  # flying, contact, landed, tipped, crashed

#: Ship-ticks of a chunk: a fleet big enough that the interpreter's share is nothing, small
#: enough that two workers finish together and a progress bar moves.
CHUNK_SHIP_TICKS = 4_000_000


def chunks(n_cases: int, n_ticks: int, workers: int) -> list[np.ndarray]:
    """The case numbers dealt round-robin into chunks: at least two per worker, each at most
    about CHUNK_SHIP_TICKS ship-ticks."""
    if n_cases == 0:
        return []
    by_size = math.ceil(n_cases * max(n_ticks, 1) / CHUNK_SHIP_TICKS)
    n = max(1, min(n_cases, max(2 * workers, by_size)))
    return [np.arange(j, n_cases, n) for j in range(n)]


# -- one part, in any process ------------------------------------------------------------------
_STOP = None  # the workers' shared stop flag (a multiprocessing Event)
_DONE = None  # the workers' shared ship-tick counter (a multiprocessing Value)


def _init_worker(stop, done) -> None:
    global _STOP, _DONE
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _STOP, _DONE = stop, done


def _progress(k: int) -> None:
    if _DONE is not None:
        with _DONE.get_lock():
            _DONE.value += k


def run_chunk(sw: Sweep, cases) -> dict[str, np.ndarray]:
    """One chunk's columns (sweep.fleet.run_part), in a worker."""
    from touchdown.sim.scenario import ScenarioError
    from touchdown.sweep.cases import SweepError
    from touchdown.sweep.fleet import run_part
    stop = (lambda: _STOP.is_set()) if _STOP is not None else None
    try:
        return run_part(sw, cases, _progress, stop)
    except ScenarioError as exc:  # as a plain message: it crosses to the parent by pickle
        raise SweepError(f"a case of the sweep: {exc}") from None


# -- the whole ---------------------------------------------------------------------------------
@dataclass
class Result:
    sweep: Sweep
    columns: dict[str, np.ndarray]  # in case order: case, state (int, -1 missing), results
    wall_s: float = 0.0
    interrupted: bool = False
    workers: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def done(self) -> np.ndarray:
        return self.columns["done"]

    def counts(self) -> dict[str, int]:
        st = self.columns["state"][self.done]
        out = {label: int(np.sum(st == k)) for k, label in enumerate(OUTCOMES)}
        out["missing"] = int(np.sum(~self.done))
        return out

    def summary(self) -> str:
        n = self.sweep.n_cases
        c = self.counts()
        parts = [f"{label} {c[label]:,} ({100.0 * c[label] / n:.1f}%)" for label in
                 ("landed", "tipped", "crashed", "contact", "flying") if c[label]]
        if c["missing"]:
            parts.append(f"missing {c['missing']:,} (interrupted)")
        return f"{n:,} cases: " + ", ".join(parts or ["none"])

    def table(self, scenario_json: str = ""):
        """The table of SPEC.md section 6 as a pyarrow Table, the definition, the scenario and
        the project version in its metadata."""
        import pyarrow as pa
        from importlib.metadata import version
        cols, sw, done = self.columns, self.sweep, self.done
        arrays = {"case": pa.array(cols["case"], pa.int64())}
        for j, a in enumerate(sw.axes):
            arrays[a.key] = pa.array(sw.values[cols["case"], j], pa.float64())
        labels = np.array(OUTCOMES, dtype=object)[np.clip(cols["state"], 0, None)]
        arrays["outcome"] = pa.array(labels, pa.string(), mask=~done)
        for name in RESULTS[1:]:
            x = cols[name]
            arrays[name] = pa.array(x, pa.float64(), mask=~done | np.isnan(x))
        meta = {"touchdown.sweep": json.dumps(sw.definition()),
                "touchdown.scenario": scenario_json or json.dumps(sw.doc, default=str),
                "touchdown.version": version("touchdown"),
                "touchdown.complete": "true" if done.all() else "false"}
        units = {name: (unit, doc) for name, unit, doc in (CASE_COLUMN, *RESULT_COLUMNS)}
        for a in sw.axes:
            units[a.key] = _axis_unit(a)
        schema = pa.schema([pa.field(name, arr.type, metadata={"unit": units[name][0],
                                                               "description": units[name][1]})
                            for name, arr in arrays.items()], metadata=meta)
        return pa.Table.from_arrays(list(arrays.values()), schema=schema)

    def write(self, path, scenario_json: str = "") -> None:
        import pyarrow.parquet as pq
        tmp = f"{path}.partial"
        pq.write_table(self.table(scenario_json), tmp)
        os.replace(tmp, path)


def _axis_unit(axis) -> tuple[str, str]:
    """A varied key's unit and description, from its scenario setting (sim.settings)."""
    from touchdown.sim.settings import BY_KEY
    s = BY_KEY.get(axis.key)
    what = f"the varied scenario key {axis.key}" + (f": {s.doc}" if s is not None and s.doc
                                                     else "")
    return (s.unit if s is not None else ""), what


def _gather(sw: Sweep, parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    n = sw.n_cases
    out = {"case": np.arange(n, dtype=np.int64), "state": np.full(n, -1, np.int8),
           "done": np.zeros(n, bool)}
    for name in RESULTS[1:]:
        out[name] = np.full(n, np.nan)
    for p in parts:
        idx = p["case"]
        out["state"][idx] = p["state"]
        out["done"][idx] = p["done"]
        for name in RESULTS[1:]:
            out[name][idx] = p[name]
    return out


def run(sw: Sweep, workers: int = 2, scheduler: str | None = None, progress: bool = False,
        chunk_cases: int | None = None) -> Result:
    """Run every case of ``sw``: in this process (``workers`` 1 or 0), in ``workers`` spawned
    processes, or on the Dask scheduler at ``scheduler``. ``chunk_cases``: cases per chunk
    (default: sized by ship-ticks)."""
    t0 = time.perf_counter()
    n_ticks = _n_ticks(sw)
    if chunk_cases:
        n = max(1, math.ceil(sw.n_cases / chunk_cases))
        parts = [np.arange(j, sw.n_cases, n) for j in range(n)]
    else:
        parts = chunks(sw.n_cases, n_ticks, max(workers, 1))
    bar = _Bar(sw.n_cases * n_ticks) if progress else None
    stop = _Interrupt()
    results: list[dict] = []
    try:
        stop.install()
        if scheduler:
            results, how = _run_dask(sw, parts, scheduler, stop, bar)
        elif workers <= 1:
            how = "1 process"
            for p in parts:
                if stop.asked:
                    break
                from touchdown.sweep.fleet import run_part
                results.append(run_part(sw, p, bar.add if bar else None, lambda: stop.asked))
        else:
            results, how = _run_processes(sw, parts, workers, stop, bar)
    finally:
        stop.restore()
        if bar is not None:
            bar.close()
    res = Result(sw, _gather(sw, results), time.perf_counter() - t0, stop.asked, how)
    return res


def _n_ticks(sw: Sweep) -> int:
    from touchdown.sim.scenario import parse
    return parse(sw.case_doc(0), sw.source).params.sim.n_ticks


def start_method() -> str:
    """How the workers start: forked from this process where that is safe (Linux, and no other
    thread here: a fork copies any lock another thread holds at that instant, e.g. a stream's,
    for ever), else spawned.

    Why fork: a spawned worker starts a fresh interpreter that imports numpy, numba and the
    package again (~1.0 s of CPU here), sets up numba's typing and lowering registries at its
    first compiled call (~0.6 s: numba imports scipy.linalg to look for a BLAS) and loads the
    step from the kernel cache (~0.45 s): ~2 s of CPU a worker, before its first case. A forked
    worker has all of that from this process, which loads the kernels once first
    (:func:`sweep.fleet.ready`). The cases' numbers do not depend on it (the same machine code
    from the same cache)."""
    if sys.platform.startswith("linux") and threading.active_count() == 1:
        return "fork"
    return "spawn"


def _run_processes(sw, parts, workers, stop, bar):
    import multiprocessing as mp
    method = start_method()
    if method == "fork":
        from touchdown.sweep.fleet import ready
        ready()  # the kernels loaded here, once: each forked worker has them
    ctx = mp.get_context(method)
    flag, done = ctx.Event(), ctx.Value("q", 0)
    results = []
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_worker,
                             initargs=(flag, done)) as pool:
        # (forked at the first submit, before the pool's own threads and the progress bar's)
        futures = {pool.submit(run_chunk, sw, p) for p in parts}
        try:
            while futures:
                finished, futures = wait(futures, timeout=0.2, return_when=FIRST_COMPLETED)
                for f in finished:
                    if not f.cancelled():
                        results.append(f.result())
                if bar is not None:
                    bar.set(done.value)
                if stop.asked and not flag.is_set():
                    flag.set()  # the chunks under way stop after their block
                    for f in futures:
                        f.cancel()
        finally:
            flag.set()
    return results, f"{workers} processes"


def _run_dask(sw, parts, address, stop, bar):
    from distributed import Client, as_completed
    results = []
    with Client(address) as client:
        futures = client.map(run_chunk, [sw] * len(parts), parts, pure=False)
        n_workers = len(client.scheduler_info().get("workers", {}))
        done_ticks = 0
        per = {f.key: len(p) for f, p in zip(futures, parts)}
        n_ticks = bar.total // max(sw.n_cases, 1) if bar else 0
        ac = as_completed(futures)
        for f in ac:
            if stop.asked:
                for g in futures:
                    g.cancel()
                break
            results.append(client.gather(f))
            if bar is not None:
                done_ticks += per[f.key] * n_ticks
                bar.set(done_ticks)
    return results, f"Dask at {address} ({n_workers} workers)"


class _Interrupt:
    """SIGINT while sweeping sets ``asked`` (the main thread only)."""

    def __init__(self):
        self.asked = False
        self._previous = None

    def _on(self, signum, frame):
        self.asked = True

    def install(self):
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._on)

    def restore(self):
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None


class _Bar:
    """A rich progress bar over ship-ticks, on a terminal; shown from its first update (its
    refresh thread then starts: after the workers are forked, :func:`start_method`)."""

    def __init__(self, total: int):
        self.total = total
        self.done = 0
        self.prog = None
        self.shown = False

    def _show(self) -> None:
        self.shown = True
        if sys.stdout.isatty():
            from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn,
                                       TimeRemainingColumn)
            self.prog = Progress(TextColumn("sweep"), BarColumn(), TextColumn("ship-ticks"),
                                 MofNCompleteColumn(), TimeRemainingColumn())
            self.prog.start()
            self.task = self.prog.add_task("sweep", total=self.total)

    def add(self, k: int) -> None:
        self.set(self.done + k)

    def set(self, k: int) -> None:
        self.done = k
        if not self.shown:
            self._show()
        if self.prog is not None:
            self.prog.update(self.task, completed=k)

    def close(self) -> None:
        if self.prog is not None:
            self.prog.stop()
