"""The cases as one fleet: every case a ship, stepped by the compiled tick of record and replay
(sim.step.step_ticks, the same compiled code, loaded from the cache `touchdown warm` fills), each
group of cases that share a scene (a case may change the contact model, the body or the slope)
with its own scene record and terrain, and its outcome reduced block by block (:func:`_fold_block`):
nothing of a tick is kept past its block.

Why step_ticks itself: a loop of the sweep's own around the step (0.8's ``sweep_ticks``) is
compiled as a whole with the step it calls (sim.compiled: an entry point links in and optimizes
everything below it), so the step's ~180 kernels were optimized and turned into machine code a
second time for it: ~75 s of CPU after `touchdown warm`, ~130 s in a fresh process (measured with
numba's compile events, docs/issue36/session22-suite2.txt). The sweep's own kernels are now the
reductions alone, a few seconds.

Why a case's row is the bits of the case recorded alone: the row's ship is built by the scenario
parser from the case's own scenario (its parameters, sub-steps and start placed on its terrain do
not depend on the other ships parsed with it: sim.scenario), and stepped by the same per-ship tick
with the same scene record, rotation and commands as ``touchdown record`` steps it (sim.step: no
ship reads another's numbers). The reductions below are running maxima, sums and the instant of the
last transition, each of one ship's own numbers.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from touchdown.logs import derived
from touchdown.sim.compiled import cache_dir, in_cache, separate
from touchdown.sim.contact import Legs
from touchdown.sim.dynamics import Motion
from touchdown.sim.energy import mechanical, total
from touchdown.sim.frames import Body, body_rotation
from touchdown.sim.params import SCENE_DTYPE, Records
from touchdown.sim.state import (COMMAND_DTYPE, INPUTS_DTYPE, OUTPUTS_DTYPE, STATE_DTYPE,
    TRANSITION_DTYPE, concatenate)
from touchdown.sim.ship import CONTACT, Turn, scene_ground
from touchdown.sim.step import Queue, Span, Written, observe_ships, resting, step_ticks
from touchdown.sim.vec import quat_axis_z
from touchdown.sweep.cases import Sweep

#: What the fleet reduces per ship as it steps (one record per case).
ACC_DTYPE = np.dtype([
    ("min_cos_tilt", "f8"),  # -> max_tilt_deg
    ("max_penetration_m", "f8"),
    ("peak_normal_n", "f8"),
    ("slide_m", "f8"),
    ("t_last_s", "f8"),  # the instant of the last transition
    ("last_to", "i1"),  # the state it led to (-1: none)
    ("e0_j", "f8"),  # mechanical energy at tick 0 and at the end (sim.energy, as export's energy_j)
    ("e1_j", "f8"),
], align=True)

#: Ship-ticks per call of the step: about a tenth of a second of stepping, so that Ctrl-C and the
#: progress bar answer promptly, and ~10 MB of the block's per-tick records (states, telemetry,
#: inputs: ~0.5 kB a ship-tick) that :func:`_fold_block` reduces.
BLOCK_SHIP_TICKS = 20_000


@separate
def _energy_into(scenes, terrains, group, rot_index, rot, ships, state, acc, end):
    """Each ship's mechanical energy at its state (sim.measure.energy's arithmetic) into
    ``acc.e0_j`` or (``end``) ``acc.e1_j``; ``rot``: (cos, sin) per rotation group."""
    for i in range(state.shape[0]):
        g = group[i]
        cfg = scenes[g]
        sp = ships[i]
        rec = state[i]
        r = rot_index[i]
        ground = scene_ground(cfg, terrains[g], rot[r, 0], rot[r, 1])
        ratio = rec.mass_kg / sp.mass0_kg
        motion = Motion((rec.pos_m[0], rec.pos_m[1], rec.pos_m[2]),
                        (rec.vel_mps[0], rec.vel_mps[1], rec.vel_mps[2]),
                        (rec.quat[0], rec.quat[1], rec.quat[2], rec.quat[3]),
                        (rec.omega_body_radps[0], rec.omega_body_radps[1],
                         rec.omega_body_radps[2]))
        e = mechanical(Body(cfg.gm_m3ps2, cfg.body_radius_m, cfg.omega_radps), rec.mass_kg,
                       (sp.inertia0_kgm2[0] * ratio, sp.inertia0_kgm2[1] * ratio,
                        sp.inertia0_kgm2[2] * ratio),
                       Legs(sp.leg_radius_m, sp.com_height_m, sp.stiffness_per_kg * rec.mass_kg),
                       motion, ground, True)
        if end:
            acc[i].e1_j = total(e)
        else:
            acc[i].e0_j = total(e)


@separate
def _fold_outputs(o, a):
    """A tick's outputs ``o`` into a case's running extremes ``a`` (records, written in place)."""
    if o.cos_tilt < a.min_cos_tilt:
        a.min_cos_tilt = o.cos_tilt
    if o.peak_penetration_m > a.max_penetration_m:
        a.max_penetration_m = o.peak_penetration_m
    if o.normal_force_n > a.peak_normal_n:
        a.peak_normal_n = o.normal_force_n


@separate
def _observe_into(outs, acc):
    for i in range(outs.shape[0]):
        _fold_outputs(outs[i], acc[i])


@separate
def _footprint_bf(p, q, h, c, s):
    """The footprint's centre (h below the centre of mass along the long axis), turned into the
    body-fixed frame by the body's angle (c, s)."""
    ez = quat_axis_z(q)
    f = (p[0] - h * ez[0], p[1] - h * ez[1], p[2] - h * ez[2])
    return (c * f[0] + s * f[1], c * f[1] - s * f[0], f[2])


