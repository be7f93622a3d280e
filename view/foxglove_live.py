"""``touchdown view --redis URL --foxglove PORT``: the running service's fleet served to Foxglove
over Foxglove's WebSocket protocol (the ``foxglove-sdk`` server, ``ws://127.0.0.1:PORT``; in
Foxglove: Open connection, Foxglove WebSocket), on the channels of a Foxglove export
(view.foxglove), so docs/foxglove-layout.json opens a live service and a recorded log alike.

It reads what ``touchdown view --redis`` (the Rerun view, view.live) reads, and nothing the
service does not publish for its readers: the telemetry stream ``P:telemetry`` (each sample a
slice of a shard's ships: position, velocity, state, altitude, tilt, fuel), the event stream
(``P:ships``, or each shard's on a Redis Cluster), the service's config (its scene) and each
ship's table (``P:shard:{k}:specs``: its legs, for the lander's shape). The service is not
touched and needs no flag: any number of these servers may follow it.

What telemetry does not carry is not invented: it holds no attitude, so a live lander is drawn
upright on its local vertical (its tilt is a value on /foxglove/ships, and its state colours
it); it holds no forces or energy, so those values are absent (not zero) live. The transforms'
translations and the site-frame values are sim.measure.site_frame's (a test holds them to it).

Messages are stamped with the service's simulated time (tick x dt), and the server tells its
clients that time (the Time capability), so Foxglove's clock is the simulation's. A client that
connects later gets the ground and the whole fleet's landers within ``RESEND_S`` (a live
connection keeps no messages for late comers).
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field

import numpy as np
import redis

from touchdown.logs.redis_stream import DEFAULT_URL
from touchdown.proto import service_pb2 as spb
from touchdown.proto import touchdown_pb2 as pb
from touchdown.service import redis_io as rio
from foxglove_schemas_protobuf.Log_pb2 import Log

from touchdown.sim.enums import EventKind, SurfaceState
from touchdown.sim.frames import body_rotation
from touchdown.view import foxglove as fx
from touchdown.view.live import ServiceStreams
from touchdown.view.rerun_view import ViewError

#: how often the ground and the whole fleet's landers are sent again (wall seconds), for
#: clients that connected since, and the least time between two fleet updates after changes
RESEND_S = 2.0
SCENE_MIN_S = 0.25
#: the values telemetry carries (ShipValues fields), the others absent live
LIVE_VALUES = ("tilt_deg", "fuel_mass", "altitude", "east", "north", "up", "v_east", "v_north",
               "v_up")
LABEL_STATE = {s.label: int(s) for s in SurfaceState}
LEVELS = {"ship.crashed": Log.ERROR, "ship.tipped": Log.WARNING,
          "ship.command_rejected": Log.WARNING, "ship.autoland_failed": Log.WARNING}


def site_of(p: np.ndarray, v: np.ndarray, omega: float, radius: float, t_s: float
            ) -> tuple[np.ndarray, np.ndarray]:
    """Inertial positions and velocities (N,3) at time ``t_s`` as (east, north, up) and the
    velocity relative to the surface in the same axes (sim.measure.site_frame's: the body turned
    by omega t about z, its x axis through the site; up = x - R)."""
    c, s = body_rotation(omega, t_s)
    x, y = c * p[:, 0] + s * p[:, 1], -s * p[:, 0] + c * p[:, 1]
    vx, vy = c * v[:, 0] + s * v[:, 1], -s * v[:, 0] + c * v[:, 1]
    vx, vy = vx + omega * y, vy - omega * x  # less the surface's own velocity, omega z x r
    return (np.stack([y, p[:, 2], x - radius], axis=1),
            np.stack([vy, v[:, 2], vx], axis=1))


def upright_xyzw(pos_site: np.ndarray, radius: float) -> np.ndarray:
    """The rotation taking the body's z axis to the local vertical at each position (the
    radial direction, in site axes), x y z w: a lander drawn upright where it is."""
    r = pos_site + np.array([0.0, 0.0, radius])
    u = r / np.linalg.norm(r, axis=1)[:, None]
    q = np.stack([-u[:, 1], u[:, 0], np.zeros(len(u)), 1.0 + u[:, 2]], axis=1)
    return q / np.linalg.norm(q, axis=1)[:, None]


@dataclass
class LiveFleet:
    """Every ship seen, by key (the order first seen), its latest state; the scene's body."""

    radius: float
    omega: float
    ids: list[str] = field(default_factory=list)
    key: dict[str, int] = field(default_factory=dict)
    state: dict[int, int] = field(default_factory=dict)  # of the ships present
    legs: dict[int, tuple[float, float]] = field(default_factory=dict)  # (a, h)
    pos: dict[int, np.ndarray] = field(default_factory=dict)
    changed: bool = False

    @staticmethod
    def of(scene: dict) -> "LiveFleet":
        body = scene.get("body", {}) if isinstance(scene, dict) else {}
        period = float(body.get("rotation_period", 0.0) or 0.0)
        return LiveFleet(float(body.get("radius", 1737400.0)),
                         2.0 * math.pi / period if period else 0.0)

    def keys_of(self, ship_ids) -> np.ndarray:
        out = np.empty(len(ship_ids), np.int64)
        for i, sid in enumerate(ship_ids):
            k = self.key.get(sid)
            if k is None:
                k = self.key[sid] = len(self.ids)
                self.ids.append(sid)
            out[i] = k
        return out

    def drop(self, ship_id: str) -> None:
        k = self.key.get(ship_id)
        if k is not None and self.state.pop(k, None) is not None:
            self.changed = True


