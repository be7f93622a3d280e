"""Work-precision benchmark: ``touchdown bench accuracy [--quick] [--out DIR]``.

For each method and tick, canonical scenes are run and compared with the independent references
of ``bench/reference.py`` (closed forms and tight-tolerance ``solve_ivp`` solutions):

    apex_12 / apex_20 / apex_45   first apex after a 12 / 20 / 45 m/s lunar impact
    apex_20_earth                 the same at 20 m/s under Earth's gravity (restitution depends on g)
    separation_45                 speed at which the feet leave the ground after the 45 m/s impact
    penetration_45                deepest penetration of the 45 m/s impact
    contact_20                    how long the 20 m/s impact's feet stay on the ground
    settle_20                     time from the start until a 20 m/s arrival lands (bounce, flight,
                                  absorbed re-contact, and the settle rule)
    slide                         resting position: where a 5 m/s slide stops (Coulomb on the
                                  sphere, ~ v^2 / 2 mu_k g; the ship's rotation frozen)
    topple                        time to tip over from 5 deg past the critical angle (pivot ODE)
    trip                          time for a 2 m/s touchdown with 6 m/s sideways to trip over its
                                  leading feet (the planar rigid lander on four feet, Radau;
                                  mu_s = mu_k, as the reference has)
    righting                      time for the RCS to right a lander lying at 90 deg (pivot ODE)

Errors are relative. The apex and the contact's ends are read from the recorded state exactly
(energy in point-mass gravity, ballistic extrapolation to the ground), not from tick samples, so
that an exact method shows as exact; event times (settle, topple, righting) are tick times, as a
user sees them.

Cost is the CPU time one ship costs per simulated second (:func:`per_ship_cost`): the run's ticks
stepped for ``batch`` identical ships by the compiled loop, divided by them. That is the per-ship
work a method does (what the live service pays per ship). MuJoCo's curve on the bounce measures
(``bench/mujoco_side.bounce_run``: the same lander, four sphere feet whose solref is the seed's
spring-damper) is measured against the closed form in uniform gravity, its cost one lander through
``mujoco.rollout``.
Writes ``work_precision.png`` (one panel per measure, one curve per configuration),
``work_precision.csv`` and ``work_precision.md`` into ``--out``. Methods are run plain (one step
per tick, the stability guard off) so that each curve is the method itself; the configurations
marked "+ sub-steps" are as a scenario runs them by default (contact sub-steps of
``max_substep``), and the default configuration is drawn as stars.
"""
from __future__ import annotations

import csv
import math
import os
import time
from dataclasses import dataclass

import numpy as np

from touchdown.bench.reference import (bounce_ode, critical_angle_rad, planar_touchdown,
    righting_time, settle_time, topple_time)
from touchdown.bench.speed import machine
from touchdown.sim.constants import EARTH_GM_M3PS2, EARTH_RADIUS_M, MOON_GM_M3PS2, MOON_RADIUS_M
from touchdown.sim.enums import EventKind
from touchdown.sim.params import ContactParams, SimParams
from touchdown.sim.run import run, run_blocks
from touchdown.sim.scenario import parse

PLAIN = ["explicit_euler", "semi_implicit_euler", "velocity_verlet", "rk4", "exponential"]
SEED = "semi_implicit_euler"
DEFAULT_SIM = SimParams()
DEFAULT = f"{DEFAULT_SIM.integrator} + sub-steps (default)"
H_COM, A_LEG, MASS = 3.0, 2.26, 10000.0  # the default ship
MEASURES = ["apex_12", "apex_20", "apex_45", "apex_20_earth", "separation_45", "penetration_45",
            "contact_20", "settle_20", "slide", "topple", "trip", "righting"]


@dataclass(frozen=True)
class Body:
    gm: float
    radius: float

    @property
    def g(self) -> float:
        return self.gm / self.radius ** 2

    def doc(self) -> dict:
        return {"gm": self.gm, "radius": self.radius}