@separate
def _fold_block(before, states, outputs, ships, rot, events, event_ticks, n_events, dt_s, acc):
    """A block of ticks of one group's ships, as sim.step.step_ticks wrote it (``states`` and
    ``outputs``: (ticks, ships); ``before``: the ships' states before the block; ``rot[k]``: the
    body's (cos, sin) at the start of the block's k-th tick; ``events[:n_events]`` its
    transitions, ``event_ticks`` the tick each led to), folded into each ship's ``acc``, tick
    after tick as each ship stepped: its telemetry's extremes, the ground its footprint slid over
    while in contact through a tick, and its last transition (at n dt - (dt - t_offset) for the
    step into tick n, as sim.step.transitions)."""
    for i in range(states.shape[1]):
        a = acc[i]
        h = ships[i].com_height_m
        prev = before[i]
        for k in range(states.shape[0]):
            rec = states[k, i]
            _fold_outputs(outputs[k, i], a)
            if prev.surface_state == CONTACT and rec.surface_state == CONTACT:
                f0 = _footprint_bf((prev.pos_m[0], prev.pos_m[1], prev.pos_m[2]),
                                   (prev.quat[0], prev.quat[1], prev.quat[2], prev.quat[3]),
                                   h, rot[k, 0], rot[k, 1])
                f1 = _footprint_bf((rec.pos_m[0], rec.pos_m[1], rec.pos_m[2]),
                                   (rec.quat[0], rec.quat[1], rec.quat[2], rec.quat[3]),
                                   h, rot[k + 1, 0], rot[k + 1, 1])
                d = (f1[0] - f0[0], f1[1] - f0[1], f1[2] - f0[2])
                n2 = f1[0] * f1[0] + f1[1] * f1[1] + f1[2] * f1[2]
                along = (d[0] * f1[0] + d[1] * f1[1] + d[2] * f1[2]) / math.sqrt(n2)
                tang2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - along * along
                if tang2 > 0.0:
                    a.slide_m = a.slide_m + math.sqrt(tang2)
            prev = rec
    for e in range(n_events):
        ev = events[e]
        a = acc[ev.ship]
        a.t_last_s = event_ticks[e] * dt_s - (dt_s - ev.t_offset_s)
        a.last_to = ev.to_state