def parse_scene(scene: dict):
    """The service's scene (its config's scenario) resolved by the scenario's rules, with a
    stand-in ship (the scene may have none): its body, terrain and ship defaults; None if it
    does not resolve (the live view then draws a flat ground and the default lander)."""
    try:
        from touchdown.sim.scenario import parse
        doc = {k: v for k, v in scene.items() if k != "ships"} if isinstance(scene, dict) else {}
        doc.setdefault("name", "live")
        doc.setdefault("duration", 1.0)
        return parse({**doc, "ships": [{"id": "(any)"}]}, "the service's scene")
    except Exception:  # noqa: BLE001 - (any refusal: the defaults)
        return None


class Legs:
    """Each ship's leg radius and centre-of-mass height, from its table in the service
    (``P:shard:{k}:specs``) resolved by the scene's rules (sim.scenario), or the scene's
    defaults when none is found."""

    def __init__(self, client, keys: rio.Keys, shards: int, scenario):
        self.client, self.keys, self.shards = client, keys, shards
        self._scene = scenario.scene if scenario is not None else None

    def of(self, ship_ids: list[str]) -> list[tuple[float, float]]:
        from touchdown.service.commands import shard_of
        pipe = self.client.pipeline(transaction=False)
        for sid in ship_ids:
            pipe.hget(self.keys.shard(shard_of(sid, self.shards), "specs"), sid)
        try:
            raw = pipe.execute()
        except redis.exceptions.RedisError:
            raw = [None] * len(ship_ids)
        out = []
        for sid, r in zip(ship_ids, raw):
            table = {"id": sid}
            try:
                got = json.loads(r) if r else None
                if isinstance(got, list) and len(got) == 2 and isinstance(got[1], dict):
                    table = {**got[1], "id": sid}
            except ValueError:
                pass
            out.append(self._resolve(table))
        return out

    def _resolve(self, table: dict) -> tuple[float, float]:
        if self._scene is not None:
            try:
                ships = self._scene.ship(table)[0]
                return float(ships.leg_radius_m[0]), float(ships.com_height_m[0])
            except Exception:  # noqa: BLE001 - a table the scene refuses: its default
                pass
        return 2.26, 3.0


@dataclass
class Served:
    samples: int = 0
    events: int = 0
    messages: int = 0
    ships: int = 0


