"""The live view in Foxglove (issue 37): ``touchdown view --redis URL --foxglove PORT`` serves a
running service's fleet over Foxglove's WebSocket protocol. A real service (``touchdown serve``,
a subprocess, on a real Redis under a key prefix of its own) runs; the test connects as
Foxglove connects (the SDK's server speaks ``foxglove.sdk.v1``, the successor of
``foxglove.websocket.v1`` with the same messages; the ``websockets`` client),
subscribes to every channel and decodes what arrives with Foxglove's published classes, and
holds it to what the service put on its telemetry stream (read back from Redis)."""
from __future__ import annotations

import base64
import json
import math
import os
import re
import signal
import struct
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np
import pytest
import redis
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from mcap_protobuf.schema import build_file_descriptor_set
from websockets.sync.client import connect

from redis_server import redis_url  # noqa: F401 - the fixture
from redis_server import remove_prefix
from touchdown.proto import service_pb2 as spb
from touchdown.proto import views_pb2
from touchdown.sim import measure
from touchdown.sim.enums import SurfaceState
from touchdown.sim.scenario import parse_text
from touchdown.view import foxglove as fx
from touchdown.view.foxglove_live import site_of
from touchdown.view.scene import STATE_COLORS

pytestmark = pytest.mark.redis

ROOT = Path(__file__).resolve().parents[1]
CLASSES = {fx.TOPIC_TRANSFORMS: FrameTransforms, fx.TOPIC_LANDERS: SceneUpdate,
           fx.TOPIC_GROUND: SceneUpdate, fx.TOPIC_EVENTS: Log,
           fx.TOPIC_SHIPS: views_pb2.FleetValues}
SCENE = """
name = "live-foxglove"
duration = 600.0
[body]
rotation_period = 86400.0
[[ships]]
id = "s1"
[ships.initial]
altitude = 2.0
vertical_speed = -3.0
[[ships]]
id = "s2"
[ships.initial]
altitude = 6.0
vertical_speed = -2.0
horizontal_speed = 1.0
[[ships]]
id = "s3"
leg_radius = 3.0
com_height = 2.5
[ships.initial]
altitude = 0.5
"""


def _cli(*args: str) -> list[str]:
    return [sys.executable, str(ROOT / "cli.py"), *args]


def _wait(pred, seconds: float, what: str) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if pred():
            return
        time.sleep(0.1)
    raise AssertionError(f"timed out waiting for {what}")


@pytest.fixture
def service(redis_url, tmp_path):  # noqa: F811
    prefix = f"test:foxglove:{uuid.uuid4().hex[:10]}"
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE)
    err = open(tmp_path / "serve.err", "w")
    proc = subprocess.Popen(_cli("serve", "--redis", redis_url, "--prefix", prefix,
                                 "--scenario", str(scene), "--rate", "20",
                                 "--telemetry-hz", "10", "--shards", "2",
                                 "--log-dir", str(tmp_path / "flight")),
                            stdout=subprocess.DEVNULL, stderr=err)
    client = redis.Redis.from_url(redis_url)
    try:
        _wait(lambda: proc.poll() is None and client.xlen(f"{prefix}:telemetry") > 3, 120,
              "the service's telemetry")
        yield redis_url, prefix, scene, client
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
        err.close()
        client.close()
        remove_prefix(redis_url, prefix)


