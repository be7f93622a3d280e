"""The Rerun view (issue 11), read back with Rerun's own reader: what a person would check on
screen, asserted on the .rrd that ``touchdown view -o`` writes."""
import json
import os
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
from click.testing import CliRunner

from touchdown.cli import main
from touchdown.sim.enums import SurfaceState
from touchdown.view.rerun_view import FORCE_COLORS, STATE_COLORS


def invoke(*args):
    r = CliRunner().invoke(main, [str(a) for a in args])
    assert r.exception is None or isinstance(r.exception, SystemExit), r.exception
    return r


def record(tmp, name, *sets, out=None):
    path = tmp / (out or f"{name}.mcap")
    args = [a for s in sets for a in ("--set", s)]
    r = invoke("record", name, *args, "-o", path)
    assert r.exit_code == 0, r.output
    return path


def exported(log):
    r = invoke("export", log)
    assert r.exit_code == 0, r.output
    return [json.loads(line) for line in r.stdout.splitlines()]


def rrd(path) -> dict[str, dict[str, list]]:
    """entity -> {component column or "tick" -> values over the tick timeline (static data under
    "static:" + column)}, from Rerun's own reader."""
    import rerun.chunk as rc

    out: dict[str, dict[str, list]] = {}
    per_entity: dict[str, list[pa.RecordBatch]] = {}
    for ch in rc.RrdReader(path).stream().to_chunks():
        rb = ch.to_record_batch()
        ent = out.setdefault(ch.entity_path, {})
        if ch.is_static:
            for name in rb.schema.names:
                if ":" in name:
                    ent["static:" + name] = rb.column(name).to_pylist()
            continue
        per_entity.setdefault(ch.entity_path, []).append(rb)
    for path_, batches in per_entity.items():
        rows = []
        for rb in batches:
            cols = {n: rb.column(n).to_pylist() for n in rb.schema.names}
            for k in range(rb.num_rows):
                rows.append({n: v[k] for n, v in cols.items()})
        rows.sort(key=lambda r: r["tick"])
        ent = out[path_]
        for name in rows[0]:
            if name == "tick" or ":" in name:
                ent[name] = [r.get(name) for r in rows]
    return out