MOON = Body(MOON_GM_M3PS2, MOON_RADIUS_M)
EARTH = Body(EARTH_GM_M3PS2, EARTH_RADIUS_M)


def _doc(initial: dict, sim: dict, duration: float, batch: int, body: Body = MOON,
         ship: dict | None = None, contact: dict | None = None, inputs: list | None = None) -> dict:
    ships = [{"id": f"s{i}", **(ship or {}), "initial": initial, "inputs": inputs or []}
             for i in range(batch)]
    return {"name": "accuracy", "duration": duration, "sim": sim, "contact": contact or {},
            "body": body.doc(), "ships": ships}


#: ticks of a run sampled for timing, and how often each sampled step is timed (alone and in the
#: batch, alternately; the fastest of each is kept: a step timed once is mostly noise). Wall-clock
#: time on an otherwise idle machine: the process CPU clock is too coarse here for one step.
TIMED_REPEATS = 3


def per_ship_cost(doc: dict, n_ticks: int) -> float:
    """CPU seconds one ship costs per simulated second in this run: ``len(doc["ships"])``
    identical ships stepped together for the run's ``n_ticks`` ticks by the compiled loop (no log),
    the fastest of TIMED_REPEATS, divided by the ships and the simulated time. Identical ships
    do identical work, so this is the per-ship work of the method (what the live service pays
    per ship), the interpreter's share spread over the batch."""
    many = parse(doc, "accuracy")
    n_ticks = max(1, n_ticks)
    next(iter(run_blocks(many, last_tick=1)))  # kernels loaded before timing
    best = math.inf
    for _ in range(TIMED_REPEATS):
        t0 = time.process_time()
        for _block in run_blocks(many, last_tick=n_ticks):
            pass
        best = min(best, time.process_time() - t0)
    return best / len(doc["ships"]) / (n_ticks * many.params.sim.dt_s)


def _timed(doc: dict, stop=None):
    """Run ``doc``'s first ship alone; returns (scenario, its records, the CPU s per ship per
    simulated s). ``stop(records)`` ends the run once it has what
    it needs."""
    scn = parse({**doc, "ships": doc["ships"][:1]}, "accuracy")
    recs = []
    for rec in run(scn):
        recs.append(rec)
        if stop is not None and stop(recs):
            break
    cost = per_ship_cost(doc, len(recs) - 1)
    return scn, recs, cost


def _events(recs) -> list[tuple[int, EventKind, float]]:
    return [(r.tick, EventKind(e.kind), e.v_radial_mps) for r in recs for e in r.events if e.ship == 0]


def _touch_radius(body: Body) -> float:
    """Centre-of-mass radius at which an upright lander's feet (on a circle of A_LEG) touch."""
    return math.sqrt(body.radius ** 2 - A_LEG ** 2) + H_COM


def _radial(rec) -> tuple[float, float]:
    p, v = rec.state.pos_m[0], rec.state.vel_mps[0]
    r = float(np.linalg.norm(p))
    return r, float(np.dot(v, p)) / r


def _fall_time(body: Body, height: float, v_up: float) -> float:
    """Time for a ballistic ship ``height`` above the touch radius, rising at v_up, to reach it
    (v_up < 0: falling) under the local g; going back in time when v_up > 0 is asked by the
    caller with its sign flipped."""
    g = body.g
    return (v_up + math.sqrt(v_up * v_up + 2.0 * g * height)) / g