@dataclass
class Fleet:
    """The cases of one part of a sweep, built and ready to step."""

    cases: np.ndarray  # the case numbers, in row order
    scenes: np.ndarray
    terrains: np.ndarray
    group: np.ndarray
    rot_index: np.ndarray
    omegas: np.ndarray  # per rotation group
    ships: np.ndarray
    state: np.ndarray
    inputs: np.ndarray
    commands: np.ndarray
    fuel0: np.ndarray
    initial_state: np.ndarray  # each case's surface state at tick 0
    dt_s: float
    n_ticks: int
    acc: np.ndarray

    @classmethod
    def build(cls, sw: Sweep, cases: Sequence[int]) -> "Fleet":
        from touchdown.sim.scenario import parse
        scenes, terrains, ships, states, order, cmds = [], [], [], [], [], []
        group, omegas, rot_of = [], [], {}
        rot_index = []
        dt = n_ticks = None
        row = 0
        for g, members in enumerate(sw.groups(cases)):
            scn = parse(sw.group_doc(members), sw.source)
            p = scn.params
            dt, n_ticks = p.sim.dt_s, p.sim.n_ticks
            scenes.append(p.scene)
            terrains.append(p.terrain)
            ships.append(p.ships)
            states.append(scn.initial)
            om = p.body.omega_radps
            r = rot_of.setdefault(om, len(rot_of))
            if r == len(omegas):
                omegas.append(om)
            rot_index.extend([r] * len(members))
            group.extend([g] * len(members))
            index = {sid: row + i for i, sid in enumerate(p.ships.ship_id)}
            for cmd in scn.timeline.commands:
                cmds.append((cmd.tick, index[cmd.ship_id], cmd.inputs))
            order.extend(members)
            row += len(members)
        n = row
        table = np.array(sorted(cmds, key=lambda c: (c[0], c[1])), dtype=COMMAND_DTYPE) \
            if cmds else np.zeros(0, COMMAND_DTYPE)
        if n == 0:
            return cls(np.zeros(0, np.int64), np.zeros(0, SCENE_DTYPE), np.zeros(0), np.zeros(0, np.int64),
                       np.zeros(0, np.int64), np.zeros(1), np.zeros(0), np.zeros(0, STATE_DTYPE),
                       np.zeros(0), table, np.zeros(0), np.zeros(0, np.int8), 0.05, 0,
                       np.zeros(0, ACC_DTYPE))
        sh = concatenate(ships)
        st = concatenate(states)
        from touchdown.sim.state import INPUTS_DTYPE
        fleet = cls(np.array(order, np.int64), np.concatenate(scenes), np.concatenate(terrains),
                    np.array(group, np.int64), np.array(rot_index, np.int64),
                    np.array(omegas, float), sh.rows.copy(), st.rows.copy(),
                    np.zeros(n, INPUTS_DTYPE), table, st.rows["fuel_kg"].copy(),
                    st.rows["surface_state"].copy(), dt, n_ticks, np.zeros(n, ACC_DTYPE))
        fleet._start()
        return fleet

    def rotations(self, first_tick: int, k: int) -> np.ndarray:
        """(cos, sin) at the start of ticks first_tick .. first_tick + k per rotation group (as
        sim.step.rotations computes them)."""
        out = np.empty((len(self.omegas), k + 1, 2))
        for r, om in enumerate(self.omegas.tolist()):
            self._spin(om, first_tick, out[r])
        return out

    def _spin(self, om: float, first_tick: int, out: np.ndarray) -> None:
        """(cos, sin) of a body spinning at ``om`` at the start of ticks first_tick, ... into the
        rows of ``out``."""
        if om == 0.0:
            out[:, 0], out[:, 1] = 1.0, 0.0
        else:
            for j in range(out.shape[0]):
                out[j] = body_rotation(om, (first_tick + j) * self.dt_s)

    def _start(self) -> None:
        """Tick 0: the telemetry of each start (as the log's first record), the energy."""
        acc = self.acc
        acc["min_cos_tilt"] = np.inf
        acc["max_penetration_m"] = -np.inf
        acc["peak_normal_n"] = -np.inf
        acc["last_to"] = -1
        acc["t_last_s"] = np.nan
        outs = np.zeros(len(self.cases), OUTPUTS_DTYPE)
        rot = self.rotations(0, 0)
        for g in range(len(self.scenes)):
            rows = np.flatnonzero(self.group == g)
            r = int(self.rot_index[rows[0]])
            o = np.zeros(len(rows), OUTPUTS_DTYPE)
            observe_ships(self.scenes[g:g + 1], self.terrains[g:g + 1], self.ships[rows],
                          self.state[rows], o, rot[r, 0, 0], rot[r, 0, 1])
            outs[rows] = o
        _observe_into(outs, acc)
        _energy_into(self.scenes, self.terrains, self.group, self.rot_index, rot[:, 0, :],
                     self.ships, self.state, acc, False)

    def bounds(self) -> list[tuple[int, int]]:
        """Each group's rows (lo, hi): Fleet.build lays each group's cases in one run of rows."""
        starts = np.flatnonzero(np.diff(self.group, prepend=-1))
        return list(zip(starts.tolist(), np.append(starts[1:], len(self.group)).tolist()))

    def _rotation(self, r: int) -> np.ndarray:
        """(cos, sin) at the start of every tick 0 .. n_ticks of rotation group ``r``
        (:meth:`rotations`' numbers), kept for the next group of the same rotation group (groups
        of one body's spin come one after another: one table at a time)."""
        kept = getattr(self, "_rot_kept", None)
        if kept is not None and kept[0] == r:
            return kept[1]
        table = np.empty((self.n_ticks + 1, 2))
        self._spin(float(self.omegas[r]), 0, table)
        self._rot_kept = (r, table)
        return table

    def step(self, progress: Callable[[int], None] | None = None,
             stop: Callable[[], bool] | None = None) -> int:
        """Step every case to the end (or until ``stop()``, checked between blocks); returns the
        last tick reached by every case.

        Group by group (its cases share the scene record, the terrain and the body's angle),
        blocks of ticks by sim.step.step_ticks, as record and replay step a scenario: the commands
        applied before the tick they are for, a ship at a fixed point of the step (a still body)
        given its state and telemetry again rather than stepped (sim.step.Resting); each block
        then folded into the cases' reductions (:func:`_fold_block`)."""
        n = len(self.cases)
        if n == 0:
            return self.n_ticks
        bounds = self.bounds()
        ticks = []
        for g, (lo, hi) in enumerate(bounds):
            ticks.append(self._step_group(g, lo, hi, progress, stop))
            if ticks[-1] < self.n_ticks:
                break
        # the groups not started are at tick 0 (an interrupted part is reported missing whole:
        # run_part's ``done``)
        reached = min(ticks) if len(ticks) == len(bounds) else 0
        rot = self.rotations(reached, 0)
        _energy_into(self.scenes, self.terrains, self.group, self.rot_index, rot[:, 0, :],
                     self.ships, self.state, self.acc, True)
        self.last_tick = reached
        return reached

    def _step_group(self, g: int, lo: int, hi: int, progress, stop) -> int:
        """Group ``g``'s ships (rows lo..hi-1) to the end, or until ``stop()``; the tick reached."""
        n_g = hi - lo
        recs = Records(self.scenes[g:g + 1], self.terrains[g:g + 1], self.ships[lo:hi])
        state, inputs, acc = self.state[lo:hi], self.inputs[lo:hi], self.acc[lo:hi]
        r = int(self.rot_index[lo])
        on = bool(self.omegas[r] == 0.0)
        rotation = self._rotation(r)
        table = self.commands
        if len(table):
            mine = (table["ship"] >= lo) & (table["ship"] < hi)
            table = table[mine]  # (a copy) sorted by tick, then ship, as the whole
            table["ship"] -= lo
        # transitions a tick can make (sim.step.tick_capacity, for these ships)
        cap = int(np.sum(2 * recs.ships["n_substeps"] + 3))
        size = max(1, BLOCK_SHIP_TICKS // n_g)
        kept = None
        tick, c = 0, 0
        while tick < self.n_ticks:
            if stop is not None and stop():
                break
            k = min(size, self.n_ticks - tick)
            states = np.empty((k, n_g), STATE_DTYPE)
            outputs = np.empty((k, n_g), OUTPUTS_DTYPE)
            ins = np.empty((k, n_g), INPUTS_DTYPE)
            events = np.empty(cap * min(k, 16), TRANSITION_DTYPE)
            event_ticks = np.empty(events.shape[0], np.int64)
            count = np.zeros(1, np.int64)
            kept = resting(n_g, state, inputs, outputs, on, kept)
            before = state.copy()
            rot = rotation[tick:tick + k + 1]
            done, c = step_ticks(recs, state, inputs, Queue(table, c), Span(tick, rot),
                                 Written(states, outputs, ins, events, event_ticks, count, kept),
                                 cap)
            _fold_block(before, states[:done], outputs[:done], recs.ships, rot, events,
                        event_ticks, int(count[0]), self.dt_s, acc)
            tick += done
            if progress is not None:
                progress(done * n_g)
        return tick

    def columns(self) -> dict[str, np.ndarray]:
        """The table's result columns, in case order within this part (SPEC.md section 6)."""
        acc, st = self.acc, self.state
        final = st["surface_state"].astype(np.int8)
        t_out = np.where(acc["last_to"] == final, acc["t_last_s"], np.nan)
        # a ship that starts landed or tipped and stays so entered its state at 0
        t_out = np.where((acc["last_to"] == -1) & (final == self.initial_state)
                         & np.isin(final, (2, 3, 4)), 0.0, t_out)
        # flying and contact have no instant of outcome
        t_out = np.where(np.isin(final, (0, 1)), np.nan, t_out)
        # as export computes tilt_deg (sim.trig's acos: the same bits on every machine)
        tilt = derived.tilt_deg(acc["min_cos_tilt"])
        return {"case": self.cases, "state": final, "t_outcome": t_out, "max_tilt_deg": tilt,
                "max_penetration": np.maximum(acc["max_penetration_m"], 0.0),
                "peak_normal_force": acc["peak_normal_n"], "slide_distance": acc["slide_m"],
                "energy_dissipated_j": acc["e0_j"] - acc["e1_j"],
                "fuel_used": self.fuel0 - st["fuel_kg"]}


def run_part(sw: Sweep, cases: Sequence[int], progress=None, stop=None) -> dict[str, np.ndarray]:
    """Build and step cases ``cases`` of ``sw``; their columns (``done`` False where not stepped
    to the end)."""
    fleet = Fleet.build(sw, cases)
    last = fleet.step(progress, stop)
    cols = fleet.columns()
    cols["done"] = np.full(len(fleet.cases), last >= fleet.n_ticks)
    return cols


# -- the sweep's own compiled code -----------------------------------------------------------------
#: The kernels of its own a sweep calls from Python: its reductions, a few seconds of CPU once
#: after an install or a change to sim/. The step is record's (sim.step.step_ticks), which
#: `touchdown warm` compiles.
SWEEP_KERNELS = (_fold_block, _observe_into, _energy_into)


def kernels_ready() -> bool:
    """Whether the sweep's kernels are in the on-disk cache (their first call loads them)."""
    return all(in_cache(k) for k in (step_ticks, observe_ships, *SWEEP_KERNELS))


def ready() -> float:
    """Compile (or load) the sweep's kernels in this process: two cases of the built-in envelope
    scene for one tick. Under an exclusive lock in the kernel cache, so that processes that
    start together (a sweep's workers, a machine's Dask workers, two sweeps) compile them once:
    the others wait, then load them. Returns the seconds it took."""
    import fcntl
    import time
    import tomllib

    from touchdown import scenarios
    from touchdown.sweep.cases import Axis
    t0 = time.perf_counter()
    doc = tomllib.loads(scenarios.text("envelope"))
    doc["duration"] = doc.get("sim", {}).get("dt", 0.05)
    sw = Sweep.of(doc, "envelope", [Axis("ships.initial.horizontal_speed", 0.0, 6.0)],
                  samples=2, seed=1)
    try:
        lock = open(cache_dir() / ".sweep-kernels.lock", "w")
    except OSError:  # no writable cache: numba compiles without caching anyway
        run_part(sw, [0, 1])
        return time.perf_counter() - t0
    with lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        run_part(sw, [0, 1])
    return time.perf_counter() - t0
