"""The command line's contract (SPEC.md section 2): exit codes, one-line errors naming the file and
key, nothing half-written, both entry points, the export fields, Ctrl-C."""
import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from touchdown import scenarios
from touchdown.cli import main
from touchdown.logs.reader import LogReader

ROOT = Path(__file__).resolve().parents[1]
GOOD = """
name = "ok"
duration = 1.0
[[ships]]
id = "a"
[ships.initial]
altitude = 1.0
vertical_speed = -3.0
"""


def invoke(*args):
    r = CliRunner().invoke(main, [str(a) for a in args])
    assert r.exception is None or isinstance(r.exception, SystemExit), r.exception
    return r


def test_scenarios_lists_at_least_twelve_and_each_records(tmp_path):
    r = invoke("scenarios")
    assert r.exit_code == 0
    lines = r.output.strip().splitlines()
    assert len(lines) >= 12
    names = [ln.split()[0] for ln in lines]
    assert names == scenarios.names()
    assert all(len(ln.split(None, 1)) == 2 for ln in lines)  # name and a description
    for name in names:
        out = tmp_path / f"{name}.mcap"
        r = invoke("record", name, "--set", "duration=1", "-o", out)
        assert r.exit_code == 0, (name, r.output)
        assert out.stat().st_size > 0


@pytest.mark.parametrize("text,key", [
    (GOOD + "colour = 1\n", "colour"),
    (GOOD.replace('[[ships]]', '[contact]\ncrash_sped = 1\n[[ships]]'), "contact.crash_sped"),
    (GOOD.replace('id = "a"', 'id = "a"\nmas = 3'), "ships[0].mas"),
    (GOOD.replace("altitude = 1.0", "altitude = 1.0\nspin = 2"), "ships[0].initial.spin"),
    (GOOD.replace('name = "ok"', ""), "name"),
    (GOOD.replace("duration = 1.0", ""), "duration"),
    ('name = "x"\nduration = 1.0\n', "ships"),
    (GOOD.replace('id = "a"', 'player_id = "p"'), "ships[0].id"),
    (GOOD.replace('id = "a"', 'id = "a"\nmass = nan'), "ships[0].mass"),
    (GOOD.replace('id = "a"', 'id = "a"\nmass = inf'), "ships[0].mass"),
    (GOOD.replace('id = "a"', 'id = "a"\nmass = -5.0'), "ships[0].mass"),
    (GOOD.replace('id = "a"', 'id = "a"\nmass = "heavy"'), "ships[0].mass"),
    (GOOD.replace('id = "a"', 'id = "a"\nmass = true'), "ships[0].mass"),
    (GOOD.replace("[[ships]]", "[contact]\nfriction_kinetic = 0.9\n[[ships]]"),
     "contact.friction_kinetic"),
    (GOOD.replace("[[ships]]", "[contact]\nbounce_speed = 60.0\n[[ships]]"), "contact.bounce_speed"),
    (GOOD.replace("[[ships]]", '[sim]\nintegrator = "magic"\n[[ships]]'), "sim.integrator"),
    (GOOD.replace("altitude = 1.0\nvertical_speed = -3.0",
                  'state = "tipped"\ntilt_deg = 40.0'), "ships[0].initial.tilt_deg"),
    (GOOD + "[oops\n", "(syntax)"),
])
def test_bad_scenarios_exit_2_with_one_line_naming_file_and_key(tmp_path, text, key):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    out = tmp_path / "out.mcap"
    r = invoke("record", path, "-o", out)
    assert r.exit_code == 2, r.output
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.output
    assert "bad.toml" in lines[0] and key in lines[0], lines[0]
    assert not out.exists() and not Path(str(out) + ".partial").exists()


@pytest.mark.parametrize("args,needle", [
    (["no-such-scenario"], "no-such-scenario"),
    (["missing.toml"], "missing.toml"),
    (["bounce", "--set", "sim.dt=-1"], "sim.dt"),
    (["bounce", "--set", "nonsense.key=1"], "nonsense"),
    (["bounce", "--set", "novalue"], "novalue"),
])
def test_bad_arguments_exit_2(tmp_path, args, needle):
    out = tmp_path / "o.mcap"
    r = invoke("record", *args, "-o", out)
    assert r.exit_code == 2 and needle in r.output and "Traceback" not in r.output, r.output
    assert not out.exists()


def test_set_overrides_reach_the_run(tmp_path):
    out = tmp_path / "o.mcap"
    r = invoke("record", "bounce", "--set", "sim.dt=0.02", "--set", "ships[0].mass=9000",
               "--set", "duration=1", "-o", out)
    assert r.exit_code == 0, r.output
    rows = [json.loads(x) for x in invoke("export", out).output.splitlines()]
    assert rows[1]["t"] == pytest.approx(0.02)
    assert rows[0]["mass"] == 9000.0
    assert len(rows) == 51