def bounce(sim: dict, v0: float, body: Body, batch: int) -> tuple[float, dict[str, float]]:
    """The first bounce of a vertical impact at v0 from 0.3 m: its errors and cost."""
    alt0 = 0.3

    lifted = []

    def after_liftoff(recs):  # the first state with the feet clear after the liftoff
        lifted.extend(k == EventKind.LIFTOFF for _, k, _ in _events(recs[-1:]))
        return any(lifted) and recs[-1].outputs.altitude_m[0] > 0.0

    scn, recs, cost = _timed(_doc({"altitude": alt0, "vertical_speed": -v0}, sim, 2 * v0 / body.g,
                                  batch, body), after_liftoff)
    ev = _events(recs)
    if len(ev) < 2 or ev[0][1] != EventKind.CONTACT or ev[1][1] != EventKind.LIFTOFF:
        return cost, {}
    r_touch = _touch_radius(body)
    r0, u0 = _radial(recs[0])
    v_imp = math.sqrt(u0 * u0 + 2.0 * body.gm * (1.0 / r_touch - 1.0 / r0))
    ref = bounce_ode(body.gm, body.radius, v_imp, com_height_m=H_COM)
    dt = scn.params.sim.dt_s
    (t_c, _, _), (t_l, _, v_sep) = ev[0], ev[1]
    # the apex from the first clear state after liftoff: energy in point-mass gravity
    r, u = _radial(recs[-1])
    r_apex = 1.0 / (1.0 / r - u * u / (2.0 * body.gm))
    # the contact's ends: ballistic from the last clear state before it and back from the first after
    rb, ub = _radial(recs[t_c - 1])
    t_in = (t_c - 1) * dt + _fall_time(body, rb - r_touch, ub)
    t_out = recs[-1].tick * dt - _fall_time(body, r - r_touch, -u)
    peak = max(float(rec.outputs.peak_penetration_m[0]) for rec in recs[t_c:t_l + 1])
    return cost, {"apex": abs((r_apex - r_touch) / ref.apex_m - 1),
                  "separation": abs(v_sep / ref.separation_speed_mps - 1),
                  "penetration": abs(peak / ref.max_penetration_m - 1),
                  "contact": abs((t_out - t_in) / ref.contact_duration_s - 1)}


def _event_time(doc: dict, kind: EventKind) -> tuple[float, float, list]:
    """Run ``doc`` until its first ship's first ``kind`` event: (cost, the event's tick time or
    nan, the records)."""
    def reached(recs):
        return any(k == kind for _, k, _ in _events(recs[-1:]))

    scn, recs, cost = _timed(doc, reached)
    ticks = [t for t, k, _ in _events(recs) if k == kind]
    return cost, ticks[0] * scn.params.sim.dt_s if ticks else float("nan"), recs


def settle(sim: dict, v0: float, batch: int) -> tuple[float, float]:
    alt0 = 0.3
    r_touch = _touch_radius(MOON)
    doc = _doc({"altitude": alt0, "vertical_speed": -v0}, sim, 2.5 * v0 / MOON.g + 3.0, batch)
    cost, t_landed, recs = _event_time(doc, EventKind.LANDED)
    r0, u0 = _radial(recs[0])
    v_imp = math.sqrt(u0 * u0 + 2.0 * MOON.gm * (1.0 / r_touch - 1.0 / r0))
    ref, _ = settle_time(MOON.gm, MOON.radius, v_imp, com_height_m=H_COM)
    ref += _fall_time(MOON, r0 - r_touch, u0)
    return cost, abs(t_landed / ref - 1)


def slide(sim: dict, batch: int) -> tuple[float, float]:
    """Where a 5 m/s slide comes to rest. The ship's rotation is frozen (a huge inertia): a real
    lander pitches forward as it brakes (friction acts at its feet, 3 m below its centre of
    mass), which moves its normal force about and its stopping point by ~1e-3 in a way that no
    closed form follows. Frozen, it is Coulomb's slide on the sphere: the normal force is
    m (g - v^2 / r), so the distance is -(r / 2 mu_k) ln(1 - v0^2 / (g r)) (-> v0^2 / 2 mu_k g)."""
    v0, mu_k = 5.0, ContactParams().friction_kinetic
    doc = _doc({"state": "contact", "altitude": -MOON.g / 100.0, "horizontal_speed": v0}, sim,
               v0 / (mu_k * MOON.g) + 2.0, batch, contact={"settle_linear_vel": 1e-3},
               ship={"inertia": [1e15, 1e15, 1e15]})
    scn, recs, cost = _timed(doc)
    p0 = recs[0].state.pos_m[0]
    r = float(np.linalg.norm(p0))
    g = MOON.gm / (r * r)
    arc = max(float(np.linalg.norm(rec.state.pos_m[0] - p0)) for rec in recs)
    ref = -(r / (2.0 * mu_k)) * math.log1p(-v0 * v0 / (g * r))
    return cost, abs(arc / ref - 1)


