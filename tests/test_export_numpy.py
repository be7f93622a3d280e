"""The Parquet and CSV export without compiled code (issue 37, item 7): the derived columns in
numpy are the compiled functions' numbers bit for bit, the tick records decoded in plain Python
and numpy are the compiled decoder's (its checks, its messages, its numbers), and the command
loads no numba."""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from touchdown.logs import LogError, derived
from touchdown.logs import decode as dec
from touchdown.logs import export as ex
from touchdown.logs.codec import decode_tick_python, encode_tick, varint
from touchdown.logs.reader import LogReader, TickData
from touchdown.logs.rebuild import fleet_params, log_params, scenario_of
from touchdown.sim.dynamics import Motion
from touchdown.sim import measure
from touchdown.sim.scenario import parse

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data"
LOGS = sorted(DATA.glob("*.mcap")) + sorted((DATA / "golden").glob("*.mcap"))

pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    """Every number the same double, to the bit (NaNs: both NaN)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    nan = np.isnan(a)
    return bool(np.array_equal(nan, np.isnan(b))
                and np.array_equal(a[~nan].view(np.int64), b[~nan].view(np.int64)))


# -- the derived columns ----------------------------------------------------------------------------
SCENES = {
    "level": {},
    "spinning": {"body": {"rotation_period": 36000.0}},
    "spinning-back": {"body": {"rotation_period": -7200.0, "radius": 3.0e6,
                               "surface_gravity": 3.0}},
    "slope": {"body": {"terrain": {"slope_deg": 20.0, "slope_azimuth_deg": 35.0,
                                   "base_height": 1.5}}},
    "bumps": {"body": {"terrain": {"slope_deg": 5.0, "bumps": [
        {"east": 2.0, "north": -3.0, "radius": 6.0, "height": 1.2},
        {"east": -4.0, "north": 1.0, "radius": 3.0, "height": -0.7}]}}},
    "radial": {"contact": {"surface_normal": "radial"},
               "body": {"terrain": {"slope_deg": 12.0, "bumps": [
                   {"east": 0.0, "north": 0.0, "radius": 5.0, "height": 0.4}]}}},
}


def scene_params(extra: dict, ships: int = 5):
    """A scene's parameters with ``ships`` ships of different classes (mass, legs, inertia,
    stiffness)."""
    rng = np.random.default_rng(len(json.dumps(extra)))
    doc = {"name": "derived", "duration": 2.0, **extra, "ships": [
        {"id": f"s{i}", "mass": float(rng.uniform(2e3, 3e4)),
         "com_height": float(rng.uniform(1.0, 4.0)), "leg_radius": float(rng.uniform(1.0, 4.0)),
         "stiffness_per_kg": float(rng.uniform(50.0, 400.0)),
         "initial": {"altitude": 5.0}} for i in range(ships)]}
    return parse(doc, "derived").params


def random_states(params, n: int, seed: int):
    """Rows of ships of ``params`` at and near the ground under the site (feet in it, above it,
    far above), turning, at times on several ticks; a few odd numbers (non-unit attitudes,
    zeros of either sign, an infinity, a NaN)."""
    rng = np.random.default_rng(seed)
    radius = params.body.radius_m
    ship = rng.integers(0, params.ships.n, n)
    t = np.repeat(np.round(rng.uniform(0.0, 500.0, n // 4 + 1), 2), 4)[:n]
    c, s = measure.body_angles(params, t, n)
    height = np.where(rng.random(n) < 0.7, rng.uniform(-0.5, 5.0, n), rng.uniform(5, 3e4, n))
    east, north = rng.uniform(-8, 8, n), rng.uniform(-8, 8, n)
    body_fixed = np.stack([radius + height, east, north], axis=1)
    p = np.stack([c * body_fixed[:, 0] - s * body_fixed[:, 1],
                  s * body_fixed[:, 0] + c * body_fixed[:, 1], body_fixed[:, 2]], axis=1)
    v = rng.normal(0, 3, (n, 3))
    q = rng.normal(0, 1, (n, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    q[::7] *= rng.uniform(0.9, 1.1, (len(q[::7]), 1))  # off the unit sphere
    w = rng.normal(0, 0.3, (n, 3))
    mass = params.ships.mass0_kg[ship] * rng.uniform(0.7, 1.0, n)
    v[::11, 1] = -0.0
    w[::13] = 0.0
    w[1::13] = -0.0
    odd = rng.choice(n, 6, replace=False)
    q[odd[0], 2] = np.nan
    q[odd[1], 0] = np.inf
    p[odd[2], 0] = np.inf
    v[odd[3], 2] = np.nan
    mass[odd[4]] = np.inf
    w[odd[5], 1] = -np.inf
    return ship, t, p, v, q, w, mass


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_the_numpy_site_frame_and_energy_are_the_compiled_ones_bit_for_bit(scene):
    params = scene_params(SCENES[scene])
    ship, t, p, v, q, w, mass = random_states(params, 20_000, 1)
    with np.errstate(all="ignore"):
        c, s = derived.body_angles(params, t)
        mc, ms = measure.body_angles(params, t, t.shape[0])
        assert same_bits(np.broadcast_to(c, mc.shape), mc)
        assert same_bits(np.broadcast_to(s, ms.shape), ms)
        pos, vel = measure.site_frame(params, p, v, t)
        mine = derived.site_frame(params, p, v, c, s)
        for k in range(3):
            assert same_bits(mine[k], pos[:, k]) and same_bits(mine[3 + k], vel[:, k])
        want = measure.energy(params, ship, t, Motion(p, v, q, w), mass)["total_j"]
        got = derived.energy(params, ship, p, v, q, w, mass, c, s)
    assert same_bits(got, want)
    # the rows that touch the ground, spring and all, are most of them
    assert (np.isfinite(want) & (p[:, 0] > 0)).sum() > 10_000


def test_the_numpy_energy_of_a_fleet_of_one_class_takes_its_numbers_once():
    params = scene_params({}, ships=1).take(np.zeros(40, np.int64))  # one class, 40 ships
    ship, t, p, v, q, w, mass = random_states(params, 5_000, 2)
    with np.errstate(all="ignore"):
        want = measure.energy(params, ship, t, Motion(p, v, q, w), mass)["total_j"]
        got = derived.energy(params, ship, p, v, q, w, mass, 1.0, 0.0)
    assert same_bits(got, want)


def test_the_tilt_is_sim_trigs_arccosine_in_degrees():
    """The column's tilt is degrees(sim.trig.acos(c)) value by value, bit for bit (the same bits
    on every machine), and within 2e-14 deg (or 1e-14 relative) of libm's."""
    from touchdown.sim import trig
    rng = np.random.default_rng(3)
    c = np.concatenate([rng.uniform(-1.0, 1.0, 200_000), 1 - rng.exponential(1e-9, 10_000),
                        -1 + rng.exponential(1e-9, 10_000),
                        [1.0, -1.0, 0.0, -0.0, 1.5, -7.0, np.nan, 1e-300, -1e-300]])
    want = np.array([math.degrees(trig.acos(x)) for x in c.tolist()])
    got = derived.tilt_deg(c)
    assert same_bits(got, want)
    libm = np.array([math.degrees(math.acos(max(-1.0, min(1.0, x)))) if x == x else np.nan
                     for x in c.tolist()])
    assert np.allclose(got, libm, rtol=1e-14, atol=2e-14, equal_nan=True)
    assert got[-9:-3].tolist() == [0.0, 180.0, 90.0, 90.0, 0.0, 180.0] and np.isnan(got[-3])