EXPORT_FIELDS = {"tick", "t", "ship_id", "state", "altitude", "penetration", "tilt_deg", "v_radial",
                 "v_tangential", "normal_force", "friction_force", "fuel_mass",
                 "east", "north", "up", "v_east", "v_north", "v_up", "omega_x", "omega_y",
                 "omega_z", "energy_j"}
EVENT_FIELDS = {"event", "tick", "t", "ship_id", "player_id", "body", "from_state", "to_state"}


def test_export_gives_spec_fields_per_ship_per_tick_and_per_event(bounce_log, tmp_path):
    out = bounce_log
    rows = [json.loads(x) for x in invoke("export", out).output.splitlines()]
    assert len(rows) == 601 and all(EXPORT_FIELDS <= set(r) for r in rows)
    assert {r["state"] for r in rows} <= {"flying", "contact", "landed", "tipped", "crashed"}
    assert rows[-1]["state"] == "landed" and rows[0]["state"] == "flying"
    assert [r["tick"] for r in rows] == list(range(601))
    events = [json.loads(x) for x in invoke("export", out, "--events").output.splitlines()]
    assert all(EVENT_FIELDS <= set(e) for e in events)
    assert [e["event"] for e in events] == ["ship.contact", "ship.liftoff", "ship.contact",
                                           "ship.landed"]
    assert events[0]["player_id"] == "player-1" and events[0]["body"] == "Luna"
    file_out = tmp_path / "rows.jsonl"
    assert invoke("export", out, "-o", file_out).exit_code == 0
    assert file_out.read_text() == invoke("export", out).output


def test_export_places_the_ship_in_the_landing_site_frame_with_its_energy(tmp_path):
    """The bounce starts 5 m up (its feet), falling at 20 m/s, upright, over the site: east =
    north = 0, up = 5 m + com_height above the reference sphere (less 1.5 um: the feet, 2.26 m
    out, stand that much higher on the curved body), v_up = -20 m/s, no spin; energy_j = m v^2 / 2
    + m GM (1/R - 1/r). Speeds in the site frame match the positions' differences."""
    out = tmp_path / "b.mcap"
    assert invoke("record", "bounce", "--set", "duration=2", "-o", out).exit_code == 0
    rows = [json.loads(x) for x in invoke("export", out).output.splitlines()]
    first = rows[0]
    assert first["east"] == 0.0 and first["north"] == 0.0
    assert first["up"] == pytest.approx(8.0, abs=2e-6)
    assert (first["v_east"], first["v_north"], first["v_up"]) == (0.0, 0.0, -20.0)
    assert (first["omega_x"], first["omega_y"], first["omega_z"]) == (0.0, 0.0, 0.0)
    gm, radius = 4.9048695e12, 1737400.0
    r = radius + first["up"]
    assert first["energy_j"] == pytest.approx(0.5 * 1e4 * 400.0 + 1e4 * gm * (1 / radius - 1 / r),
                                              rel=1e-12)
    for a, b in zip(rows[0:3], rows[1:4]):  # falling freely (it lands at 0.24 s): mean speed
        assert (b["up"] - a["up"]) / 0.05 == pytest.approx(0.5 * (a["v_up"] + b["v_up"]), rel=1e-6)


def test_export_of_a_bad_file_is_one_line_exit_2(tmp_path):
    for name, data in (("missing.mcap", None), ("junk.mcap", b"not an mcap at all" * 50)):
        path = tmp_path / name
        if data is not None:
            path.write_bytes(data)
        r = invoke("export", path)
        assert r.exit_code == 2 and name in r.output and "Traceback" not in r.output
        assert len(r.output.strip().splitlines()) == 1


@pytest.mark.parametrize("cmd", [[], ["scenarios"], ["record"], ["export"], ["replay"], ["bench"]])
def test_every_command_has_help(cmd):
    r = invoke(*cmd, "--help")
    assert r.exit_code == 0 and "Usage" in r.output


BENCHES = ["speed", "replay", "accuracy", "stability", "physics", "fuzz", "serve", "envelope",
           "logs"]


@pytest.mark.parametrize("name", BENCHES)
def test_each_benchmark_is_a_subcommand_with_its_own_options(name):
    r = invoke("bench", name, "--help")
    assert r.exit_code == 0 and f"bench {name}" in r.output
    assert "--quick" in r.output
    assert ("--files" in r.output) == (name == "fuzz")  # fuzz's options are fuzz's alone
    assert ("--out " in r.output) == (name == "accuracy")
    if name != "fuzz":
        assert invoke("bench", name, "--files", "3").exit_code == 2  # no such option


