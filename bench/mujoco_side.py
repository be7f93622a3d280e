"""MuJoCo beside Touchdown: the same landers stepped by both, measured in one run, as ratios.

The lander in MuJoCo (4.0): one free body with the default ship's mass and inertia, four sphere feet
(radius 5 cm) where Touchdown's feet are ((+-a, 0, -h), (0, +-a, -h) from the centre of mass), a plane
for the ground, lunar gravity, dt 0.01 s. Each foot's contact has ``solref = (-K, -B)`` with
``K = k / m = stiffness_per_kg`` and ``B = c / m = 2 zeta sqrt(K)``: with the impedance near 1
(``solimp`` 0.9999) a contact's reference acceleration is ``-K x - B x'`` (MuJoCo's documentation,
"Solver parameters", negative solref), so an upright lander on four feet moves as the seed's one
spring-damper does (omega^2 = K, 2 zeta omega = B). Friction 0.5 (the seed's kinetic), condim 3.

Timing: MuJoCo runs through ``mujoco.rollout`` (its C loop; one thread: one MjData), Touchdown through
its own step; CPU time (``time.process_time``). Both simulate the same span: one lander bouncing at
20 m/s from 5 m and settling, 1,000 s (100,000 MuJoCo steps, 20,000 Touchdown ticks), and 10,000
landers arriving at 2-49 m/s from 0.5-30 m, 1 s (100 steps, 20 ticks).

Needs the ``bench`` extra (``pip install -e '.[bench]'``), which installs mujoco.
"""
from __future__ import annotations

import math
import tempfile
import time

import numpy as np

MOON_G = 4.9048695e12 / 1737400.0 ** 2  # GM / R^2 of sim.params.BodyParams' defaults, m/s^2
FOOT_RADIUS_M = 0.05


def lander_xml(mass_kg: float, inertia_kgm2, leg_radius_m: float, com_height_m: float,
               stiffness_per_kg: float, damping_ratio: float, dt_s: float = 0.01,
               friction: float = 0.5, gravity: float = MOON_G, integrator: str = "Euler") -> str:
    k = stiffness_per_kg
    b = 2.0 * damping_ratio * np.sqrt(k)
    a, h, r = leg_radius_m, com_height_m, FOOT_RADIUS_M
    feet = "\n".join(
        f'      <geom type="sphere" size="{r}" pos="{x} {y} {-h + r}" mass="0" '
        f'solref="{-k} {-b}" solimp="0.9999 0.9999 0.001 0.5 2" friction="{friction} 0.005 '
        f'0.0001" condim="3"/>' for x, y in ((a, 0), (0, a), (-a, 0), (0, -a)))
    ix, iy, iz = inertia_kgm2
    return f"""<mujoco model="touchdown-lander">
  <compiler inertiafromgeom="false"/>
  <option timestep="{dt_s}" gravity="0 0 {-gravity}" integrator="{integrator}"/>
  <worldbody>
    <geom type="plane" size="0 0 1" solref="{-k} {-b}" solimp="0.9999 0.9999 0.001 0.5 2"/>
    <body name="lander" pos="0 0 {h + 5.0}">
      <freejoint/>
      <inertial pos="0 0 0" mass="{mass_kg}" diaginertia="{ix} {iy} {iz}"/>
{feet}
    </body>
  </worldbody>
</mujoco>"""


def default_lander():
    """The MuJoCo model of the built-in bounce's lander, and the Touchdown scenario it copies."""
    import mujoco

    from touchdown import scenarios
    from touchdown.sim.scenario import parse_text

    scn = parse_text(scenarios.text("bounce"), "bounce")
    sh, cp = scn.params.ships, scn.params.contact
    xml = lander_xml(float(sh.mass0_kg[0]), sh.inertia0_kgm2[0], float(sh.leg_radius_m[0]),
                     float(sh.com_height_m[0]), float(sh.stiffness_per_kg[0]), cp.damping_ratio)
    return mujoco.MjModel.from_xml_string(xml), scn


def initial_states(model, heights_m, speeds_mps) -> np.ndarray:
    """Full physics states (mjSTATE_FULLPHYSICS) of landers whose feet are ``heights_m`` above the
    ground, falling at ``speeds_mps``."""
    import mujoco

    data = mujoco.MjData(model)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    out = np.empty((len(heights_m), mujoco.mj_stateSize(model, spec)))
    com_h = -model.geom_pos[1][2] + FOOT_RADIUS_M  # feet geoms follow the plane (geom 0)
    for i, (hgt, v) in enumerate(zip(heights_m, speeds_mps)):
        mujoco.mj_resetData(model, data)
        data.qpos[2] = com_h + hgt
        data.qvel[2] = -v
        mujoco.mj_getState(model, data, out[i], spec)
    return out