@pytest.mark.parametrize("log", LOGS, ids=lambda p: p.name)
def test_every_log_of_tests_data_exports_the_reference_rows(log, tmp_path):
    """The columnar export (numpy) against the per-row one (compiled sim.measure, JSON per row),
    Parquet and CSV, on every log kept in tests/data: every format, keyframe intervals,
    slopes, a spinning or tilted scene, a format-1 log's nulls."""
    with LogReader(log) as r:
        ref = list(ex.tick_rows(r))
    for fmt in ("parquet", "csv"):
        out = tmp_path / f"x.{fmt}"
        from click.testing import CliRunner
        from touchdown.cli import main
        res = CliRunner().invoke(main, ["export", str(log), "--format", fmt, "-o", str(out)])
        assert res.exit_code == 0, res.output
        if fmt == "parquet":
            rows = pq.read_table(out).to_pylist()
        else:
            import pyarrow.csv as pcsv
            rows = pcsv.read_csv(out).to_pylist()
        assert len(rows) == len(ref)
        for a, b in zip(rows, ref):
            assert a.keys() == b.keys()
            for k in a:
                x, y = a[k], b[k]
                if y is None and k in ("east", "north", "up"):
                    continue  # (a format-1 log between keyframes: the per-row path gives no
                    # site frame without velocities; the columns give the logged position's)
                if isinstance(y, float) and fmt == "parquet":  # the double itself
                    assert x is not None and same_bits(x, y), (k, x, y)
                else:
                    assert x == y or (x is None and y is None), (k, x, y)