def test_foxglove_connects_to_a_running_service_and_sees_its_fleet(service, tmp_path):
    url, prefix, scene_path, client = service
    err_path = tmp_path / "view.err"
    with open(err_path, "w") as err:
        view = subprocess.Popen(_cli("view", "--redis", url, "--prefix", prefix,
                                     "--foxglove", "0", "--seconds", "12"),
                                stdout=subprocess.PIPE, stderr=err, text=True)
        port = None
        end = time.monotonic() + 60
        while port is None and time.monotonic() < end and view.poll() is None:
            found = re.search(r"ws://127\.0\.0\.1:(\d+)", err_path.read_text())
            port = int(found.group(1)) if found else None
            time.sleep(0.1)
        assert port, err_path.read_text()
        received: dict[str, list] = {}
        times = []
        with connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1", "foxglove.websocket.v1"],
                     open_timeout=20) as ws:
            assert ws.subprotocol == "foxglove.sdk.v1"
            info = json.loads(ws.recv(timeout=20))
            assert info["op"] == "serverInfo" and "time" in info["capabilities"]
            channels = {}
            while len(channels) < len(fx.SCHEMAS):
                msg = ws.recv(timeout=20)
                if isinstance(msg, str) and json.loads(msg)["op"] == "advertise":
                    for ch in json.loads(msg)["channels"]:
                        channels[ch["id"]] = ch
            by_topic = {ch["topic"]: ch for ch in channels.values()}
            assert set(by_topic) == set(fx.SCHEMAS)
            for topic, ch in by_topic.items():
                cls = CLASSES[topic]
                assert ch["encoding"] == "protobuf" and ch["schemaName"] == cls.DESCRIPTOR.full_name
                assert base64.b64decode(ch["schema"]) == \
                    build_file_descriptor_set(cls).SerializeToString()
            subs = {k: ch["topic"] for k, ch in enumerate(channels.values())}
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                {"id": k, "channelId": ch["id"]} for k, ch in enumerate(channels.values())]}))
            end = time.monotonic() + 8
            while time.monotonic() < end:
                try:
                    msg = ws.recv(timeout=1)
                except TimeoutError:
                    continue
                if isinstance(msg, str):
                    continue
                if msg[0] == 0x01:
                    sub, t_ns = struct.unpack_from("<IQ", msg, 1)
                    topic = subs[sub]
                    received.setdefault(topic, []).append(
                        (t_ns, CLASSES[topic].FromString(msg[13:])))
                elif msg[0] == 0x02:
                    times.append(struct.unpack_from("<Q", msg, 1)[0])
        view.wait(timeout=60)
    assert view.returncode == 0, err_path.read_text()
    assert "Foxglove messages" in view.stdout.read()

    # what the service published, read back: (tick, ship) -> its sample
    samples = {}
    for _id, fields in client.xrange(f"{prefix}:telemetry"):
        s = spb.Telemetry.FromString(fields[b"proto"])
        for i, sid in enumerate(s.ship_ids):
            samples[(round(s.t_s * 1e9), sid)] = (np.array(s.pos_m[3 * i:3 * i + 3]),
                                                  np.array(s.vel_mps[3 * i:3 * i + 3]),
                                                  s.state[i], s.altitude_m[i], s.cos_tilt[i],
                                                  s.t_s)
    params = parse_text(scene_path.read_text(), "scene").params
    assert set(received) >= {fx.TOPIC_TRANSFORMS, fx.TOPIC_SHIPS, fx.TOPIC_LANDERS,
                             fx.TOPIC_GROUND}, set(received)
    assert times and times == sorted(times)  # the clock is the simulation's

    # every transform: from site to the ship's frame, the sample's centre of mass in the site
    # frame (sim.measure.site_frame on the sample), upright on the local vertical
    n = 0
    for t_ns, msg in received[fx.TOPIC_TRANSFORMS]:
        for tr in msg.transforms:
            p, v, _st, _alt, _c, t_s = samples[(t_ns, tr.child_frame_id)]
            pos, _vel = measure.site_frame(params, p[None, :], v[None, :], t_s)
            assert tr.parent_frame_id == fx.SITE_FRAME
            assert tr.timestamp.seconds * 10**9 + tr.timestamp.nanos == t_ns
            got = np.array([tr.translation.x, tr.translation.y, tr.translation.z])
            assert np.allclose(got, pos[0], rtol=0, atol=1e-6)
            q = (tr.rotation.x, tr.rotation.y, tr.rotation.z, tr.rotation.w)
            z = np.array([2 * (q[0] * q[2] + q[3] * q[1]), 2 * (q[1] * q[2] - q[3] * q[0]),
                          1 - 2 * (q[0] ** 2 + q[1] ** 2)])
            up = got + [0, 0, params.body.radius_m]
            assert np.allclose(z, up / np.linalg.norm(up), atol=1e-12)
            n += 1
    assert n >= 6

    # the values by ship id: state, altitude, tilt as the sample's; site velocity as measure's;
    # no forces (telemetry holds none): absent, not zero
    for t_ns, msg in received[fx.TOPIC_SHIPS]:
        for s in msg.ships:
            p, v, st, alt, cos_tilt, t_s = samples[(t_ns, s.ship_id)]
            assert s.state == SurfaceState(st).label and s.altitude == alt
            assert s.tilt_deg == pytest.approx(math.degrees(math.acos(min(1.0, cos_tilt))),
                                               abs=1e-9)
            _pos, vel = measure.site_frame(params, p[None, :], v[None, :], t_s)
            assert np.allclose([s.v_east, s.v_north, s.v_up], vel[0], rtol=0, atol=1e-9)
            assert not s.HasField("normal_force") and not s.HasField("energy_j")

    # the landers: every ship seen, in its frame, in the colour of its latest state then
    last_state = {}
    for (t_ns, sid), (_p, _v, st, *_r) in sorted(samples.items()):
        last_state.setdefault(sid, []).append((t_ns, st))
    for t_ns, msg in received[fx.TOPIC_LANDERS]:
        assert {e.id for e in msg.entities} <= {"s1", "s2", "s3"} and msg.entities
        for e in msg.entities:
            assert e.frame_id == e.id and e.frame_locked
            st = [s for t, s in last_state[e.id] if t <= t_ns][-1]
            rgb = tuple(round(c * 255) for c in (e.cubes[0].color.r, e.cubes[0].color.g,
                                                 e.cubes[0].color.b))
            assert rgb == STATE_COLORS[SurfaceState(st)]
    big = [e for _t, m in received[fx.TOPIC_LANDERS] for e in m.entities if e.id == "s3"]
    feet = {round(math.hypot(p.x, p.y), 9) for p in big[0].lines[0].points[1::2]}
    assert feet == {3.0}  # its own legs, from its table in the service

    # the events: each a foxglove.Log named by its ship, as on the service's event stream
    published = [(f[b"event"].decode(), f[b"ship_id"].decode())
                 for _i, f in client.xrange(f"{prefix}:ships")]
    for _t, lg in received.get(fx.TOPIC_EVENTS, []):
        assert (lg.message.split()[0], lg.name) in published
    assert received.get(fx.TOPIC_EVENTS), "no event reached Foxglove"