class _Channels:
    """The Foxglove channels on the SDK's context (protobuf, Foxglove's schemas embedded)."""

    def __init__(self, ctx):
        import foxglove
        from mcap_protobuf.schema import build_file_descriptor_set
        self.channels = {}
        for topic, cls in fx.SCHEMAS.items():
            schema = foxglove.Schema(name=cls.DESCRIPTOR.full_name, encoding="protobuf",
                                     data=build_file_descriptor_set(cls).SerializeToString())
            self.channels[topic] = foxglove.Channel(topic, schema=schema,
                                                    message_encoding="protobuf", context=ctx)
        self.sent = 0

    def log(self, topic: str, data: bytes, t_ns: int) -> None:
        self.channels[topic].log(data, log_time=int(t_ns))
        self.sent += 1


def serve(url: str = DEFAULT_URL, prefix: str = "galaxy", port: int = 8765,
          seconds: float | None = None, password: str | None = None, host: str = "127.0.0.1",
          history: int = 2000, ready=None) -> Served:
    """Serve the fleet to Foxglove on ``host:port`` (0: any free port) for ``seconds`` (None:
    until Ctrl-C), from the last ``history`` telemetry samples and events on. ``ready(port)``
    is called once the server listens."""
    import foxglove
    from foxglove.websocket import Capability

    streams = ServiceStreams(url, prefix, password, history)
    client, keys, scene = streams.client, streams.keys, streams.scene
    fleet = LiveFleet.of(scene)
    scenario = parse_scene(scene)
    if scenario is not None:  # the body as the service resolved it
        fleet.radius = float(scenario.params.body.radius_m)
        fleet.omega = float(scenario.params.body.omega_radps)
    legs = Legs(client, keys, streams.shards, scenario)
    ctx = foxglove.Context()
    channels = _Channels(ctx)
    try:
        server = foxglove.start_server(name=f"touchdown ({prefix})", host=host, port=port,
                                       capabilities=[Capability.Time], context=ctx)
    except Exception as exc:  # noqa: BLE001 - the SDK's error: a port in use, a bad host
        streams.close()
        raise ViewError(f"--foxglove {port}: cannot serve on {host}:{port} ({exc})",
                        exit_code=2) from None
    if ready is not None:
        ready(server.port)
    enc = fx.FleetEncoder(value_fields=LIVE_VALUES)
    enc.ids(fleet.ids)
    landers = fx.LanderCache(fleet.ids, _Column(fleet, 0), _Column(fleet, 1),
                             label=True)
    served = Served()
    t_ns = 0
    sent_scene = sent_ground = -math.inf
    gone: set[int] = set()
    try:
        for batch in streams.batches(seconds, block_ms=100):
            for stream, fields in batch:
                if stream == streams.telemetry:
                    try:
                        sample = spb.Telemetry.FromString(fields.get(b"proto", b""))
                    except Exception:  # noqa: BLE001 - a damaged entry: skipped
                        continue
                    t_ns = max(t_ns, _sample(sample, fleet, legs, enc, channels))
                    served.samples += 1
                else:
                    k = _event(fields, fleet, channels, t_ns)
                    if k is not None:
                        gone.add(k)
                    served.events += 1
            now = time.monotonic()
            if t_ns and now - sent_ground >= RESEND_S and fleet.pos and scenario is not None:
                reach = max((a + h for a, h in fleet.legs.values()), default=5.0)
                channels.log(fx.TOPIC_GROUND, fx.ground_around(
                    scenario.params, np.array(list(fleet.pos.values())), reach, n=21), t_ns)
                sent_ground = now
            if t_ns and (now - sent_scene >= RESEND_S or (
                    fleet.changed and now - sent_scene >= SCENE_MIN_S)):
                deleted = [fleet.ids[k] for k in sorted(gone)]
                channels.log(fx.TOPIC_LANDERS, landers.update(
                    t_ns, sorted(fleet.state.items()), deleted), t_ns)
                gone.clear()
                fleet.changed = False
                sent_scene = now
            if t_ns:
                server.broadcast_time(t_ns)
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
        streams.close()
    served.messages = channels.sent
    served.ships = len(fleet.state)
    return served