def _i_transverse() -> float:
    """The default inertia (sim/scenario.py): a uniform cylinder of radius a, length 2 h."""
    return MASS * (3 * A_LEG * A_LEG + (2 * H_COM) ** 2) / 12.0


def topple(sim: dict, batch: int) -> tuple[float, float]:
    th0 = critical_angle_rad(H_COM, A_LEG) + math.radians(5.0)
    doc = _doc({"state": "contact", "altitude": -MOON.g / 100.0, "tilt_deg": math.degrees(th0)},
               sim, 8.0, batch)
    cost, t_tipped, _ = _event_time(doc, EventKind.TIPPED)
    ref = topple_time(MOON.g, MASS, _i_transverse(), H_COM, A_LEG, th0, math.radians(80.0))
    return cost, abs(t_tipped / ref - 1)


def trip(sim: dict, batch: int) -> tuple[float, float]:
    """Friction at the feet pitches a fast sideways touchdown over its leading feet; the rotation
    it causes meets the feet's restoring moment half a sub-step late (MODEL-NOTES 32), so this is
    where the sub-step shows."""
    v_side, mu = 6.0, ContactParams().friction_kinetic
    v_down = math.sqrt(2.0 ** 2 + 2.0 * MOON.g * 0.2)
    doc = _doc({"altitude": 0.2, "vertical_speed": -2.0, "horizontal_speed": v_side,
                "heading_deg": 90.0}, sim, 6.0, batch, contact={"friction_static": mu})
    cost, t_tipped, _ = _event_time(doc, EventKind.TIPPED)
    g = MOON.gm / (MOON.radius + H_COM) ** 2
    t_tip, _, _ = planar_touchdown(v_side, v_down, g, t_end_s=6.0)
    return cost, abs(t_tipped / (t_tip + (v_down - 2.0) / MOON.g) - 1)


def righting(sim: dict, batch: int) -> tuple[float, float]:
    tau = 80000.0
    # rcs_isp at its largest (1e5 s): the RCS burns 0.3 kg in 8 s, 3e-5 of the mass the reference
    # holds fixed (the measure is good to a tick, 1e-2, anyway)
    doc = _doc({"state": "tipped", "tilt_deg": 90.0}, sim, 8.0, batch,
               ship={"max_rcs_torque": tau, "rcs_isp": 1e5},
               inputs=[{"t": 0.0, "rcs": [0.0, -1.0, 0.0]}])
    cost, t_righted, _ = _event_time(doc, EventKind.RIGHTED)
    ref = righting_time(MOON.g, MASS, _i_transverse(), H_COM, A_LEG, tau, math.radians(90.0),
                        math.radians(80.0))
    return cost, abs(t_righted / ref - 1)


def configs(quick: bool) -> list[tuple[str, float, dict]]:
    dts = [0.01, 0.05, 0.1] if quick else [0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2]
    out = [(m, dt, {"integrator": m, "dt": dt, "max_substep": 0.0, "on_unstable": "allow",
                    "energy_guard": False})
           for m in PLAIN for dt in dts]
    subbed = [dt for dt in dts if dt >= 0.02] or dts
    out += [("rk4 + sub-steps", dt, {"integrator": "rk4", "dt": dt}) for dt in subbed]
    out += [(DEFAULT, dt, {"integrator": DEFAULT_SIM.integrator, "dt": dt}) for dt in subbed]
    return out