def test_the_site_frame_of_the_live_view_is_the_logs():
    """The live view's conversion (telemetry has only inertial positions and velocities) is
    sim.measure.site_frame's, on a turning body, to rounding."""
    params = parse_text(SCENE, "scene").params
    rng = np.random.default_rng(3)
    p = rng.normal(size=(20, 3)) * 50 + [params.body.radius_m + 5, 0, 0]
    v = rng.normal(size=(20, 3))
    for t in (0.0, 12.35, 1800.0):
        pos, vel = site_of(p, v, params.body.omega_radps, params.body.radius_m, t)
        ref_p, ref_v = measure.site_frame(params, p, v, t)
        assert np.allclose(pos, ref_p, rtol=0, atol=1e-7)
        assert np.allclose(vel, ref_v, rtol=0, atol=1e-9)


def test_foxglove_without_redis_or_with_a_bad_url_is_one_line(tmp_path):
    r = subprocess.run(_cli("view", "--foxglove", "8765"), capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 2 and "--redis" in r.stderr and "Traceback" not in r.stderr
    r = subprocess.run(_cli("view", "--redis", "redis://:secret@127.0.0.1:1/0", "--foxglove",
                            "0", "--seconds", "1"), capture_output=True, text=True, timeout=60,
                       env={**os.environ})
    assert r.returncode == 2 and "Traceback" not in r.stderr and "secret" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr
