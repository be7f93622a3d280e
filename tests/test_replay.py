"""Replay: bit-for-bit verification, the first divergence, keyframe windows, one ship alone,
other SIMD paths, and what-if runs."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from mcap.reader import make_reader
from mcap.writer import Writer

from touchdown.cli import main
from touchdown.logs.codec import encode_tick
from touchdown.logs.decode import decode_tick
from touchdown.logs.header import TOPIC_TICKS
from touchdown.logs.reader import LogReader
from touchdown.replay.verify import verify

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("replay")
    out = {}
    for name, sets in (("bounce", ["duration=16"]), ("fleet", ["duration=8"])):
        path = d / f"{name}.mcap"
        args = ["record", name, "-o", str(path)] + [x for s in sets for x in ("--set", s)]
        r = CliRunner().invoke(main, args)
        assert r.exit_code == 0, r.output
        out[name] = path
    return out


def rewrite_topic(src: Path, dst: Path, topic: str, edit) -> None:
    """Copy a log, passing each message of ``topic`` through ``edit(bytes) -> bytes``."""
    with open(src, "rb") as f, open(dst, "wb") as g:
        w = Writer(g)
        w.start()
        schemas, channels = {}, {}
        for schema, channel, message in make_reader(f).iter_messages():
            if schema.id not in schemas:
                schemas[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = w.register_channel(channel.topic, channel.message_encoding,
                                                          schemas[schema.id])
            data = edit(message.data) if channel.topic == topic else message.data
            w.add_message(channels[channel.id], message.log_time, data, message.publish_time,
                          message.sequence)
        w.finish()


def rewrite(src: Path, dst: Path, tick: int, field: str, index: int, delta_ulps: int = 1):
    """Copy a log, nudging one number of one tick record by a few units in the last place."""
    def edit(data: bytes) -> bytes:
        t, t_s, n, arrays = decode_tick(data)
        if t != tick:
            return data
        a = arrays[field].copy()
        a[index] = np.nextafter(a[index], np.inf) if delta_ulps == 1 else a[index] + 1
        arrays[field] = a
        return encode_tick(t, t_s, n, arrays)
    rewrite_topic(src, dst, TOPIC_TICKS, edit)


def test_identical_rerun_verifies(logs):
    r = CliRunner().invoke(main, ["replay", str(logs["bounce"]), "--verify"])
    assert r.exit_code == 0, r.output
    assert "identical: ticks 0..320" in r.output


@pytest.mark.parametrize("tick,field,index,shown", [
    (57, "vel_mps", 2, "vel_mps[2]"),
    (200, "altitude_m", 0, "altitude_m"),
    (3, "fuel_kg", 0, "fuel_kg"),
])
def test_a_one_ulp_edit_is_found_at_exactly_its_tick_and_field(logs, tmp_path, tick, field,
                                                                 index, shown):
    bad = tmp_path / "edited.mcap"
    rewrite(logs["bounce"], bad, tick, field, index)
    r = CliRunner().invoke(main, ["replay", str(bad), "--verify"])
    assert r.exit_code == 1, r.output
    assert f"DIVERGED at tick {tick}" in r.output
    assert f"field {shown}" in r.output
    assert "ship lander-1" in r.output
    if tick > 20:
        assert "ship.contact" in r.output  # the last transitions before the divergence


def test_edit_in_a_fleet_names_the_ship(logs, tmp_path):
    bad = tmp_path / "edited.mcap"
    rewrite(logs["fleet"], bad, 40, "pos_m", 3 * 4 + 1)  # ship 4 ("slider"), y
    res = verify(str(bad))
    assert res.divergence.tick == 40
    assert res.divergence.ship_id == "slider"
    assert res.divergence.field == "pos_m[1]"


def test_keyframe_window_matches_the_run_from_tick_zero(logs):
    res = verify(str(logs["fleet"]), first=60, last=140)
    assert res.identical and res.first_tick == 60 and res.last_tick == 140
    # and an edit inside the window is still found from the keyframe
    r = CliRunner().invoke(main, ["replay", str(logs["fleet"]), "--verify", "--from-tick", "100",
                                  "--to-tick", "120"])
    assert r.exit_code == 0, r.output


def test_one_ship_of_many_replays_alone_bit_identically(logs):
    for ship in ("soft", "bouncer", "toppler", "hover"):
        res = verify(str(logs["fleet"]), ship_id=ship)
        assert res.identical, res.report()
        assert res.ships == [ship]


def test_unknown_ship_is_a_user_error(logs):
    r = CliRunner().invoke(main, ["replay", str(logs["fleet"]), "--verify", "--ship", "nope"])
    assert r.exit_code == 2
    assert "nope" in r.output and "Traceback" not in r.output


@pytest.mark.slow
def test_other_simd_paths_and_another_batch_replay_bit_identically(logs):
    """Re-run in subprocesses with numpy's widest SIMD extensions switched off, whole and one
    ship alone (another batch composition)."""
    import numpy as np  # noqa: F401
    from numpy._core._multiarray_umath import __cpu_features__ as feats
    wide = [f for f in ("AVX512_SPR", "AVX512_ICL", "X86_V4", "X86_V3", "AVX512F", "AVX2")
            if feats.get(f)]
    if not wide:
        pytest.skip("this CPU has no SIMD extension above numpy's baseline to switch off")
    for disabled, extra in ((wide[:1], []), (wide, ["--ship", "bouncer"])):
        env = dict(os.environ, NPY_DISABLE_CPU_FEATURES=" ".join(disabled))
        r = subprocess.run([sys.executable, str(ROOT / "cli.py"), "replay", str(logs["fleet"]),
                            "--verify", *extra], env=env, capture_output=True, text=True,
                           cwd=ROOT, timeout=300)
        assert r.returncode == 0, (disabled, r.stdout, r.stderr)
        assert "identical" in r.stdout


def test_what_if_reports_departures_and_writes_a_log(logs, tmp_path):
    out = tmp_path / "whatif.mcap"
    r = CliRunner().invoke(main, ["replay", str(logs["bounce"]), "--set",
                                  "sim.integrator=semi_implicit_euler", "--set",
                                  "sim.max_substep=0", "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert "largest position difference" in r.output
    pos = float(r.output.split("largest position difference: ")[1].split(" m")[0])
    assert pos > 0.1  # the seed's method at the plain tick bounces visibly differently
    assert "ship.liftoff" in r.output and "|" in r.output
    with LogReader(out) as reader:
        assert reader.scenario.integrator == "semi_implicit_euler"
    assert verify(str(out)).identical  # the new log is itself a replayable recording


def test_what_if_with_no_change_departs_by_nothing(logs):
    r = CliRunner().invoke(main, ["replay", str(logs["bounce"]), "--set", "sim.dt=0.05"])
    assert r.exit_code == 0, r.output
    assert "largest position difference: 0 m" in r.output


def test_sparse_keyframes_seek_from_the_nearest_one(tmp_path):
    path = tmp_path / "sparse.mcap"
    r = CliRunner().invoke(main, ["record", "bounce", "--set", "duration=16", "--keyframe-every",
                                  "50", "-o", str(path)])
    assert r.exit_code == 0, r.output
    with LogReader(path) as reader:
        assert reader.keyframe_interval == 50
        flags = {td.tick: td.is_keyframe for td in reader.ticks()}
    assert flags[0] and flags[50] and flags[300] and not flags[51] and not flags[299]
    res = verify(str(path), first=130, last=200)
    assert res.identical and res.first_tick == 100  # started from the keyframe at 100
    assert verify(str(path)).identical
    bad = tmp_path / "edited.mcap"
    rewrite(path, bad, 77, "altitude_m", 0)  # a non-keyframe tick: telemetry is still checked
    assert verify(str(bad)).divergence.tick == 77



def test_the_chunks_zstd_level_changes_the_files_size_not_its_contents(tmp_path):
    """``record --zstd-level``: a faster level writes a larger file holding the same messages,
    which replays bit for bit; without the option the level is logs.encode's default (1); a
    level zstd has not is refused (exit 2) before anything is written."""
    from touchdown.logs.encode import DEFAULT_ZSTD_LEVEL

    logs = {}
    for level in ("3", "-20", str(DEFAULT_ZSTD_LEVEL), None):
        logs[level] = tmp_path / f"z{level}.mcap"
        option = [] if level is None else ["--zstd-level", level]
        r = CliRunner().invoke(main, ["record", "fleet", "--set", "duration=6", *option,
                                      "-o", str(logs[level])])
        assert r.exit_code == 0, r.output
    assert logs["-20"].stat().st_size > 1.2 * logs["3"].stat().st_size
    assert logs[None].read_bytes() == logs[str(DEFAULT_ZSTD_LEVEL)].read_bytes()
    assert logs[None].stat().st_size > logs["3"].stat().st_size
    messages = {}
    for level, path in logs.items():
        with open(path, "rb") as f:
            messages[level] = [(c.topic, m.log_time, m.sequence, bytes(m.data)) for _s, c, m
                               in make_reader(f, validate_crcs=True).iter_messages()]
    assert len(messages["3"]) > 100 and messages["3"] == messages["-20"]
    assert verify(str(logs["-20"])).identical
    r = CliRunner().invoke(main, ["record", "bounce", "--zstd-level", "23", "-o",
                                  str(tmp_path / "no.mcap")])
    assert r.exit_code == 2 and "--zstd-level" in r.output
    assert not list(tmp_path.glob("no.mcap*"))


DATA = Path(__file__).resolve().parent / "data"


def test_a_log_of_the_previous_version_replays_with_a_version_notice(tmp_path):
    """tests/data holds logs written by touchdown 0.2.0 (log format 1: one friction regime per
    ship; velocities on keyframes only). verify re-runs them under today's physics, says that a
    divergence is expected and why, and names it; export and what-if replay read them."""
    r = CliRunner().invoke(main, ["replay", str(DATA / "bounce-0.2.0.mcap"), "--verify"])
    assert r.exit_code == 1
    assert "written by touchdown 0.2.0" in r.output and "divergence is expected" in r.output
    assert "DIVERGED at tick" in r.output and "nan" not in r.output
    out = tmp_path / "again.mcap"
    r = CliRunner().invoke(main, ["replay", str(DATA / "fleet-0.2.0-kf5.mcap"), "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert "written by touchdown 0.2.0" in r.output
    assert CliRunner().invoke(main, ["replay", str(out), "--verify"]).exit_code == 0
    r = CliRunner().invoke(main, ["export", str(DATA / "fleet-0.2.0-kf5.mcap")])
    assert r.exit_code == 0
    rows = [json.loads(line) for line in r.output.splitlines()]
    assert len(rows) == 21 * 6
    keyframe, between = rows[0], rows[6]  # tick 0 is a keyframe; tick 1 holds no velocities
    assert keyframe["energy_j"] is not None and between["energy_j"] is None