def bounce_measures(one) -> dict[str, tuple[float, float]]:
    """The bounce measures (:data:`BOUNCE_MEASURES`) as (relative error, cost), from
    ``one(v0, body) -> (cost, errors by kind)`` run for each impact."""
    nan = float("nan")
    found = {}
    for name, v0, body in (("12", 12.0, MOON), ("20", 20.0, MOON), ("45", 45.0, MOON),
                           ("20_earth", 20.0, EARTH)):
        cost, err = one(v0, body)
        found["apex_" + name] = (err.get("apex", nan), cost)
        if name == "45":
            found["separation_45"] = (err.get("separation", nan), cost)
            found["penetration_45"] = (err.get("penetration", nan), cost)
        if name == "20":
            found["contact_20"] = (err.get("contact", nan), cost)
    return found


def sweep(quick: bool, batch: int) -> list[dict]:
    rows = []
    for label, dt, sim in configs(quick):
        found: dict[str, tuple[float, float]] = {}
        with np.errstate(all="ignore"):
            found.update(bounce_measures(lambda v0, body: bounce(sim, v0, body, batch)))
            cost, err = settle(sim, 20.0, batch)
            found["settle_20"] = (err, cost)
            for name, fn in (("slide", slide), ("topple", topple), ("trip", trip),
                             ("righting", righting)):
                cost, err = fn(sim, batch)
                found[name] = (err, cost)
        for measure in MEASURES:
            err, cost = found[measure]
            rows.append({"measure": measure, "method": label, "dt_s": dt, "relative_error": err,
                         "cpu_s_per_ship_sim_s": cost})
        print(f"  {label:<34} dt {dt:<6g} " + " ".join(
            f"{m} {found[m][0]:.1e}" for m in ("apex_20", "apex_45", "settle_20", "slide",
                                               "topple")), flush=True)
    return rows


BOUNCE_MEASURES = ("apex_12", "apex_20", "apex_45", "apex_20_earth", "separation_45",
                   "penetration_45", "contact_20")


def mujoco_label() -> str | None:
    try:
        import mujoco
    except ImportError:
        return None
    return f"MuJoCo {mujoco.__version__} (Euler)"


def mujoco_sweep(quick: bool) -> list[dict]:
    """MuJoCo's curve on the bounce measures (bench/mujoco_side.bounce_run: the same lander,
    solref the seed's spring-damper, flat ground, uniform gravity), against the closed form in
    uniform gravity (bench.reference.bounce_closed_form); empty without mujoco."""
    label = mujoco_label()
    if label is None:
        return []
    from touchdown.bench.mujoco_side import bounce_run
    from touchdown.bench.reference import bounce_closed_form

    rows = []
    dts = [0.002, 0.01, 0.05] if quick else [0.001, 0.002, 0.005, 0.01, 0.02, 0.05]
    for dt in dts:
        def one(v0, body):
            g = body.g
            m, cost = bounce_run(v0, g, dt)
            ref = bounce_closed_form(g, math.sqrt(v0 * v0 + 2.0 * g * 0.3))
            return cost, {} if m is None else {
                "apex": abs(m["apex"] / ref.apex_m - 1),
                "separation": abs(m["separation"] / ref.separation_speed_mps - 1),
                "penetration": abs(m["penetration"] / ref.max_penetration_m - 1),
                "contact": abs(m["contact"] / ref.contact_duration_s - 1)}

        found = bounce_measures(one)
        for measure in BOUNCE_MEASURES:
            err, cost = found[measure]
            rows.append({"measure": measure, "method": label, "dt_s": dt, "relative_error": err,
                         "cpu_s_per_ship_sim_s": cost})
        print(f"  {label:<34} dt {dt:<6g} apex_20 {found['apex_20'][0]:.1e} apex_45 "
              f"{found['apex_45'][0]:.1e}", flush=True)
    return rows


