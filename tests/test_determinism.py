"""Determinism: the step is a pure function, and a ship's numbers do not depend on its batch."""
import dataclasses
from fractions import Fraction

import numpy as np
import pytest

import background

from scenes import records, scene
from touchdown.sim.state import OUTPUTS_DTYPE, STATE_ARRAY_FIELDS, STATE_DTYPE
from touchdown.sim.step import step

OUTPUT_FIELDS = OUTPUTS_DTYPE.names


def varied_fleet(n, seed=20261122):
    """n different ships: every initial state, speeds, tilts, spins, sizes, commands."""
    rng = np.random.default_rng(seed)
    ships = []
    for i in range(n):
        state = ["flying", "flying", "flying", "contact", "landed", "tipped"][i % 6]
        ini = {"state": state, "east": float(rng.uniform(-5e3, 5e3)),
               "north": float(rng.uniform(-5e3, 5e3)), "heading_deg": float(rng.uniform(0, 360))}
        if state == "flying":
            ini.update(altitude=float(rng.choice([rng.uniform(0.0, 3.0), rng.uniform(10, 5e3)])),
                       vertical_speed=float(-rng.uniform(0, 60)),
                       horizontal_speed=float(rng.uniform(0, 8)),
                       tilt_deg=float(rng.uniform(0, 50)),
                       angular_velocity=[float(x) for x in rng.uniform(-0.3, 0.3, 3)])
        elif state == "contact":
            ini.update(altitude=-0.01, vertical_speed=float(-rng.uniform(0, 30)),
                       tilt_deg=float(rng.uniform(0, 60)),
                       horizontal_speed=float(rng.uniform(0, 5)))
        elif state == "landed":
            ini.update(tilt_deg=float(rng.uniform(0, 10)))
        else:
            ini.update(tilt_deg=float(rng.uniform(81, 90)))
        inputs = []
        if rng.random() < 0.3:
            inputs.append({"t": float(rng.uniform(0, 1)), "throttle": float(rng.uniform(0, 1)),
                           "rcs": [float(x) for x in rng.uniform(-1, 1, 3)],
                           "hold": str(rng.choice(["off", "radial", "kill_rotation"]))})
        # ship classes: mass, legs (some wide and squat, stiff enough on their rocking mode to
        # need more sub-steps than the scene's), inertia (some with three different moments) and
        # contact stiffness
        wide = rng.random() < 0.1
        ship = {"id": f"s{i}", "mass": float(rng.uniform(3e3, 2e4)),
                "fuel_mass": float(rng.uniform(100, 2000)),
                "com_height": float(rng.uniform(0.5, 1.0) if wide else rng.uniform(1.5, 5)),
                "leg_radius": float(rng.uniform(6, 9) if wide else rng.uniform(1, 4)),
                "stiffness_per_kg": float(rng.choice([100.0, rng.uniform(50.0, 400.0)])),
                "initial": ini, "inputs": inputs}
        if rng.random() < 0.3:
            a, b = rng.uniform(1e4, 6e4, 2)
            ship["inertia"] = [float(a), float(b), float(rng.uniform(abs(a - b), a + b))]
        ships.append(ship)
    return ships


def assert_same_ship(a_rec, b_rec, i, j):
    for name in STATE_ARRAY_FIELDS:
        x, y = getattr(a_rec.state, name)[i], getattr(b_rec.state, name)[j]
        assert np.asarray(x).tobytes() == np.asarray(y).tobytes(), (a_rec.tick, name)
    for name in OUTPUT_FIELDS:
        x, y = getattr(a_rec.outputs, name)[i], getattr(b_rec.outputs, name)[j]
        assert np.asarray(x).tobytes() == np.asarray(y).tobytes(), (a_rec.tick, name)