#: runs of the one-lander measures, the least taken on both sides: a recording's two threads (the
#: step's and the writer's) share this machine's two vCPUs, and its CPU time varies by a third from
#: run to run with how they overlap (261,000-403,000 ticks/s in one process, session 27); the least
#: of three was often the slow end
ONE_LANDER_REPEATS = 7


def _best(fn, repeats: int) -> float:
    best = float("inf")
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def mujoco_one_lander(n_steps: int = 100_000, repeats: int = ONE_LANDER_REPEATS) -> float:
    """Steps per CPU second, one lander bouncing at 20 m/s from 5 m and settling."""
    import mujoco
    from mujoco import rollout

    model, _ = default_lander()
    data = mujoco.MjData(model)
    x0 = initial_states(model, [5.0], [20.0])
    return n_steps / _best(lambda: rollout.rollout(model, data, x0, nstep=n_steps), repeats)


def mujoco_fleet(n_ships: int = 10_000, n_steps: int = 100, repeats: int = 3) -> float:
    """Lander-steps per CPU second, ``n_ships`` landers arriving at 2-49 m/s (one thread)."""
    import mujoco
    from mujoco import rollout

    model, _ = default_lander()
    data = mujoco.MjData(model)
    rng = np.random.default_rng(7)
    x0 = initial_states(model, rng.uniform(0.5, 30.0, n_ships), rng.uniform(2.0, 49.0, n_ships))
    return n_ships * n_steps / _best(
        lambda: rollout.rollout(model, data, x0, nstep=n_steps), repeats)


def _runner(scn, log_dir: str | None):
    """What is timed: the run stepped alone (its blocks made and dropped) or, with ``log_dir``,
    recorded as ``touchdown record`` does (the full MCAP log: encoding, compression and writing,
    on the writer's threads too, which process_time counts)."""
    from touchdown.sim.run import run_blocks
    next(iter(run_blocks(scn, last_tick=1)))  # the kernels loaded before timing
    if log_dir is None:
        def go():
            for _ in run_blocks(scn):
                pass
        return go
    import os
    from touchdown.service.driver import record

    def go_logged():
        record(scn, os.path.join(log_dir, "bench.mcap"), "bench")
    go_logged()  # the writer's kernels (the tick encoder) loaded, its modules imported
    return go_logged


def touchdown_one_lander(n_ticks: int = 100_000, repeats: int = ONE_LANDER_REPEATS,
                         log_dir: str | None = None) -> float:
    """Ticks per CPU second of the built-in bounce, stepped alone or with its full log."""
    from touchdown import scenarios
    from touchdown.sim.scenario import parse_text

    scn = parse_text(scenarios.text("bounce"), "bounce", {"duration": n_ticks * 0.05})
    return n_ticks / _best(_runner(scn, log_dir), repeats)


def touchdown_fleet(n_ships: int = 10_000, n_ticks: int = 100, repeats: int = 3,
                    log_dir: str | None = None) -> float:
    """Ship-ticks per CPU second, ``n_ships`` landers arriving at 2-49 m/s from 0.5-30 m,
    stepped alone or with their full log."""
    from touchdown.sim.scenario import parse

    rng = np.random.default_rng(7)
    ships = [{"id": f"s{i}", "initial": {"altitude": float(h), "vertical_speed": -float(v),
                                         "east": float(10.0 * i)}}
             for i, (h, v) in enumerate(zip(rng.uniform(0.5, 30.0, n_ships),
                                            rng.uniform(2.0, 49.0, n_ships)))]
    scn = parse({"name": "arrivals", "duration": n_ticks * 0.05, "ships": ships}, "bench")
    return n_ships * n_ticks / _best(_runner(scn, log_dir), repeats)


# -- the first bounce, against the closed form ------------------------------------------------------
def bounce_run(v0_mps: float, g_mps2: float, dt_s: float, height_m: float = 0.3,
               integrator: str = "Euler"):
    """One lander dropped upright at v0 from ``height_m`` (its feet's), stepped by MuJoCo until
    its first apex after the bounce: (the bounce's measures, as bench.accuracy reads Touchdown's,
    or None if it did not bounce; CPU seconds per simulated second of the run, from
    mujoco.rollout). Measures: apex and separation speed from the first state after the feet
    leave the ground (energy in uniform gravity: exact for the state), the deepest sampled
    penetration, and the contact's duration from the last clear state before it and the first
    after (ballistic extrapolation)."""
    import mujoco
    from mujoco import rollout

    from touchdown import scenarios
    from touchdown.sim.scenario import parse_text

    scn = parse_text(scenarios.text("bounce"), "bounce")
    sh, cp = scn.params.ships, scn.params.contact
    xml = lander_xml(float(sh.mass0_kg[0]), sh.inertia0_kgm2[0], float(sh.leg_radius_m[0]),
                     float(sh.com_height_m[0]), float(sh.stiffness_per_kg[0]), cp.damping_ratio,
                     dt_s=dt_s, gravity=g_mps2, integrator=integrator)
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    h = float(sh.com_height_m[0])
    mujoco.mj_resetData(model, data)
    data.qpos[2] = h + height_m
    data.qvel[2] = -v0_mps
    t_end = 2.0 * v0_mps / g_mps2 + 1.0
    n = int(math.ceil(t_end / dt_s))
    zs, vs, touching = [], [], []
    for _ in range(n):
        mujoco.mj_step(model, data)
        zs.append(float(data.qpos[2]))
        vs.append(float(data.qvel[2]))
        touching.append(data.ncon > 0)
        if len(touching) > 2 and not touching[-1] and any(touching) and vs[-1] > 0.0:
            break
    x0 = initial_states(model, [height_m], [v0_mps])
    t0 = time.process_time()
    reps = max(1, int(2000 // n))
    for _ in range(reps):
        rollout.rollout(model, data, x0, nstep=n)
    cost = (time.process_time() - t0) / reps / (n * dt_s)
    if not any(touching) or touching[-1] or vs[-1] <= 0.0:
        return None, cost
    first = touching.index(True)
    z, v = zs[-1], vs[-1]
    measures = {"apex": (z - h) + v * v / (2.0 * g_mps2),
                "separation": math.sqrt(v * v + 2.0 * g_mps2 * (z - h)),
                "penetration": max(h - x for x in zs),
                "contact": None}
    zb, vb = (zs[first - 1], vs[first - 1]) if first > 0 else (h + height_m, -v0_mps)
    t_in = first * dt_s + (vb + math.sqrt(vb * vb + 2.0 * g_mps2 * (zb - h))) / g_mps2
    t_out = len(zs) * dt_s - (-v + math.sqrt(v * v + 2.0 * g_mps2 * (z - h))) / g_mps2
    measures["contact"] = t_out - t_in
    return measures, cost


def main(quick: bool = False) -> None:
    """Print both engines' rates and their ratios, measured now, on this machine."""
    try:
        import mujoco
    except ImportError:
        print("MuJoCo side by side: skipped (pip install -e '.[bench]' installs mujoco)")
        return
    one = 5_000 if quick else 100_000
    fleet, fleet_steps = (1_000, 20) if quick else (10_000, 100)
    # the same simulated time on both: five MuJoCo steps of 0.01 s per Touchdown tick of 0.05 s
    mj_one = mujoco_one_lander(one)
    mj_fleet = mujoco_fleet(fleet, fleet_steps)
    with tempfile.TemporaryDirectory() as tmp:
        runs = [(label, touchdown_one_lander(one // 5, log_dir=d),
                 touchdown_fleet(fleet, fleet_steps // 5, log_dir=d))
                for label, d in (("stepping alone", None), ("with the full log", tmp))]
    print(f"MuJoCo {mujoco.__version__} beside Touchdown (CPU time of every thread; MuJoCo dt "
          f"0.01 s through mujoco.rollout on one thread, Touchdown's tick 0.05 s; Touchdown "
          f"stepping alone, and recording its full MCAP log as `touchdown record` does):")
    for label, td_one, td_fleet in runs:
        print(f"  one lander, {label}: MuJoCo {mj_one:>12,.0f} steps/s   Touchdown "
              f"{td_one:>10,.0f} ticks/s   per step {td_one / mj_one:.4f}x   per simulated "
              f"second {td_one * 0.05 / (mj_one * 0.01):.3f}x")
        print(f"  {fleet:,} landers, {label}: MuJoCo {mj_fleet:>12,.0f} ship-steps/s   "
              f"Touchdown {td_fleet:>10,.0f} ship-ticks/s   per step {td_fleet / mj_fleet:.3f}x"
              f"   per simulated second {td_fleet * 0.05 / (mj_fleet * 0.01):.3f}x")