def mujoco_at_one_percent(rows: list[dict]) -> list[str]:
    """The issue's aim: at <= 1% first-apex error (apex_20), simulated seconds per CPU second for
    one lander, Touchdown's default tick against MuJoCo's cheapest step that reaches it."""
    label = mujoco_label()
    mj = [r for r in rows if r["method"] == label and r["measure"] == "apex_20"
          and r["relative_error"] <= 0.01]
    td = [r for r in rows if r["method"] == DEFAULT and r["measure"] == "apex_20"
          and abs(r["dt_s"] - DEFAULT_SIM.dt_s) < 1e-12]
    if not mj or not td:
        return []
    best = min(mj, key=lambda r: r["cpu_s_per_ship_sim_s"])
    ours = td[0]
    ratio = best["cpu_s_per_ship_sim_s"] / ours["cpu_s_per_ship_sim_s"]
    return [f"at <= 1% first-apex error (20 m/s): Touchdown's default (dt {ours['dt_s']:g} s, "
            f"error {ours['relative_error']:.1e}) {1 / ours['cpu_s_per_ship_sim_s']:,.0f} "
            f"simulated s per CPU s; {label} at dt {best['dt_s']:g} s (error "
            f"{best['relative_error']:.1e}) {1 / best['cpu_s_per_ship_sim_s']:,.0f}: {ratio:.1f}x"]


def front(rows: list[dict], measure: str) -> set[tuple[str, float]]:
    """The configurations on the work-precision front of ``measure``: none other is both
    cheaper and more accurate. An error below 1e-9 counts as exact (rounding and the
    references' own tolerance), and two errors within 1% of each other as equal (the same
    answer, rounded differently)."""
    pts = [(r["cpu_s_per_ship_sim_s"], max(r["relative_error"], 1e-9), (r["method"], r["dt_s"]))
           for r in rows if r["measure"] == measure and math.isfinite(r["relative_error"])]
    return {k for c, e, k in pts
            if not any(c2 < c and e2 < 0.99 * e for c2, e2, _ in pts)}


def ten_hz_summary(rows: list[dict]) -> list[str]:
    """The issue's aim at the live service's 10 Hz tick: the first bounce of 20-45 m/s impacts."""
    out = []
    for label in (SEED, "exponential", DEFAULT):
        sel = [r for r in rows if r["method"] == label and abs(r["dt_s"] - 0.1) < 1e-12
               and r["measure"] in ("apex_20", "apex_45", "separation_45", "penetration_45",
                                    "contact_20")]
        if not sel:
            continue
        worst = max(r["relative_error"] for r in sel)
        cost = float(np.mean([r["cpu_s_per_ship_sim_s"] for r in sel]))
        out.append(f"{label} at 10 Hz: worst first-bounce error {worst:.1e}, "
                   f"cost {cost * 1e6 / 10:.2f} us per ship-tick")
    return out