def test_one_ship_alone_and_among_a_thousand_of_other_classes_is_bit_identical():
    """Every tick, every number of the state and the telemetry, and every event: a ship's bits
    do not depend on its neighbours, whatever their mass, legs, inertia or stiffness, nor on how
    many sub-steps they need."""
    fleet = varied_fleet(1000)
    body = {"terrain": {"bumps": [{"east": 30.0, "north": 0.0, "radius": 40.0, "height": 1.5}]},
            "rotation_period": 7200.0}
    scn = scene(ships=fleet, body=body, duration=2.0)
    subs = scn.params.ships.n_substeps
    assert subs.min() == 2 and subs.max() > 2  # the wide-legged ships take sub-steps of their own
    together = records(scn)
    wide = [i for i, s in enumerate(fleet) if s["leg_radius"] > 5][:2]
    for k in (0, 3, 4, 5, 997, *wide):  # flying, contact, landed, tipped, flying, wide-legged
        alone = records(scene(ships=[fleet[k]], body=body, duration=2.0))
        assert len(alone) == len(together)
        for a, b in zip(together, alone):
            assert_same_ship(a, b, k, 0)
            ev_a = [(e.kind, e.from_state, e.to_state, e.v_radial_mps) for e in a.events
                    if e.ship == k]
            ev_b = [(e.kind, e.from_state, e.to_state, e.v_radial_mps) for e in b.events]
            assert ev_a == ev_b


def test_ships_at_rest_copied_not_stepped_give_the_stepped_bits():
    """sim.step.Resting: a world does not step again a ship whose tick gave back its state bit for
    bit (landed and tipped ships at rest, on a body that does not turn); it copies that tick. The
    varied fleet on such a body (its ships landing, tipping, resting, lifting off and torqued by
    RCS on their commands), run by the world, has every ship's state, telemetry and events at
    every tick bit for bit as stepping the whole batch tick by tick (sim.step.step, which never
    copies), and the copying did happen."""
    from touchdown.sim.world import World
    fleet = varied_fleet(240, seed=20261129)
    for i, ship in enumerate(fleet):  # landed and tipped ships given commands after rest
        if ship["initial"]["state"] in ("landed", "tipped") and i % 4 == 0:
            ship["inputs"] = [{"t": 1.2, "throttle": 1.0}, {"t": 1.5, "throttle": 0.0}]
        elif ship["initial"]["state"] in ("landed", "tipped") and i % 4 == 2:
            ship["inputs"] = [{"t": 1.0, "rcs": [0.0, 1.0, 0.0]}, {"t": 1.1, "rcs": [0.0, 0.0, 0.0]}]
    body = {"terrain": {"bumps": [{"east": 30.0, "north": 0.0, "radius": 40.0, "height": 1.5}]}}
    scn = scene(ships=fleet, body=body, duration=3.0)
    world = World.of(scn)
    blocks = list(world.blocks(60, max_ticks=7))  # blocks of 7 ticks: rest carried across them
    assert world._resting[0].fixed.sum() >= 40
    state = scn.initial
    k = 0
    for block in blocks:
        stepped = []
        for j in range(len(block)):
            state, out, evs = step(scn.params, state, scn.inputs_at(k))
            stepped += evs
            k += 1
            for name in STATE_DTYPE.names:  # field by field: a record's padding is not state
                assert block.states[j][name].tobytes() == state.rows[name].tobytes(), (k, name)
            for name in OUTPUT_FIELDS:
                assert block.outputs[j][name].tobytes() == out.rows[name].tobytes(), (k, name)
        assert block.events == [dataclasses.replace(e, ship_id=block.ship_ids[e.ship])
                                for e in stepped]
    events = [(e.ship, e.kind) for b in blocks for e in b.events]
    assert len(events) >= 10


def test_the_fleet_reaches_contact_and_transitions():
    """The batch above is not idle: the check is worth something only if ships do things."""
    recs = records(scene(ships=varied_fleet(120), duration=2.0))
    kinds = {e.kind for r in recs for e in r.events}
    assert len(kinds) >= 4