def test_a_column_without_nulls_is_required_and_a_format_1_logs_velocities_are_nullable(
        tmp_path):
    from click.testing import CliRunner
    from touchdown.cli import main
    old = set(ex.nullable_columns(1))
    assert {"v_east", "omega_x", "energy_j", "energy_guard_j"} <= old and "east" not in old
    for log, nullable in ((DATA / "fleet-0.2.0-kf5.mcap", old), (DATA / "golden" / "bounce.mcap",
                                                              set())):
        out = tmp_path / "x.parquet"
        assert CliRunner().invoke(main, ["export", str(log), "--format", "parquet", "-o",
                                         str(out)]).exit_code == 0
        schema = pq.read_schema(out)
        assert {f.name for f in schema if f.nullable} == nullable
        table = pq.read_table(out)
        assert all(table[n].null_count == 0 for n in table.column_names if n not in nullable)
        assert all(table[n].null_count > 0 for n in nullable)  # velocities between keyframes


def test_the_log_params_are_the_scenarios(tmp_path):
    """log_params (checked, not placed: no compiled code) gives scenario_of's fleet_params."""
    for log in LOGS:
        with LogReader(log) as r:
            a, b = log_params(r), fleet_params(r, scenario_of(r)[0])
        assert repr(a) == repr(b), log.name


def test_parquet_and_csv_export_load_no_compiled_code(tmp_path):
    """The command imports neither numba nor scipy: half a second of a Parquet export (numba's
    import, and the registry refresh loading cached kernels triggers, which imports scipy)."""
    code = ("import sys\nfrom touchdown.cli import main\ntry:\n    main()\n"
            "except SystemExit as e:\n    assert not e.code, e.code\n"
            "print(sorted(m for m in ('numba', 'scipy', 'llvmlite') if m in sys.modules))\n")
    for fmt in ("parquet", "csv"):
        out = tmp_path / f"x.{fmt}"
        r = subprocess.run([sys.executable, "-c", code, "export", str(DATA / "fleet-0.5.0.mcap"),
                            "--format", fmt, "-o", str(out)], capture_output=True, text=True,
                           cwd=ROOT)
        assert r.returncode == 0, r.stderr
        assert r.stdout.strip() == "[]", (fmt, r.stdout)
        assert out.stat().st_size > 0


# -- the decoder -----------------------------------------------------------------------------------
def ticks_of(log: Path, n: int):
    with LogReader(log) as r:
        fmt, table = r.log_format, len(r.ship_table())
        return [(td.raw, td.tick_from_time) for td in r.ticks(0, n - 1)], fmt, table


def alone(raw: bytes, tick: int, fmt: int, table: int):
    """The tick decoded and checked on its own (TickData), or the LogError it gives."""
    td = TickData(raw, tick, "x", 0, fmt, table)
    try:
        td._decode()
    except LogError as exc:
        return exc
    return td


def block_of(raws, fmt, table, wanted=None):
    data = np.frombuffer(b"".join(r for r, _ in raws), np.uint8)
    offsets = np.cumsum([0] + [len(r) for r, _ in raws])
    return dec.decode_block(data, offsets, np.array([t for _, t in raws]), fmt, table, 0,
                            wanted, where="x")


