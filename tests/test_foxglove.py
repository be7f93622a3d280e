"""Foxglove-ready logs (issue 37, item 1): ``touchdown export LOG --format foxglove`` writes
Foxglove's published schemas; every message decodes with the published classes
(foxglove-schemas-protobuf), every ship's transform is its logged position and attitude
(checked against the raw log by scipy's rotations, not by the code that wrote it), the landers
wear their state's colour, the values are addressed by ship id, and the committed layout opens
the channels the export writes."""
from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from mcap.reader import make_reader
from mcap_protobuf.schema import build_file_descriptor_set
from scipy.spatial.transform import Rotation

from touchdown.cli import main
from touchdown.logs.reader import LogReader
from touchdown.proto import views_pb2
from touchdown.sim.enums import SurfaceState
from touchdown.view import foxglove as fx
from touchdown.view.foxglove_layout import layout_json
from touchdown.view.scene import STATE_COLORS

ROOT = Path(__file__).resolve().parents[1]
FLEET = ROOT / "tests" / "data" / "golden" / "fleet.toml"
CLASSES = {fx.TOPIC_TRANSFORMS: FrameTransforms, fx.TOPIC_LANDERS: SceneUpdate,
           fx.TOPIC_GROUND: SceneUpdate, fx.TOPIC_EVENTS: Log,
           fx.TOPIC_SHIPS: views_pb2.FleetValues}


def invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """The golden fleet (a ship joins, one leaves, commands) on a turning body, recorded, and
    its Foxglove export, decoded by topic with the published classes."""
    tmp = tmp_path_factory.mktemp("foxglove")
    log, out = tmp / "fleet.mcap", tmp / "fleet-foxglove.mcap"
    r = invoke("record", FLEET, "--set", "body.rotation_period=7200", "-o", log)
    assert r.exit_code == 0, r.output
    r = invoke("export", log, "--format", "foxglove", "-o", out)
    assert r.exit_code == 0, r.output
    by_topic: dict[str, list] = {}
    with open(out, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        for schema, channel, message in reader.iter_messages():
            cls = CLASSES[channel.topic]
            assert schema.name == cls.DESCRIPTOR.full_name and schema.encoding == "protobuf"
            assert schema.data == build_file_descriptor_set(cls).SerializeToString()
            assert message.log_time == message.publish_time
            by_topic.setdefault(channel.topic, []).append(
                (message.log_time, cls.FromString(message.data)))
    return log, out, by_topic, summary


def _rows(log):
    r = invoke("export", log)
    assert r.exit_code == 0
    return [json.loads(line) for line in r.output.splitlines()]


def test_every_channel_decodes_with_foxglove_published_schemas(exported):
    log, out, by_topic, summary = exported
    assert set(by_topic) == set(fx.SCHEMAS)
    with LogReader(log) as r:
        n_ticks = sum(1 for _ in r.ticks())
    assert len(by_topic[fx.TOPIC_TRANSFORMS]) == len(by_topic[fx.TOPIC_SHIPS]) == n_ticks
    assert len(by_topic[fx.TOPIC_GROUND]) == 1
    r = invoke("doctor", out)
    assert r.exit_code == 0 and "verdict: ok" in r.stdout, r.stdout


def _site(p, theta, radius):
    """An inertial position in the landing-site frame (east, north, up), independently: the
    body turned by theta about z, its x axis through the site (sim.frames)."""
    c, s = math.cos(theta), math.sin(theta)
    x, y = c * p[0] + s * p[1], -s * p[0] + c * p[1]
    return np.array([y, p[2], x - radius])


def test_every_ships_transform_is_its_logged_position_and_attitude(exported):
    """Per tick and ship: parent ``site``, child the ship's id, stamped with the simulated
    time (the log time), the translation its logged centre of mass in the site frame (to
    rounding, computed here from the raw inertial position and the body's turn), the rotation
    its logged attitude: each body axis, turned by the transform's rotation, is the logged
    attitude's axis in the site frame."""
    log, _out, by_topic, _summary = exported
    with LogReader(log) as r:
        params = json.loads(r.scenario.resolved_json)
        dt = r.scenario.dt_s
        ids = r.ship_table().ids
        logged = {td.tick: (td.keys.tolist(), td.vec("pos_m", 3), td.vec("quat", 4))
                  for td in r.ticks()}
    radius = params["body"]["radius"]
    omega = 2 * math.pi / params["body"]["rotation_period"]
    checked = 0
    for t_ns, msg in by_topic[fx.TOPIC_TRANSFORMS]:
        tick = round(t_ns / (dt * 1e9))
        keys, pos, quat = logged[tick]
        assert [tr.child_frame_id for tr in msg.transforms] == [ids[k] for k in keys]
        theta = omega * tick * dt
        turn = Rotation.from_euler("z", -theta)
        to_site = Rotation.from_matrix([[0, 1, 0], [0, 0, 1], [1, 0, 0]])  # (x,y,z) -> (y,z,x)
        for tr, p, q in zip(msg.transforms, pos, quat):
            assert tr.parent_frame_id == fx.SITE_FRAME
            assert tr.timestamp.seconds * 10**9 + tr.timestamp.nanos == t_ns
            got = np.array([tr.translation.x, tr.translation.y, tr.translation.z])
            assert np.allclose(got, _site(p, theta, radius), rtol=0, atol=1e-6), (tick, got)
            fox = Rotation.from_quat([tr.rotation.x, tr.rotation.y, tr.rotation.z,
                                      tr.rotation.w])
            body = to_site * turn * Rotation.from_quat([q[1], q[2], q[3], q[0]])
            assert np.allclose(fox.as_matrix(), body.as_matrix(), atol=1e-12), tick
            checked += 1
    assert checked > 100


def test_the_transforms_tilt_and_position_are_the_exports(exported):
    """The same numbers as the export's columns (one source of truth): east, north, up bit for
    bit, the tilt of the transform's z axis from local vertical within 1e-9 degree."""
    log, _out, by_topic, _summary = exported
    rows = {(row["tick"], row["ship_id"]): row for row in _rows(log)}
    dt = 0.05
    for t_ns, msg in by_topic[fx.TOPIC_TRANSFORMS]:
        tick = round(t_ns / (dt * 1e9))
        for tr in msg.transforms:
            row = rows[(tick, tr.child_frame_id)]
            assert (tr.translation.x, tr.translation.y, tr.translation.z) == (
                row["east"], row["north"], row["up"])
            z = Rotation.from_quat([tr.rotation.x, tr.rotation.y, tr.rotation.z,
                                    tr.rotation.w]).apply([0, 0, 1])
            p = np.array([row["east"], row["north"], row["up"] + 1737400.0])
            up = p / np.linalg.norm(p)
            tilt = math.degrees(math.acos(max(-1.0, min(1.0, float(z @ up)))))
            assert abs(tilt - row["tilt_deg"]) < 1e-6, (tick, tr.child_frame_id)


def test_values_are_addressed_by_ship_id_across_joins_and_leaves(exported):
    """FleetValues name each ship: a ship's altitude found by its id at every tick is the
    export's, though its place in the array changes as ships join and leave."""
    log, _out, by_topic, _summary = exported
    rows = {(row["tick"], row["ship_id"]): row for row in _rows(log)}
    places = {}
    for t_ns, msg in by_topic[fx.TOPIC_SHIPS]:
        assert msg.t * 1e9 == pytest.approx(t_ns)
        for i, s in enumerate(msg.ships):
            row = rows[(msg.tick, s.ship_id)]
            assert s.state == row["state"]
            for name in fx.VALUE_FIELDS:
                assert getattr(s, name) == row[name], (msg.tick, s.ship_id, name)
            places.setdefault(s.ship_id, set()).add(i)
    assert any(len(p) > 1 for p in places.values()), places  # a ship moved in the array
    assert {sid for _t, sid in rows} == set(places)


def test_landers_are_drawn_in_their_frames_in_their_states_colour(exported):
    """Each SceneUpdate holds every ship present then (frame-locked in its own frame, the
    descent stage in its state's colour at that tick, four legs, its footprint) and deletes
    those that left; the first is at the first tick."""
    log, _out, by_topic, _summary = exported
    rows = {(row["tick"], row["ship_id"]): row for row in _rows(log)}
    present: dict[int, set] = {}
    for tick, sid in rows:
        present.setdefault(tick, set()).add(sid)
    updates = by_topic[fx.TOPIC_LANDERS]
    assert updates[0][0] == 0
    seen_delete = False
    for t_ns, msg in updates:
        tick = round(t_ns / 5e7)
        assert {e.id for e in msg.entities} == present[tick], tick
        for e in msg.entities:
            assert e.frame_id == e.id and e.frame_locked
            state = SurfaceState[rows[(tick, e.id)]["state"].upper()]
            rgb = tuple(round(c * 255) for c in (e.cubes[0].color.r, e.cubes[0].color.g,
                                                 e.cubes[0].color.b))
            assert rgb == STATE_COLORS[state]
            legs = e.lines[0]
            assert legs.type == legs.LINE_LIST and len(legs.points) == 8
            feet = {(p.x, p.y, p.z) for p in legs.points[1::2]}
            assert len(feet) == 4 and len({round(p[2], 9) for p in feet}) == 1
        seen_delete |= bool(msg.deletions)
    assert seen_delete  # the ship that left is taken off the scene


def test_events_are_foxglove_logs_named_by_ship(exported):
    log, _out, by_topic, _summary = exported
    r = invoke("export", log, "--events")
    events = [json.loads(line) for line in r.output.splitlines()]
    logs = by_topic[fx.TOPIC_EVENTS]
    assert len(logs) == len(events) > 0
    for (t_ns, lg), ev in zip(logs, events):
        assert lg.name == ev["ship_id"] and ev["event"] in lg.message
        stamp = lg.timestamp.seconds + lg.timestamp.nanos * 1e-9
        assert stamp == pytest.approx(ev["t_event"], abs=1e-9)
        assert lg.level == (Log.ERROR if ev["to_state"] == "crashed" else
                            Log.WARNING if ev["to_state"] == "tipped" else Log.INFO)


def test_the_committed_layout_is_the_code_and_opens_the_exports_channels(exported):
    """docs/foxglove-layout.json (Foxglove's layout format, built with the SDK's typed classes)
    is what view.foxglove_layout builds; every topic it names is a channel of the export, every
    field it plots is a ShipValues field, and its 3-D panel is in the transforms' parent frame."""
    _log, _out, by_topic, summary = exported
    committed = (ROOT / "docs" / "foxglove-layout.json").read_text()
    assert committed == layout_json(), "run: python -m touchdown.view.foxglove_layout"
    doc = json.loads(committed)
    text = json.dumps(doc)
    topics = {c.topic for c in summary.channels.values()}
    named = set(re.findall(r'"(/foxglove/[a-z]+)', text)) | set(
        re.findall(r'(/foxglove/[a-z]+)\.', text))
    assert named and named <= topics, named - topics
    fields = {f.name for f in views_pb2.ShipValues.DESCRIPTOR.fields}
    plotted = re.findall(r"\{ship_id==\$ship\}\.([a-z_]+)", text)
    assert plotted and set(plotted) <= fields
    panels = []

    def walk(node):
        if isinstance(node, dict):
            if node.get("type") == "panel":
                panels.append(node)
            for v in node.values():
                walk(v)
        elif isinstance(node, list):
            for v in node:
                walk(v)
    walk(doc["content"])
    kinds = {p["panelType"] for p in panels}
    assert {"ThreeDee", "Plot", "Log", "StateTransitions"} <= kinds
    three_d = next(p for p in panels if p["panelType"] == "ThreeDee")["config"]
    assert three_d["followTf"] == three_d["fixedFrame"] == fx.SITE_FRAME
    assert all(tr.parent_frame_id == three_d["followTf"]
               for tr in by_topic[fx.TOPIC_TRANSFORMS][0][1].transforms)


def test_the_fast_encoders_write_what_protobuf_writes():
    """The per-tick messages put together as bytes decode to the same messages as protobuf's
    own, for ids of every length, every state, zeros and signed zeros."""
    enc = fx.FleetEncoder()
    ids = ["a", "ship-1", "x" * 200, "é-ü"]
    enc.ids(ids)
    keys = np.array([0, 1, 2, 3, 3, 1], np.int64)
    counts = np.array([4, 2])
    rng = np.random.default_rng(1)
    pos = rng.normal(size=(6, 3)) * 1e3
    pos[0] = 0.0
    pos[1, 0] = -0.0
    quat = rng.normal(size=(6, 4))
    msgs = enc.transforms([0, 2_345_000_001], counts, keys, pos, quat)
    for k, (lo, hi) in enumerate(((0, 4), (4, 6))):
        ref = FrameTransforms()
        for r in range(lo, hi):
            tr = ref.transforms.add(parent_frame_id="site", child_frame_id=ids[keys[r]])
            tr.timestamp.FromNanoseconds([0, 2_345_000_001][k])
            tr.translation.x, tr.translation.y, tr.translation.z = pos[r]
            tr.rotation.x, tr.rotation.y, tr.rotation.z, tr.rotation.w = quat[r]
        assert FrameTransforms.FromString(msgs[k]) == ref
    states = np.array([0, 1, 2, 3, 4, 0])
    cols = {name: rng.normal(size=6) for name in fx.VALUE_FIELDS}
    cols["altitude"][2] = 0.0
    msgs = enc.values([0, 7], [0.0, 0.35], counts, keys, states, cols)
    got = views_pb2.FleetValues.FromString(msgs[1])
    assert got.tick == 7 and got.t == 0.35 and [s.ship_id for s in got.ships] == [ids[3], ids[1]]
    assert got.ships[1].state == "flying" and got.ships[1].mass == cols["mass"][5]
    first = views_pb2.FleetValues.FromString(msgs[0])
    assert first.ships[2].HasField("altitude") and first.ships[2].altitude == 0.0