@pytest.mark.slow
def test_both_entry_points_work(tmp_path):
    script = Path(sys.executable).with_name("touchdown")
    for argv in ([sys.executable, str(ROOT / "cli.py")], [str(script)]):
        r = subprocess.run(argv + ["scenarios"], capture_output=True, text=True, cwd=tmp_path,
                           timeout=60)
        assert r.returncode == 0 and "bounce" in r.stdout, r.stderr
        r = subprocess.run(argv + ["record", "nope"], capture_output=True, text=True,
                           cwd=tmp_path, timeout=60)
        assert r.returncode == 2 and "Traceback" not in r.stderr


@pytest.mark.slow
def test_ctrl_c_leaves_a_finished_log_of_what_was_simulated(tmp_path):
    out = tmp_path / "long.mcap"
    proc = subprocess.Popen([sys.executable, str(ROOT / "cli.py"), "record", "bounce", "--set",
                             "duration=100000", "-o", str(out)], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    partial = Path(str(out) + ".partial")
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not (partial.exists() and partial.stat().st_size > 20_000):
        time.sleep(0.1)
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    assert out.exists() and not partial.exists()
    with LogReader(out) as reader:
        assert reader.status.complete  # a finished MCAP: footer and summary
        # the tick numbers as the records say them, read as columns (logs.reader.blocks): a
        # TickData decodes one record in Python, ~0.3 ms, and half a second holds ~10^5 ticks
        ticks = np.concatenate([b.ticks.copy() for b in reader.blocks(wanted=())]).tolist()
        summary = reader.read_summary()
    assert ticks == list(range(len(ticks))) and len(ticks) > 10
    assert summary.complete is False and summary.reason == "interrupted"
    assert summary.last_tick == ticks[-1]
    r = invoke("replay", out, "--verify")
    assert r.exit_code == 0, r.output


@pytest.mark.slow
def test_progress_bar_on_a_terminal_and_quiet_otherwise(tmp_path):
    import os
    import pty
    out = tmp_path / "p.mcap"
    argv = [sys.executable, str(ROOT / "cli.py"), "record", "bounce", "--set", "duration=100",
            "-o", str(out)]
    pid, fd = pty.fork()
    if pid == 0:  # the child runs the command on the pseudo-terminal
        os.chdir(ROOT)
        os.execv(argv[0], argv)
    chunks = []
    while True:
        try:
            data = os.read(fd, 4096)
        except OSError:
            break
        if not data:
            break
        chunks.append(data)
    os.waitpid(pid, 0)
    shown = b"".join(chunks).decode(errors="replace")
    assert "ticks" in shown and "/2000" in shown.replace(" ", ""), shown[-500:]
    quiet = subprocess.run(argv, capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert quiet.returncode == 0 and "/2000" not in quiet.stdout.replace(" ", "")


def test_every_error_root_is_a_touchdown_error_with_its_exit_code():
    """One error base (sim.errors.TouchdownError) with an exit code, and one handler in the CLI
    (issue 26): each part's root derives from it."""
    from touchdown.logs import LogError
    from touchdown.replay.incident import Diverged
    from touchdown.service.serve import ServeError
    from touchdown.sim.errors import TouchdownError, UserError, WorkFailed
    from touchdown.sim.scenario import ScenarioError
    from touchdown.sim.timeline import CommandError
    from touchdown.sweep.cases import SweepError
    from touchdown.view.rerun_view import ViewError

    codes = {ScenarioError: 2, CommandError: 2, LogError: 2, ServeError: 2, SweepError: 2,
             UserError: 2, ViewError: 1, Diverged: 1, WorkFailed: 1}
    for cls, code in codes.items():
        assert issubclass(cls, TouchdownError) and cls.exit_code == code, cls
    assert issubclass(ScenarioError, ValueError) and issubclass(CommandError, ValueError)
    assert TouchdownError("x", exit_code=1).exit_code == 1


def test_the_one_handler_says_a_touchdown_error_in_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\nduration = 1.0\n[contact]\nfriction_static = -1.0\n'
                   '[[ships]]\nid = "a"\n')
    r = invoke("record", bad, "-o", tmp_path / "x.mcap")
    assert r.exit_code == 2 and "Traceback" not in r.output
    assert r.output.strip().splitlines() == [r.output.strip()]
    assert r.output.startswith("touchdown: ") and "friction_static" in r.output