class _Column:
    """A ship's leg radius (0) or centre-of-mass height (1) by key, as LanderCache reads it."""

    def __init__(self, fleet: LiveFleet, which: int):
        self.fleet, self.which = fleet, which

    def __getitem__(self, key: int) -> float:
        return self.fleet.legs.get(key, (2.26, 3.0))[self.which]


def _sample(sample, fleet: LiveFleet, legs: Legs, enc, channels: _Channels) -> int:
    """One telemetry sample: its ships' transforms and values; returns its time, ns."""
    n = len(sample.ship_ids)
    t_ns = int(round(sample.t_s * 1e9))
    if not n:
        return t_ns
    ids = list(sample.ship_ids)
    keys = fleet.keys_of(ids)
    new = [i for i, k in enumerate(keys.tolist()) if k not in fleet.legs]
    if new:
        for i, ah in zip(new, legs.of([ids[i] for i in new])):
            fleet.legs[int(keys[i])] = ah
    enc.ids(fleet.ids)
    p = np.array(sample.pos_m, float).reshape(n, 3)
    v = np.array(sample.vel_mps, float).reshape(n, 3)
    pos, vel = site_of(p, v, fleet.omega, fleet.radius, sample.t_s)
    states = np.array(sample.state, np.int64)
    for k, st, xyz in zip(keys.tolist(), states.tolist(), pos):
        if fleet.state.get(k) != st:
            fleet.state[k] = st
            fleet.changed = True
        fleet.pos[k] = xyz
    counts = np.array([n])
    channels.log(fx.TOPIC_TRANSFORMS, enc.transforms([t_ns], counts, keys, pos,
                                                     upright_xyzw(pos, fleet.radius))[0], t_ns)
    cols = {"tilt_deg": fx.tilt_deg(np.array(sample.cos_tilt)),
            "fuel_mass": np.array(sample.fuel_kg, float),
            "altitude": np.array(sample.altitude_m, float),
            "east": pos[:, 0], "north": pos[:, 1], "up": pos[:, 2],
            "v_east": vel[:, 0], "v_north": vel[:, 1], "v_up": vel[:, 2]}
    channels.log(fx.TOPIC_SHIPS, enc.values([int(sample.tick)], [float(sample.t_s)], counts,
                                            keys, states, cols)[0], t_ns)
    return t_ns


def _event(fields: dict, fleet: LiveFleet, channels: _Channels, t_ns: int) -> int | None:
    """An entry of the event stream as a foxglove.Log; a retired ship leaves the scene (returns
    its key)."""
    f = {k.decode(): v.decode("utf-8", "replace") for k, v in fields.items() if k != b"proto"}
    kind, sid = f.get("event", ""), f.get("ship_id", "")
    proto = fields.get(b"proto")
    try:
        t_event = float(f.get("t_event", "nan"))
    except ValueError:
        t_event = math.nan
    stamp = int(round(t_event * 1e9)) if math.isfinite(t_event) else t_ns
    if proto and kind in {k.topic for k in _KINDS}:
        try:
            ev = pb.TransitionEvent.FromString(proto)
            data = fx.event_log(ev.event, ev.ship_id, ev.from_state, ev.to_state,
                                stamp / 1e9, ev.v_radial_mps, ev.ship.tilt_deg, ev.player_id)
        except Exception:  # noqa: BLE001 - a damaged entry: said as its plain fields
            data = None
    else:
        data = None
    if data is None:
        text = f"{kind} {sid} (player {f.get('player_id', '')})"
        for extra in ("reason", "result"):
            if extra in f:
                text += f": {f[extra]}"
        data = fx.log_message(stamp, LEVELS.get(kind, Log.INFO), text, sid)
    channels.log(fx.TOPIC_EVENTS, data, t_ns or stamp)
    if kind == "ship.retired":
        k = fleet.key.get(sid)
        fleet.drop(sid)
        return k
    return None


_KINDS = tuple(EventKind)


__all__ = ["serve", "Served", "LiveFleet", "site_of", "upright_xyzw", "LIVE_VALUES"]