def test_step_is_pure():
    scn = scene({"altitude": 0.5, "vertical_speed": -20.0}, duration=1.0)
    inputs = scn.inputs_at(0)
    s1, o1, e1 = step(scn.params, scn.initial, inputs)
    s2, o2, e2 = step(scn.params, scn.initial, inputs)
    for name in STATE_ARRAY_FIELDS:
        assert getattr(s1, name).tobytes() == getattr(s2, name).tobytes()
    assert e1 == e2
    # the input state is not modified
    again, _, _ = step(scn.params, scn.initial, inputs)
    assert again.pos_m.tobytes() == s1.pos_m.tobytes()


BODY = {"terrain": {"bumps": [{"east": 30.0, "north": 0.0, "radius": 40.0, "height": 1.5}]},
        "rotation_period": 7200.0}


def test_the_kernels_never_fuse_a_multiply_and_an_add():
    """a * b + c rounded twice, as IEEE arithmetic (and numpy) do, never once (a fused
    multiply-add, which this CPU may have): sim.compiled's settings, on inputs where the two
    differ."""
    from touchdown.sim.compiled import kernel

    @kernel
    def mul_add(a, b, c, out):
        for i in range(a.shape[0]):
            out[i] = a[i] * b[i] + c[i]

    rng = np.random.default_rng(3)
    a, b = rng.uniform(1.0, 2.0, 10000), rng.uniform(1.0, 2.0, 10000)
    c = -(a * b) * (1.0 + rng.uniform(-1e-15, 1e-15, 10000))  # cancellation exposes the rounding
    out = np.empty_like(a)
    mul_add(a, b, c, out)
    assert out.tobytes() == (a * b + c).tobytes()
    # the inputs do tell the two apart: a fused multiply-add rounds the exact a * b + c once
    fused = [float(Fraction(x) * Fraction(y) + Fraction(z)) for x, y, z in zip(a[:500], b[:500],
                                                                                c[:500])]
    assert (np.array(fused) != (a * b + c)[:500]).sum() > 100


def _generic_env() -> dict:
    import os
    import warmup
    # and an older machine's libm and BLAS (tests/test_portable.py): glibc's functions without
    # AVX2 and FMA, OpenBLAS's SSE3 kernels
    env = dict(os.environ, NUMBA_CPU_NAME="generic", OPENBLAS_CORETYPE="Prescott",
               GLIBC_TUNABLES="glibc.cpu.hwcaps=-AVX2,-FMA")
    env.pop("NUMBA_CPU_FEATURES", None)
    if "generic_cache" in warmup.done():  # compiled there before xdist's workers started
        env["NUMBA_CACHE_DIR"] = warmup.done()["generic_cache"]
    return env


@background.job("test_determinism.py::test_kernels_compiled_for_a_generic_cpu_give_this_hosts_bits")
def _compile_for_a_generic_cpu() -> None:
    """The kernels compiled for a generic x86-64 into the cache (`touchdown warm` with
    NUMBA_CPU_NAME=generic), ahead of the test below in a serial run (tests/background.py)."""
    import subprocess
    import sys
    subprocess.run([sys.executable, "-c", "from touchdown.cli import main; main(['warm'])"],
                   env=_generic_env(), capture_output=True, timeout=1800)


@pytest.mark.slow
def test_kernels_compiled_for_a_generic_cpu_give_this_hosts_bits(tmp_path):
    """A log recorded here verifies with the kernels compiled for a generic x86-64 (no FMA, no
    AVX: NUMBA_CPU_NAME=generic; glibc and OpenBLAS as on an older machine), and a log recorded
    with those verifies here, its events too: varied ship classes, every state, terrain, a
    turning body."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    from touchdown.replay.verify import verify
    from touchdown.service.driver import record

    doc = {"name": "generic", "duration": 1.5, "body": BODY, "ships": varied_fleet(120)}
    (tmp_path / "fleet.json").write_text(json.dumps(doc))
    host = scene(ships=doc["ships"], body=BODY, duration=1.5)
    record(host, tmp_path / "host.mcap", "test")
    script = f"""