@pytest.fixture(scope="module")
def topple(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("view")
    log = record(tmp, "topple")
    out = tmp / "topple.rrd"
    r = invoke("view", log, "-o", out)
    assert r.exit_code == 0, r.output
    assert "301 ship-ticks" in r.output and out.exists() and not Path(f"{out}.partial").exists()
    return log, rrd(out)


def scalars(ent):
    return np.array([v[0] for v in ent["Scalars:scalars"]])


def test_the_view_holds_the_scene_plots_status_and_events(topple):
    _, got = topple
    for entity in ("/world", "/world/surface", "/world/lander-1/ship",
                   "/world/lander-1/ship/descent_stage", "/world/lander-1/ship/legs",
                   "/world/lander-1/ship/footprint", "/world/lander-1/trajectory",
                   "/world/lander-1/forces/normal", "/world/lander-1/forces/friction",
                   "/world/lander-1/forces/weight", "/world/lander-1/forces/thrust",
                   "/plots/altitude/lander-1/altitude_m", "/plots/altitude/lander-1/penetration_m",
                   "/plots/tilt/lander-1/tilt_deg", "/plots/tilt/limits/tipped_angle",
                   "/plots/tilt/limits/critical_toward_foot", "/plots/speed/limits/bounce_speed",
                   "/plots/speed/limits/crash_speed", "/plots/force/lander-1/normal_force_n",
                   "/plots/energy/lander-1/energy_j", "/plots/energy/lander-1/spring_j",
                   "/plots/fuel/lander-1/fuel_kg", "/status/lander-1", "/hud/lander-1",
                   "/events/log", "/legend"):
        assert entity in got, entity


def test_plotted_values_are_the_log_s(topple):
    log, got = topple
    rows = exported(log)
    assert got["/plots/altitude/lander-1/altitude_m"]["tick"] == [r["tick"] for r in rows]
    for entity, field in (("altitude/lander-1/altitude_m", "altitude"),
                          ("altitude/lander-1/penetration_m", "penetration"),
                          ("tilt/lander-1/tilt_deg", "tilt_deg"),
                          ("speed/lander-1/v_radial_mps", "v_radial"),
                          ("force/lander-1/normal_force_n", "normal_force"),
                          ("force/lander-1/friction_force_n", "friction_force"),
                          ("fuel/lander-1/fuel_kg", "fuel_mass")):
        np.testing.assert_array_equal(scalars(got["/plots/" + entity]),
                                      [r[field] for r in rows], err_msg=entity)
    # energy_j and the parts it is the sum of
    energy = scalars(got["/plots/energy/lander-1/energy_j"])
    np.testing.assert_allclose(energy, [r["energy_j"] for r in rows], rtol=1e-12)
    parts = sum(scalars(got[f"/plots/energy/lander-1/{p}"]) for p in (
        "translational_j", "rotational_j", "gravity_j", "centrifugal_j", "centrifugal_spin_j",
        "spring_j"))
    np.testing.assert_allclose(parts, energy, rtol=1e-9, atol=1e-6)
    # the ship's pose, in the landing-site frame (float32, as Rerun stores it)
    xyz = np.array(got["/world/lander-1/ship"]["Transform3D:translation"]).reshape(-1, 3)
    np.testing.assert_allclose(xyz, [[r["east"], r["north"], r["up"]] for r in rows],
                               atol=1e-6, rtol=1e-6)


def test_the_status_wears_the_seed_s_colours(topple):
    log, got = topple
    rows = exported(log)
    status = got["/status/lander-1"]
    states = [r["state"].upper() for r in rows]
    changes = [k for k in range(len(states)) if k == 0 or states[k] != states[k - 1]]
    assert status["tick"] == [rows[k]["tick"] for k in changes]
    assert [v[0] for v in status["StateChange:state"]] == [states[k] for k in changes]
    assert [v[0] for v in status["StateChange:state"]] == ["FLYING", "CONTACT", "TIPPED"]

    def rgba(c):
        return (c[0] << 24) | (c[1] << 16) | (c[2] << 8) | 255
    config = status["static:StateConfiguration:values"], status["static:StateConfiguration:colors"]
    colour_of = dict(zip(config[0][0], config[1][0]))
    assert colour_of["CONTACT"] == rgba((255, 210, 0))  # the seed's yellow
    assert colour_of["TIPPED"] == rgba((230, 40, 40))  # the seed's red
    # the 3D descent stage and the event log use the same colours
    stage = got["/world/lander-1/ship/descent_stage"]
    assert [v[0] for v in stage["Boxes3D:colors"]] == [
        rgba(STATE_COLORS[SurfaceState[s]]) for s in (states[k] for k in changes)]
    events = got["/events/log"]
    assert [v[0] for v in events["TextLog:text"]][1].count("ship.tipped") == 1
    assert events["TextLog:color"][1][0] == rgba((230, 40, 40))
    assert [v[0] for v in events["TextLog:level"]] == ["INFO", "WARN"]
    # the HUD of the seed's client display: TIPPED, the tilt large, the hint
    hud = got["/hud/lander-1"]
    last = hud["TextDocument:text"][-1][0]
    assert last.startswith("# TIPPED") and "## Tilt" in last
    assert "Use RCS rotation to right the ship" in last
    assert got["/world/lander-1/forces/normal"]["static:Arrows3D:colors"][0][0] == rgba(
        FORCE_COLORS["normal"])


def test_force_arrows_scale_with_the_weight_as_the_legend_says(topple):
    log, got = topple
    rows = exported(log)
    h = 3.0  # the topple lander's com_height
    normal = np.array(got["/world/lander-1/forces/normal"]["Arrows3D:vectors"]).reshape(-1, 3)
    weight = np.array(got["/world/lander-1/forces/weight"]["Arrows3D:vectors"]).reshape(-1, 3)
    # the weight is one com_height long and points down
    np.testing.assert_allclose(np.linalg.norm(weight, axis=1), h, rtol=1e-5)
    assert (weight[:, 2] < 0).all()
    # the normal force: com_height * log2(1 + N / W), W = m g
    g = 4.9048695e12 / 1737400.0 ** 2
    n = np.array([r["normal_force"] for r in rows])
    m = np.array([r["mass"] for r in rows])
    np.testing.assert_allclose(np.linalg.norm(normal, axis=1), h * np.log2(1 + n / (m * g)),
                               rtol=2e-4, atol=1e-6)


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("pair")
    a = record(tmp, "bounce", "duration=4", out="bug.mcap")
    b = tmp / "whatif.mcap"
    r = invoke("replay", a, "--set", "sim.dt=0.02", "-o", b)
    assert r.exit_code == 0, r.output
    out = tmp / "pair.rrd"
    r = invoke("view", a, b, "-o", out)
    assert r.exit_code == 0, r.output
    return a, b, rrd(out)


def test_two_runs_side_by_side_on_the_same_axes(pair):
    a, b, got = pair
    for label in ("bug", "whatif"):
        assert f"/world/{label}/lander-1/ship" in got
        assert f"/world/{label}/lander-1/trajectory" in got
        alt = got[f"/plots/altitude/{label}/lander-1/altitude_m"]
        assert alt["static:SeriesLines:names"][0][0] == f"{label}: lander-1 altitude"
        assert f"/status/{label}/lander-1" in got and f"/events/{label}" in got
    # each run's own ticks: the what-if took 0.02 s ticks, the bug report 0.05 s
    assert len(got["/plots/altitude/bug/lander-1/altitude_m"]["tick"]) == 81
    assert len(got["/plots/altitude/whatif/lander-1/altitude_m"]["tick"]) == 201
    np.testing.assert_array_equal(scalars(got["/plots/altitude/whatif/lander-1/altitude_m"]),
                                  [r["altitude"] for r in exported(b)])
    # the two runs' lines differ in colour
    colours = {got[f"/plots/altitude/{x}/lander-1/altitude_m"]["static:SeriesLines:colors"][0][0]
               for x in ("bug", "whatif")}
    assert len(colours) == 2


def test_a_fleet_has_a_tree_per_ship_and_one_can_be_picked(tmp_path):
    log = record(tmp_path, "fleet", "duration=1")
    ids = sorted({r["ship_id"] for r in exported(log)})
    assert len(ids) > 1
    out = tmp_path / "fleet.rrd"
    assert invoke("view", log, "-o", out).exit_code == 0
    got = rrd(out)
    for ship in ids:
        assert f"/world/{ship}/ship" in got and f"/plots/tilt/{ship}/tilt_deg" in got
    one = tmp_path / "one.rrd"
    assert invoke("view", log, "--ship", ids[1], "-o", one).exit_code == 0
    got = rrd(one)
    assert f"/world/{ids[1]}/ship" in got
    assert not any(f"/world/{s}/ship" in got for s in ids if s != ids[1])
    r = invoke("view", log, "--ship", "nobody", "-o", tmp_path / "x.rrd")
    assert r.exit_code == 2 and "no ship 'nobody'" in r.output and len(r.output.splitlines()) == 1
    assert not (tmp_path / "x.rrd").exists()


def test_bad_input_is_one_line_and_a_cut_log_is_announced(tmp_path, bounce_log):
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not a log at all")
    r = invoke("view", junk, "-o", tmp_path / "j.rrd")
    assert r.exit_code == 2 and len(r.output.splitlines()) == 1 and "junk.mcap" in r.output
    assert not (tmp_path / "j.rrd").exists() and not (tmp_path / "j.rrd.partial").exists()
    r = invoke("view", junk, "-o", tmp_path / "j.png")
    assert r.exit_code == 2 and ".rrd" in r.output
    data = bounce_log.read_bytes()  # the built-in bounce, 30 s (tests/conftest.py)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    r = invoke("view", cut, "-o", tmp_path / "cut.rrd")
    assert r.exit_code == 0 and "read only part of the log" in r.output


def _software_vulkan() -> bool:
    icd = Path("/usr/share/vulkan/icd.d")
    return icd.is_dir() and any(p.name.startswith("lvp") for p in icd.iterdir())


def test_a_screenshot_without_a_display(tmp_path, topple):
    """Rerun's headless viewer on software Vulkan: .ci/run installs Debian's mesa-vulkan-drivers;
    in CI a missing driver fails, elsewhere it skips with the reason."""
    if not _software_vulkan():
        if os.environ.get("CI") == "true":
            pytest.fail("software Vulkan (mesa-vulkan-drivers) is missing in CI")
        pytest.skip("no software Vulkan: apt install mesa-vulkan-drivers")
    log, _ = topple
    png = tmp_path / "topple.png"
    r = invoke("view", log, "--screenshot", png, "--at", "4.6")
    assert r.exit_code == 0, r.output
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    assert (width, height) == (1920, 1080)
    assert len(data) > 100_000  # a drawn view, not a blank one


def test_record_and_replay_view_their_run_or_say_why_not(tmp_path, monkeypatch):
    """With no display the viewer cannot open a window: one line naming the way out, exit 1,
    and the log itself is written."""
    for var in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"):
        monkeypatch.delenv(var, raising=False)
    log = tmp_path / "b.mcap"
    r = invoke("record", "bounce", "--set", "duration=1", "-o", log, "--view")
    assert log.exists() and r.exit_code == 1, r.output
    assert "-o OUT.rrd" in r.output.splitlines()[-1] and "Traceback" not in r.output
    r = invoke("replay", log, "--set", "sim.dt=0.02", "--view")
    assert r.exit_code == 1 and "could not open a window" in r.output.splitlines()[-1]


FAR = """
name = "far"
duration = 3.0
[[ships]]
id = "near"
[ships.initial]
altitude = 1.0
[[ships]]
id = "far"
spawn_t = 1.5
[ships.initial]
altitude = 1.0
east = 800.0
north = -300.0
"""


def test_the_fleet_view_keeps_every_ship_in_frame(tmp_path):
    """Issue 37: a ship 850 m away that joins halfway was left out of frame (a view framed by
    what it showed when it opened). The fleet view's and the site view's cameras now hold every
    ship's every sampled position (and every drawn ship's feet) in a 20-degree cone about their
    line of sight, over the whole run; the saved layout carries those cameras."""
    import rerun.blueprint as rrb

    from touchdown.view import rerun_view as rv
    from touchdown.view.scene import EYE_HALF_ANGLE_DEG, framing_eye, read_run
    scn = tmp_path / "far.toml"
    scn.write_text(FAR)
    log = tmp_path / "far.mcap"
    assert invoke("record", scn, "-o", log).exit_code == 0
    run = read_run(log)
    ships = run.overview.pos_site_m
    assert ships[:, 0].max() > 790 and ships[:, 1].min() < -290
    feet = np.concatenate([t.feet_site_m.reshape(-1, 3) for t in run.ships])
    views = {}

    def walk(node):
        if isinstance(node, rrb.Spatial3DView):
            views[node.origin] = node
        for c in getattr(node, "contents", None) or []:
            if not isinstance(c, str):
                walk(c)
    walk(rv.blueprint(rv.Layout((run,))).root_container)
    for origin, pts in (("fleet", ships), ("world", feet)):
        eye, target = framing_eye(pts)
        sight = (target - eye) / np.linalg.norm(target - eye)
        to = pts - eye
        angles = np.degrees(np.arccos(np.clip(to @ sight / np.linalg.norm(to, axis=1), -1, 1)))
        assert angles.max() <= EYE_HALF_ANGLE_DEG + 1e-9, (origin, angles.max())
        assert str(views[origin].origin) == origin and "EyeControls3D" in views[origin].properties
    assert invoke("view", log, "-o", tmp_path / "far.rrd").exit_code == 0