def write(rows: list[dict], out_dir: str, batch: int) -> list[str]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(out_dir, exist_ok=True)
    with open(os.path.join(out_dir, "work_precision.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    methods = list(dict.fromkeys(r["method"] for r in rows))
    on_front = {m: front(rows, m) for m in MEASURES}
    default_dt = DEFAULT_SIM.dt_s
    verdict = [f"{m}: {'on' if (DEFAULT, default_dt) in on_front[m] else 'OFF'} the front"
               for m in MEASURES]
    summary = ten_hz_summary(rows) + mujoco_at_one_percent(rows)
    with open(os.path.join(out_dir, "work_precision.md"), "w") as f:
        f.write(f"Relative error against the references (`bench/reference.py`); cost: CPU time "
                f"per ship (the run's ticks stepped for {batch} identical ships by the compiled "
                f"loop, divided by them; MuJoCo: one lander through mujoco.rollout), in "
                f"microseconds per ship-tick and in CPU seconds per ship per simulated second. "
                f"Machine: {machine()}.\n\n")
        f.write("Default (" + DEFAULT + f", dt {default_dt:g} s): "
                + "; ".join(verdict) + ".\n\n")
        for line in summary:
            f.write(f"- {line}\n")
        f.write("\n| method | dt (s) | us / ship-tick | CPU s / ship / sim s | "
                + " | ".join(MEASURES) + " |\n")
        f.write("|---|---|---|---|" + "---|" * len(MEASURES) + "\n")
        for m in methods:
            for dt in sorted({r["dt_s"] for r in rows if r["method"] == m}):
                sel = {r["measure"]: r for r in rows if r["method"] == m and r["dt_s"] == dt}
                cost = float(np.mean([r["cpu_s_per_ship_sim_s"] for r in sel.values()]))
                cells = [("" if x not in sel else "failed"
                          if not math.isfinite(sel[x]["relative_error"])
                          else f"{sel[x]['relative_error']:.1e}") for x in MEASURES]
                f.write(f"| {m} | {dt:g} | {cost * dt * 1e6:.2f} | {cost:.2e} | "
                        + " | ".join(cells) + " |\n")
    cols = 4
    fig, axes = plt.subplots(math.ceil((len(MEASURES) + 1) / cols), cols, figsize=(18, 12), dpi=90)
    colours = {m: f"C{i}" for i, m in enumerate(methods)}
    for ax, measure in zip(axes.flat, MEASURES):
        for m in methods:
            pts = sorted((r["cpu_s_per_ship_sim_s"], max(r["relative_error"], 1e-10), r["dt_s"])
                         for r in rows if r["measure"] == measure and r["method"] == m
                         and math.isfinite(r["relative_error"]))
            if not pts:
                continue
            x, y, dts = zip(*pts)
            if m == mujoco_label():
                ax.loglog(x, y, "s--", color="black", lw=1.5, ms=5, label=m)
            elif m == DEFAULT:
                ax.loglog(x, y, "-", color=colours[m], lw=2.5, label=m)
                ax.loglog(x, y, "*", color=colours[m], ms=13)
                for xi, yi, d in zip(x, y, dts):
                    if abs(d - default_dt) < 1e-12:
                        ax.annotate(f"default, dt {d:g}", (xi, yi), textcoords="offset points",
                                    xytext=(6, 6), fontsize=8)
            else:
                ax.loglog(x, y, "o-", color=colours[m], lw=1.2, ms=4, label=m)
        ax.axhline(1e-3, color="grey", ls=":", lw=1)
        ax.set_title(measure)
        ax.set_xlabel("CPU s per ship per simulated s")
        ax.set_ylabel("relative error")
        ax.grid(True, which="major", alpha=0.3)
    legend_ax = list(axes.flat)[len(MEASURES)]
    handles, labels = axes.flat[0].get_legend_handles_labels()
    legend_ax.legend(handles, labels, loc="center", fontsize=10)
    legend_ax.axis("off")
    for ax in list(axes.flat)[len(MEASURES) + 1:]:
        ax.axis("off")
    fig.suptitle("Touchdown work-precision: error against cost, the tick swept from 2 ms to "
                 "0.2 s; MuJoCo's curve (black, dashed) on the bounce measures (dotted: 0.1%; "
                 "errors below 1e-10 drawn at 1e-10)")
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "work_precision.png"))
    return verdict + summary


def rewrite(out_dir: str = "docs", batch: int = 256) -> None:
    """The chart and the tables again from ``out_dir``'s work_precision.csv (no new runs)."""
    with open(os.path.join(out_dir, "work_precision.csv")) as f:
        rows = [{**r, "dt_s": float(r["dt_s"]), "relative_error": float(r["relative_error"]),
                 "cpu_s_per_ship_sim_s": float(r["cpu_s_per_ship_sim_s"])}
                for r in csv.DictReader(f)]
    for line in write(rows, out_dir, batch):
        print(line)


def main(quick: bool = False, out_dir: str = "docs", batch: int | None = None) -> None:
    batch = batch or (64 if quick else 256)
    print(f"machine: {machine()}; batches of {batch} ships")
    rows = sweep(quick, batch) + mujoco_sweep(quick)
    for line in write(rows, out_dir, batch):
        print(line)
    print(f"wrote {out_dir}/work_precision.png, .csv and .md")


if __name__ == "__main__":
    main()