import json, sys
import numba
assert numba.config.CPU_NAME == "generic", numba.config.CPU_NAME
from touchdown.replay.verify import verify
from touchdown.service.driver import record
from touchdown.sim.scenario import parse
res = verify({str(tmp_path / "host.mcap")!r})
print(res.report())
assert res.identical
scn = parse(json.load(open({str(tmp_path / "fleet.json")!r})), "test")
record(scn, {str(tmp_path / "generic.mcap")!r}, "test")
"""
    root = Path(__file__).resolve().parents[1]
    background.wait(_compile_for_a_generic_cpu)
    r = subprocess.run([sys.executable, "-c", script], env=_generic_env(), cwd=root,
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "identical" in r.stdout
    mine = verify(str(tmp_path / "generic.mcap"))
    assert mine.identical, mine.report()


def test_compiling_is_announced_once_and_loading_from_the_cache_is_silent():
    """sim.compiled.notify_compilation: the command line's one-line notice is said when a kernel
    compiles (the first run after an install), once however many kernels follow."""
    import numba

    from touchdown.sim.compiled import notify_compilation

    said = []
    notify_compilation(said.append)
    try:
        @numba.njit  # not cached: it compiles on every run of this test
        def fresh_a(x):
            return x * 2.0 + 1.0

        @numba.njit
        def fresh_b(x):
            return fresh_a(x) - 1.0

        assert fresh_b(3.0) == 6.0
        assert len(said) == 1 and "compiling" in said[0]
    finally:
        notify_compilation()


def test_a_kernels_scratch_arrays_start_at_zero_in_the_shape_and_type_asked():
    """sim.compiled.zeros, the kernels' np.zeros: each call gives a fresh array of zeros, of the
    shape (an int or a tuple) and the numpy type asked, however the memory was used before."""
    from touchdown.sim.compiled import entry, kernel, zeros

    @kernel
    def dirty_then_fresh(n):
        for _ in range(3):
            a = zeros((n, 3), np.float64)
            b = zeros(n, np.int64)
            c = zeros(n, np.bool_)
            total = a.sum() + b.sum() + c.sum()
            a[:] = 7.0
            b[:] = 7
            c[:] = True
        return a, b, c, total

    @entry
    def run(n):
        return dirty_then_fresh(n)

    a, b, c, total = run(5)
    assert total == 0.0
    assert a.shape == (5, 3) and a.dtype == np.float64 and (a == 7.0).all()
    assert b.shape == (5,) and b.dtype == np.int64 and c.dtype == np.bool_ and c.all()


def test_kernels_still_free_the_arrays_they_make_and_type_array_arithmetic():
    """sim.compiled's short-cuts skip numba's reference counting only for values holding no
    managed memory: arrays made in a loop, held in a tuple and dropped, are all freed (numba's
    allocation counts balance) and give the right sums; array and scalar arithmetic both type."""
    from numba.core.runtime import _nrt_python as nrt, rtsys
    from touchdown.sim.compiled import entry, kernel

    @kernel
    def churn(n):
        kept = (np.zeros(n), 0.0)
        for i in range(5):
            fresh = np.ones(n) * float(i)  # an array times a scalar: numpy's operators
            kept = (kept[0] + fresh, kept[1] + 1.5 * float(i))  # array + array, scalar * scalar
        return kept

    @entry
    def run(n):
        total = 0.0
        for _ in range(10):
            arr, s = churn(n)
            total += arr.sum() + s
        return total

    nrt.memsys_enable_stats()
    try:
        run(4)  # compiled before counting
        before = rtsys.get_allocation_stats()
        total = run(4)
        after = rtsys.get_allocation_stats()
    finally:
        nrt.memsys_disable_stats()
    assert total == 10 * (4 * (0 + 1 + 2 + 3 + 4) + 1.5 * 10)
    allocated, freed = after.alloc - before.alloc, after.free - before.free
    assert allocated >= 10 * 5 and freed == allocated
