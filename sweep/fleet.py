"""The cases as one fleet: every case a ship, stepped by the compiled tick (sim.phases.step_ship),
each ship with its own scene record and terrain (a case may change the contact model, the body or
the slope), and its outcome reduced as it goes: nothing of a tick is kept past it.

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

from touchdown.sim.compiled import cache_dir, in_cache, separate
from touchdown.sim.contact import Legs
from touchdown.sim.dynamics import Motion
from touchdown.sim.energy import mechanical, total
from touchdown.sim.frames import Body, body_rotation
from touchdown.sim.params import SCENE_DTYPE, Records
from touchdown.sim.state import (COMMAND_DTYPE, OUTPUTS_DTYPE, STATE_DTYPE, TRANSITION_DTYPE,
    concatenate)
from touchdown.sim.ship import CONTACT, Turn, scene_ground
from touchdown.sim.step import apply_commands, observe_ships, step_ships
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

#: Ship-ticks per compiled call: about a tenth of a second of stepping, so that Ctrl-C and the
#: progress bar answer promptly.
BLOCK_SHIP_TICKS = 200_000


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
def sweep_ticks(scenes, terrains, group, rot_index, rot, ships, state, inputs, commands,
                next_command, first_tick, n_ticks, dt_s, outs, events, count, acc, raw, scratch,
                still, last_command, frozen):
    """Ticks ``first_tick`` .. ``first_tick + n_ticks - 1`` of the fleet, each ship's by
    sim.phases.step_ship with its group's scene and terrain and its rotation group's body angle
    (``rot[r, k]``: (cos, sin) at the start of the k-th tick), reduced into ``acc``. Commands
    (sorted by tick, from ``next_command``) are applied before the tick they are for, as
    sim.step.step_ticks applies them. Returns the index of the next command."""
    c = next_command
    for k in range(n_ticks):
        tick = first_tick + k
        c = apply_commands(commands, c, tick, inputs)
        t_end = (tick + 1) * dt_s
        for i in range(state.shape[0]):
            if frozen[i]:
                continue
            g = group[i]
            r = rot_index[i]
            rec = state[i]
            row = raw[i]
            for b in range(row.shape[0]):
                scratch[b] = row[b]
            sp = ships[i]
            before = rec.surface_state
            c0, s0, c1, s1 = rot[r, k, 0], rot[r, k, 1], rot[r, k + 1, 0], rot[r, k + 1, 1]
            f0 = _footprint_bf((rec.pos_m[0], rec.pos_m[1], rec.pos_m[2]),
                               (rec.quat[0], rec.quat[1], rec.quat[2], rec.quat[3]),
                               sp.com_height_m, c0, s0)
            count[0] = 0
            # the tick of record and replay (sim.step.step_ships, already compiled for them),
            # on this one ship with its own scene
            step_ships(Records(scenes[g:g + 1], terrains[g:g + 1], ships[i:i + 1]),
                       state[i:i + 1], inputs[i:i + 1], outs[i:i + 1], Turn(c0, s0, c1, s1),
                       events, count)
            a = acc[i]
            _fold_outputs(outs[i], a)
            if before == CONTACT and rec.surface_state == CONTACT:
                f1 = _footprint_bf((rec.pos_m[0], rec.pos_m[1], rec.pos_m[2]),
                                   (rec.quat[0], rec.quat[1], rec.quat[2], rec.quat[3]),
                                   sp.com_height_m, c1, s1)
                d = (f1[0] - f0[0], f1[1] - f0[1], f1[2] - f0[2])
                n2 = f1[0] * f1[0] + f1[1] * f1[1] + f1[2] * f1[2]
                along = (d[0] * f1[0] + d[1] * f1[1] + d[2] * f1[2]) / math.sqrt(n2)
                tang2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - along * along
                if tang2 > 0.0:
                    a.slide_m = a.slide_m + math.sqrt(tang2)
            for e in range(min(count[0], events.shape[0])):
                ev = events[e]
                # sim.step.transitions: at n dt - (dt - t_offset) for the step into tick n
                a.t_last_s = t_end - (dt_s - ev.t_offset_s)
                a.last_to = ev.to_state
            # a fixed point: the state came back bit for bit, on a body that does not turn,
            # with no command to come: every later tick is this one again (the same state,
            # telemetry and no transition), so the reductions have seen all they will see
            if count[0] == 0 and still[r] and last_command[i] <= tick:
                same = True
                for b in range(row.shape[0]):
                    if row[b] != scratch[b]:
                        same = False
                        break
                if same:
                    frozen[i] = True
    return c


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
            if om == 0.0:
                out[r, :, 0], out[r, :, 1] = 1.0, 0.0
            else:
                for j in range(k + 1):
                    out[r, j] = body_rotation(om, (first_tick + j) * self.dt_s)
        return out

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

    def step(self, progress: Callable[[int], None] | None = None,
             stop: Callable[[], bool] | None = None) -> int:
        """Step every case to the end (or until ``stop()``, checked between blocks); returns the
        last tick reached."""
        n = len(self.cases)
        if n == 0:
            return self.n_ticks
        cap = int(np.max(2 * self.ships["n_substeps"] + 3))
        events = np.empty(cap, TRANSITION_DTYPE)
        count = np.zeros(1, np.int64)
        outs = np.zeros(n, OUTPUTS_DTYPE)
        block = max(1, min(self.n_ticks, BLOCK_SHIP_TICKS // n))
        raw = self.state.view(np.uint8).reshape(n, self.state.dtype.itemsize)
        scratch = np.empty(self.state.dtype.itemsize, np.uint8)
        still = self.omegas == 0.0
        last_command = np.full(n, -1, np.int64)
        if len(self.commands):
            np.maximum.at(last_command, self.commands["ship"], self.commands["tick"])
        frozen = np.zeros(n, bool)
        tick, c = 0, 0
        while tick < self.n_ticks:
            if stop is not None and stop():
                break
            k = min(block, self.n_ticks - tick)
            rot = self.rotations(tick, k)
            c = sweep_ticks(self.scenes, self.terrains, self.group, self.rot_index, rot,
                            self.ships, self.state, self.inputs, self.commands, c, tick, k,
                            self.dt_s, outs, events, count, self.acc, raw, scratch, still,
                            last_command, frozen)
            tick += k
            if progress is not None:
                progress(k * n)
        rot = self.rotations(tick, 0)
        _energy_into(self.scenes, self.terrains, self.group, self.rot_index, rot[:, 0, :],
                     self.ships, self.state, self.acc, True)
        self.last_tick = tick
        self.frozen = frozen
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
        # libm's acos, as export computes tilt_deg (numpy's may differ in the last bit)
        tilt = np.array([math.degrees(math.acos(max(-1.0, min(1.0, c))))
                         for c in acc["min_cos_tilt"].tolist()])
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
#: The kernels a sweep calls from Python. Each is compiled as a whole with the step it calls
#: (sim.compiled: an entry point optimizes everything it calls), so the sweep's are a compile of
#: their own, beside record's and serve's that `touchdown warm` makes: ~2.5 minutes of CPU and
#: ~0.9 GB of memory on session 25's 2-core AMD EPYC, once after an install or a change to sim/.
SWEEP_KERNELS = (sweep_ticks, _observe_into, _energy_into)


def kernels_ready() -> bool:
    """Whether the sweep's kernels are in the on-disk cache (their first call loads them)."""
    return all(in_cache(k) for k in SWEEP_KERNELS)


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