def test_a_damaged_block_is_refused_naming_a_tick_that_is_damaged_and_only_then():
    """A byte changed, cut or added anywhere in a block of a fleet's ticks: the block is refused
    if and only if some tick is refused on its own, naming one that is; otherwise its columns
    are the ticks' numbers."""
    raws, fmt, table = ticks_of(DATA / "fleet-0.6.0-kf5.mcap", 12)
    rng = np.random.default_rng(5)
    refused = 0
    for trial in range(400):
        bad = list(raws)
        k = int(rng.integers(0, len(bad)))
        raw = bytearray(bad[k][0])
        i = int(rng.integers(0, len(raw)))
        kind = trial % 4
        if kind == 0:
            raw[i] ^= 1 << int(rng.integers(0, 8))
        elif kind == 1:
            raw[i] = int(rng.integers(0, 256))
        elif kind == 2:
            del raw[i:i + int(rng.integers(1, 4))]
        else:
            raw[i:i] = bytes(rng.integers(0, 256, int(rng.integers(1, 3)), dtype=np.uint8))
        bad[k] = (bytes(raw), bad[k][1])
        each = [alone(r, t, fmt, table) for r, t in bad]
        failing = {t for (r, t), a in zip(bad, each) if isinstance(a, LogError)}
        try:
            b = block_of(bad, fmt, table)
        except LogError as exc:
            refused += 1
            named = int(str(exc).split("tick ")[1].split(":")[0])
            assert named in failing, (str(exc), failing)
            continue
        assert not failing, failing
        for j, td in enumerate(each):
            bt = b.tick(j)
            assert bt.arrays.keys() == td.arrays.keys()
            for name, a in td.arrays.items():
                assert bt.arrays[name].astype(a.dtype).tobytes() == a.tobytes(), name
    assert 50 < refused < 400


def test_records_no_writer_writes_go_to_the_compiled_scan_and_read_the_same(monkeypatch):
    """Unknown fields are legal protobuf: a record of more fields than a writer writes (the
    Python walk stops at 64), and a block of more layouts than a log has (64 walked), read the
    same as the Python reference, through the compiled scan."""
    raws, fmt, table = ticks_of(DATA / "fleet-0.5.0.mcap", 80)
    long = [(raw + b"".join(b"\xf8\x07" + varint(j) for j in range(100)), t)
            for raw, t in raws[:3]]  # field 127, 100 times
    many = []  # 100 ticks, each with an unknown field of its own length: 100 layouts
    for j in range(100):
        t, t_s, n, arrays = decode_tick_python(raws[j % len(raws)][0])
        many.append((encode_tick(j, j * 0.05, n, arrays) + b"\xfa\x07" + varint(j) + bytes(j),
                     j))
    scanned = []
    compiled = dec._compiled
    monkeypatch.setattr(dec, "_compiled", lambda *a: scanned.append(a[-1].size) or compiled(*a))
    for blockraws in (long, many):
        b = block_of(blockraws, fmt, table)
        for j, (raw, t) in enumerate(blockraws):
            ref = decode_tick_python(raw)
            assert (int(b.ticks[j]), float(b.t_s[j]), int(b.counts[j])) == ref[:3]
            for name, a in ref[3].items():
                assert np.array_equal(b.tick(j).arrays[name].astype(a.dtype), a), name
    assert scanned == [len(long), len(many) - dec.PY_MESSAGES]
    # and a damaged one among them is named as the Python walk names it
    broken = list(long)
    broken[1] = (broken[1][0][:-1], broken[1][1])
    with pytest.raises(LogError, match=f"tick {broken[1][1]}: truncated varint"):
        block_of(broken, fmt, table)


def test_a_ship_count_past_two_to_the_63_is_refused_by_name():
    raws, fmt, table = ticks_of(DATA / "fleet-0.5.0.mcap", 2)
    t, t_s, _n, _ = decode_tick_python(raws[0][0])
    raw = encode_tick(t, t_s, 0, {}) + b"\x18" + varint((1 << 64) - 5)  # no fields
    with pytest.raises(LogError, match="a ship count of"):
        block_of([(raw, raws[0][1])], fmt, table)


def test_a_block_decoded_a_chunk_at_a_time_is_the_block_decoded_at_once():
    """LogReader.blocks (chunk by chunk, into reused buffers) against decode_block of the same
    records in one piece, on a log whose blocks end inside chunks."""
    log = DATA / "fleet-0.6.0-kf5.mcap"
    with LogReader(log) as r:
        raws = [(td.raw, td.tick_from_time) for td in r.ticks()]
        fmt, table = r.log_format, len(r.ship_table())
        whole = block_of(raws, fmt, table)
        k = 0
        for b in r.blocks(block_bytes=3000, reuse=True):
            for j in range(b.ticks.shape[0]):
                assert int(b.ticks[j]) == int(whole.ticks[k])
                for name, col in b.columns.items():
                    assert np.array_equal(b.tick(j).arrays.get(name, col[:0].ravel()),
                                          whole.tick(k).arrays.get(name, col[:0].ravel())), name
                k += 1
    assert k == len(raws)
