"""A run as Foxglove shows it (SPEC section 4): Foxglove's published schemas
(``foxglove-schemas-protobuf``: the generated protobuf classes of Foxglove's own .proto files,
the ones its app decodes), embedded as protobuf like every other message of a log.

The channels, the same in a log (``touchdown export --format foxglove``, ``touchdown record
--foxglove``) and live (``touchdown view --redis URL --foxglove PORT``, view/foxglove_live.py):

- ``/foxglove/transforms`` (``foxglove.FrameTransforms``), one message a tick: each ship's pose
  as a transform from the frame ``site`` (the landing-site frame: x east, y north, z up, m;
  origin on the reference sphere under the site) to the frame named by the ship's id: the
  translation its centre of mass, the rotation its attitude (body -> site). Stamped with the
  tick's simulated time, which is also the message's log time.
- ``/foxglove/landers`` (``foxglove.SceneUpdate``): every ship present drawn in its own frame
  (frame-locked, so it moves with the transforms): the descent stage in its state's colour (the
  Rerun view's, view.scene.STATE_COLORS), the ascent stage, four legs, footpads, the footprint
  and its id. Foxglove shows a topic's latest message after a seek, so each message holds the
  whole fleet (and deletes ships that left): one at the first tick and then after changes (a
  ship joins, leaves or changes state), at most one per ``scene_period_s`` of simulated time
  (a lander's colour is at most that late; the state itself is exact on /foxglove/ships).
- ``/foxglove/ground`` (``foxglove.SceneUpdate``), once: the body's surface with its terrain
  around the ships' paths, in the frame ``site``.
- ``/foxglove/events`` (``foxglove.Log``): each transition, stamped with the instant it
  happened, named by its ship's id, at a level by its kind (crashed an error, tipped a warning).
- ``/foxglove/ships`` (``touchdown.v1.FleetValues``, proto/views.proto), one message a tick:
  each ship's values named by its id (the export's columns), so a Plot panel addresses a ship
  by id (``/foxglove/ships.ships[:]{ship_id=="ship-1"}.altitude``, or one series per ship with
  ``ship_id`` as its label), never by a place in an array that shifts as ships join and leave.

The per-tick messages of a fleet are put together as bytes from the columns (each ship's
fields in number order, as protobuf writes them, by a compiled pass: :class:`RepeatedEncoder`),
a thousand ships in about a millisecond, where protobuf's Python objects take about fifty; a
test decodes them with the published classes. Everything else is made with those classes.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CubePrimitive_pb2 import CubePrimitive
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.Point3_pb2 import Point3
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneEntityDeletion_pb2 import SceneEntityDeletion
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.SpherePrimitive_pb2 import SpherePrimitive
from foxglove_schemas_protobuf.TextPrimitive_pb2 import TextPrimitive
from foxglove_schemas_protobuf.TriangleListPrimitive_pb2 import TriangleListPrimitive
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.timestamp_pb2 import Timestamp

from touchdown.logs import derived
from touchdown.logs.codec import varint
from touchdown.proto import views_pb2
from touchdown.sim.compiled import separate
from touchdown.sim.enums import SurfaceState
from touchdown.view.scene import STATE_COLORS, LanderShape

SITE_FRAME = "site"
TOPIC_TRANSFORMS = "/foxglove/transforms"
TOPIC_LANDERS = "/foxglove/landers"
TOPIC_GROUND = "/foxglove/ground"
TOPIC_EVENTS = "/foxglove/events"
TOPIC_SHIPS = "/foxglove/ships"
#: each topic's message class (its schema, embedded as a protobuf FileDescriptorSet)
SCHEMAS = {TOPIC_TRANSFORMS: FrameTransforms, TOPIC_LANDERS: SceneUpdate,
           TOPIC_GROUND: SceneUpdate, TOPIC_EVENTS: Log,
           TOPIC_SHIPS: views_pb2.FleetValues}
#: the per-ship values: every ShipValues field after ship_id and state (the export's columns)
VALUE_FIELDS: tuple[str, ...] = tuple(
    f.name for f in views_pb2.ShipValues.DESCRIPTOR.fields if f.name not in ("ship_id", "state"))
#: a transition's level in the Log panel, by the state it goes to (Foxglove's LogLevel)
LEVEL_BY_STATE = {SurfaceState.CRASHED: Log.ERROR, SurfaceState.TIPPED: Log.WARNING}
#: what a SceneUpdate of the fleet costs a ship, bytes (a lander: about 900); the default period
#: keeps the landers' messages of a large fleet near a tenth of its transforms' bytes
SCENE_PERIOD_S = 0.1
SCENE_PERIOD_LARGE_S = 1.0
LARGE_FLEET = 100


def scene_period(ships: int) -> float:
    """The least simulated time between two SceneUpdates of the landers (module docstring):
    0.1 s for up to 100 ships, 1 s for more."""
    return SCENE_PERIOD_S if ships <= LARGE_FLEET else SCENE_PERIOD_LARGE_S


def _stamp(t_ns: int) -> Timestamp:
    return Timestamp(seconds=t_ns // 1_000_000_000, nanos=t_ns % 1_000_000_000)


def _color(rgb: Sequence[int], alpha: float = 1.0) -> Color:
    return Color(r=rgb[0] / 255.0, g=rgb[1] / 255.0, b=rgb[2] / 255.0, a=alpha)


def _pose(x: float, y: float, z: float) -> Pose:
    return Pose(position=Vector3(x=x, y=y, z=z), orientation=Quaternion(w=1.0))


# -- the scene --------------------------------------------------------------------------------------
def lander_entity(ship_id: str, leg_radius_m: float, com_height_m: float, state: int,
                  t_ns: int, label: bool = True) -> SceneEntity:
    """A lander in its ship's frame (view.scene.LanderShape), its descent stage in its state's
    colour, frame-locked (it follows the frame's transform), until replaced or deleted."""
    shape = LanderShape.of(leg_radius_m, com_height_m)
    color = STATE_COLORS.get(SurfaceState(int(state)), (200, 200, 200))
    e = SceneEntity(timestamp=_stamp(t_ns), frame_id=ship_id, id=ship_id, frame_locked=True)
    e.cubes.append(CubePrimitive(pose=_pose(*shape.descent_center),
                                 size=Vector3(x=2 * shape.descent_half[0],
                                              y=2 * shape.descent_half[1],
                                              z=2 * shape.descent_half[2]),
                                 color=_color(color)))
    e.spheres.append(SpherePrimitive(pose=_pose(*shape.ascent_center),
                                     size=Vector3(x=2 * shape.ascent_half[0],
                                                  y=2 * shape.ascent_half[1],
                                                  z=2 * shape.ascent_half[2]),
                                     color=_color((200, 200, 205))))
    for foot in shape.feet:
        e.spheres.append(SpherePrimitive(pose=_pose(*foot),
                                         size=Vector3(x=2 * shape.pad_radius,
                                                      y=2 * shape.pad_radius,
                                                      z=0.5 * shape.pad_radius),
                                         color=_color((160, 160, 160))))
    legs = [Point3(x=p[0], y=p[1], z=p[2]) for top, foot in zip(shape.leg_tops, shape.feet)
            for p in (top, foot)]
    e.lines.append(LinePrimitive(type=LinePrimitive.LINE_LIST, pose=_pose(0, 0, 0),
                                 thickness=2 * shape.leg_radius, scale_invariant=False,
                                 points=legs, color=_color((180, 180, 180))))
    e.lines.append(LinePrimitive(type=LinePrimitive.LINE_LOOP, pose=_pose(0, 0, 0),
                                 thickness=shape.leg_radius, scale_invariant=False,
                                 points=[Point3(x=f[0], y=f[1], z=f[2]) for f in shape.feet],
                                 color=_color((255, 255, 255), 0.6)))
    if label:
        top = shape.ascent_center[2] + shape.ascent_half[2]
        e.texts.append(TextPrimitive(pose=_pose(0.0, 0.0, top + 0.5), billboard=True,
                                     font_size=14.0, scale_invariant=True,
                                     color=_color((255, 255, 255)), text=ship_id))
    return e


class LanderCache:
    """Each ship's lander entity in each state, serialized once without its timestamp (field 1):
    a SceneUpdate of the whole fleet is then its parts joined (fields in number order: the
    deletions, 1, then the entities, 2, each with its timestamp first), a thousand landers in
    a fraction of a millisecond where building them takes 60 ms."""

    def __init__(self, ids: Sequence[str], leg_radius_m, com_height_m, label: bool = True):
        self.ids, self.a, self.h, self.label = ids, leg_radius_m, com_height_m, label
        self._rest: dict[tuple[int, int], bytes] = {}

    def _entity_rest(self, key: int, state: int) -> bytes:
        got = self._rest.get((key, state))
        if got is None:
            e = lander_entity(self.ids[key], float(self.a[key]), float(self.h[key]), state, 0,
                              self.label)
            e.ClearField("timestamp")
            got = self._rest[(key, state)] = e.SerializeToString()
        return got

    def update(self, t_ns: int, ships: Iterable[tuple[int, int]],
               deleted: Iterable[str] = ()) -> bytes:
        """A SceneUpdate: the ``deleted`` ids removed, each (key, state) of ``ships`` drawn,
        stamped ``t_ns``; the bytes protobuf writes for the same message."""
        stamp = timestamp_field(1, t_ns)
        parts = []
        for ship_id in deleted:
            d = SceneEntityDeletion(timestamp=_stamp(t_ns), type=SceneEntityDeletion.MATCHING_ID,
                                    id=ship_id).SerializeToString()
            parts.append(b"\x0a" + varint(len(d)) + d)
        for key, state in ships:
            body = stamp + self._entity_rest(key, state)
            parts.append(b"\x12" + varint(len(body)) + body)
        return b"".join(parts)


def scene_update(t_ns: int, entities: Iterable[SceneEntity] = (),
                 deleted: Iterable[str] = ()) -> bytes:
    """A SceneUpdate: the ``deleted`` ids removed, then ``entities`` added or replaced."""
    msg = SceneUpdate(entities=list(entities))
    for ship_id in deleted:
        msg.deletions.append(SceneEntityDeletion(timestamp=_stamp(t_ns),
                                                 type=SceneEntityDeletion.MATCHING_ID,
                                                 id=ship_id))
    return msg.SerializeToString()


def ground_update(verts: np.ndarray, tris: np.ndarray, t_ns: int = 0) -> bytes:
    """The body's surface (view.scene.terrain_grid: site-frame vertices and triangles) as one
    entity of triangles in the frame ``site``, shaded by height as the Rerun view shades it."""
    pts = verts[tris.reshape(-1)]
    shade = np.clip(0.55 + 0.08 * (pts[:, 2] - verts[:, 2].min()), 0.55, 0.9)
    tri = TriangleListPrimitive(pose=_pose(0, 0, 0))
    tri.points.extend(Point3(x=float(x), y=float(y), z=float(z)) for x, y, z in pts.tolist())
    tri.colors.extend(Color(r=s * 200 / 255, g=s * 195 / 255, b=s * 185 / 255, a=1.0)
                      for s in shade.tolist())
    e = SceneEntity(timestamp=_stamp(t_ns), frame_id=SITE_FRAME, id="ground",
                    triangles=[tri])
    return SceneUpdate(entities=[e]).SerializeToString()


def ground_around(params, pos_site_m: np.ndarray, reach_m: float, n: int = 41) -> bytes:
    """The body's surface (with its terrain: view.scene.terrain_grid) around ships at
    ``pos_site_m``: their extent and a margin of max(5 landers' reach, 50 m, a quarter of the
    extent), as a SceneUpdate in the frame ``site``."""
    from touchdown.view.scene import terrain_grid
    lo, hi = pos_site_m.min(axis=0), pos_site_m.max(axis=0)
    margin = max(5.0 * reach_m, 50.0, 0.25 * float(max(hi[0] - lo[0], hi[1] - lo[1])))
    verts, tris = terrain_grid(params, (lo[0] - margin, hi[0] + margin),
                               (lo[1] - margin, hi[1] + margin), n=n)
    return ground_update(verts, tris)


def event_log(event: str, ship_id: str, from_state: int, to_state: int, t_event_s: float,
              v_radial_mps: float, tilt_deg: float, player_id: str = "") -> bytes:
    """A transition as a foxglove.Log: stamped with the instant it happened, named by its
    ship's id, its level by the state it goes to."""
    try:
        to = SurfaceState(int(to_state))
        text = (f"{event} {ship_id}: {SurfaceState(int(from_state)).label} -> {to.label}, "
                f"v_radial {v_radial_mps:+.2f} m/s, tilt {tilt_deg:.1f} deg"
                + (f" (player {player_id})" if player_id else ""))
    except ValueError:  # (a live stream's other events: rejections, the autopilot's reports)
        to, text = None, f"{event} {ship_id}"
    return log_message(int(round(t_event_s * 1e9)), LEVEL_BY_STATE.get(to, Log.INFO), text,
                       ship_id)


def log_message(t_ns: int, level: int, text: str, name: str) -> bytes:
    """A foxglove.Log stamped ``t_ns``."""
    return Log(timestamp=_stamp(t_ns), level=level, message=text, name=name).SerializeToString()


# -- per-tick messages of a fleet, as bytes --------------------------------------------------------
def _tag(number: int, wire: int) -> bytes:
    return varint(number << 3 | wire)


def _string_table(strings: Sequence[str], number: int) -> tuple[np.ndarray, np.ndarray]:
    """Each string as a length-delimited field ``number`` (tag, length, UTF-8), concatenated,
    with the offsets where each begins (and the end)."""
    parts = [_tag(number, 2) + varint(len(b)) + b for b in (s.encode() for s in strings)]
    off = np.zeros(len(parts) + 1, np.int64)
    np.cumsum([len(p) for p in parts], out=off[1:])
    return np.frombuffer(b"".join(parts), np.uint8).copy() if parts else \
        np.zeros(0, np.uint8), off


@separate
def _put_repeated(out, o, tag, common, table_a, off_a, idx_a, table_b, off_b, idx_b, fixed,
                  r0, r1):
    """Rows r0..r1 as one length-delimited field ``tag`` each, from ``out[o]``: the row's
    bytes are ``common``, then entry ``idx_a[r]`` of table a, entry ``idx_b[r]`` of table b
    (fields in number order), then ``fixed[r]``. Returns where it ended."""
    W = fixed.shape[1]
    for r in range(r0, r1):
        a, b = idx_a[r], idx_b[r]
        na = off_a[a + 1] - off_a[a]
        nb = off_b[b + 1] - off_b[b] if b >= 0 else 0
        n = common.shape[0] + na + nb + W
        out[o] = tag
        o += 1
        while n >= 0x80:
            out[o] = (n & 0x7F) | 0x80
            n >>= 7
            o += 1
        out[o] = n
        o += 1
        for j in range(common.shape[0]):
            out[o + j] = common[j]
        o += common.shape[0]
        for j in range(na):
            out[o + j] = table_a[off_a[a] + j]
        o += na
        if b >= 0:
            for j in range(nb):
                out[o + j] = table_b[off_b[b] + j]
            o += nb
        for j in range(W):
            out[o + j] = fixed[r, j]
        o += W
    return o


@dataclass(frozen=True)
class Fixed:
    """A run of fields of a fixed size each (doubles; submessages of doubles), as a packed
    numpy record: its tags and lengths set once, the numbers filled in by name."""

    dtype: np.dtype
    template: np.ndarray  # one record with the tags set

    @staticmethod
    def of(fields: Sequence[tuple]) -> "Fixed":
        """``fields``: (number, name) for a double, or (number, (names...)) for a submessage of
        doubles numbered 1, 2, ... (a Vector3, a Quaternion)."""
        names, formats, offsets, consts = [], [], [], []
        o = 0

        def const(b: bytes) -> None:
            nonlocal o
            for k, byte in enumerate(b):
                name = f"_c{len(consts)}"
                names.append(name)
                formats.append("u1")
                offsets.append(o)
                consts.append((name, byte))
                o += 1

        for number, what in fields:
            if isinstance(what, str):
                const(_tag(number, 1))
                names.append(what)
                formats.append("<f8")
                offsets.append(o)
                o += 8
            else:
                const(_tag(number, 2) + varint(9 * len(what)))
                for k, name in enumerate(what, start=1):
                    const(_tag(k, 1))
                    names.append(name)
                    formats.append("<f8")
                    offsets.append(o)
                    o += 8
        dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets,
                          "itemsize": o})
        template = np.zeros(1, dtype)
        for name, byte in consts:
            template[name] = byte
        return Fixed(dtype, template)

    def rows(self, n: int, columns: dict[str, np.ndarray]) -> np.ndarray:
        """(n, itemsize) bytes: the template n times, each named number from ``columns``."""
        rec = np.repeat(self.template, n)
        for name in self.dtype.names:
            if not name.startswith("_c"):
                rec[name] = columns[name]
        return rec.view(np.uint8).reshape(n, self.dtype.itemsize)


class RepeatedEncoder:
    """One message a tick holding a repeated submessage per ship, put together as bytes (module
    docstring): ``head(tick)`` bytes first, then each ship's field ``number``: the tick's
    ``common`` bytes, the ship's id field, its state field (if any), then its fixed fields."""

    def __init__(self, number: int, id_number: int, fixed: Fixed, state_number: int = 0):
        self.tag = _tag(number, 2)[0]
        assert number < 16
        self.id_number = id_number
        self.fixed = fixed
        self._ids: tuple = ()
        self._id_table = (np.zeros(0, np.uint8), np.zeros(1, np.int64))
        self._states = _string_table([s.label for s in SurfaceState], state_number) \
            if state_number else (np.zeros(0, np.uint8), np.zeros(1, np.int64))
        self._with_state = bool(state_number)

    def ids(self, ship_ids: Sequence[str]) -> None:
        """The ships' ids by key (a log's ship table; the same list again is free)."""
        if ship_ids is not self._ids or len(ship_ids) != len(self._id_table[1]) - 1:
            self._ids = ship_ids
            self._id_table = _string_table(ship_ids, self.id_number)

    def encode(self, heads: Sequence[bytes], commons: Sequence[bytes], counts: np.ndarray,
               keys: np.ndarray, states: np.ndarray | None, columns: dict[str, np.ndarray]
               ) -> list[bytes]:
        """One message per tick (``counts[k]`` rows each, tick-major ``keys``, ``states``,
        ``columns``): ``heads[k]`` then the rows."""
        n = keys.shape[0]
        fixed = self.fixed.rows(n, columns)
        ids, id_off = self._id_table
        st, st_off = self._states
        keys64 = np.ascontiguousarray(keys, np.int64)
        st_idx = np.ascontiguousarray(states, np.int64) if (
            self._with_state and states is not None) else np.full(n, -1, np.int64)
        width = fixed.shape[1] + 10 + int(np.diff(id_off).max(initial=0)) + \
            int(np.diff(st_off).max(initial=0))
        out_msgs = []
        r = 0
        for k, count in enumerate(counts.tolist()):
            common = np.frombuffer(commons[k], np.uint8)
            buf = np.empty(len(heads[k]) + count * (width + common.shape[0]), np.uint8)
            h = len(heads[k])
            buf[:h] = np.frombuffer(heads[k], np.uint8)
            end = _put_repeated(buf, h, self.tag, common, ids, id_off, keys64, st, st_off,
                                st_idx, fixed, r, r + count)
            out_msgs.append(buf[:end].tobytes())
            r += count
        return out_msgs


def timestamp_field(number: int, t_ns: int) -> bytes:
    """A google.protobuf.Timestamp field as protobuf writes it (zero parts left out)."""
    sec, nanos = divmod(int(t_ns), 1_000_000_000)
    inner = (b"\x08" + varint(sec) if sec else b"") + (b"\x10" + varint(nanos) if nanos else b"")
    return _tag(number, 2) + varint(len(inner)) + inner


#: FrameTransform: timestamp 1, parent 2 (the tick's common bytes), child 3 (the ship's id),
#: translation 4 and rotation 5 (fixed)
_TRANSFORM = Fixed.of([(4, ("x", "y", "z")), (5, ("qx", "qy", "qz", "qw"))])
_PARENT = _tag(2, 2) + varint(len(SITE_FRAME)) + SITE_FRAME.encode()
#: ShipValues: ship_id 1, state 2, then every value in number order
_VALUES = Fixed.of([(f.number, f.name) for f in views_pb2.ShipValues.DESCRIPTOR.fields
                    if f.name in VALUE_FIELDS])


class FleetEncoder:
    """The per-tick Foxglove messages of a fleet (FrameTransforms, FleetValues) from its
    columns, one encoder per log or live view (it keeps the ships' encoded ids)."""

    def __init__(self, value_fields: Sequence[str] = VALUE_FIELDS) -> None:
        """``value_fields``: the ShipValues fields written (those a source holds: the others
        are absent from each ship's values, not zero)."""
        self.value_fields = tuple(value_fields)
        fixed = _VALUES if self.value_fields == VALUE_FIELDS else Fixed.of(
            [(f.number, f.name) for f in views_pb2.ShipValues.DESCRIPTOR.fields
             if f.name in self.value_fields])
        self._transforms = RepeatedEncoder(1, 3, _TRANSFORM)
        self._values = RepeatedEncoder(3, 1, fixed, state_number=2)

    def ids(self, ship_ids: Sequence[str]) -> None:
        self._transforms.ids(ship_ids)
        self._values.ids(ship_ids)

    def transforms(self, t_ns: Sequence[int], counts: np.ndarray, keys: np.ndarray,
                   pos_site_m: np.ndarray, quat_site_xyzw: np.ndarray) -> list[bytes]:
        """A FrameTransforms per tick: ship ``keys[r]``'s frame at ``pos_site_m[r]``, turned
        by ``quat_site_xyzw[r]`` (body -> site), stamped ``t_ns[k]``."""
        cols = {"x": pos_site_m[:, 0], "y": pos_site_m[:, 1], "z": pos_site_m[:, 2],
                "qx": quat_site_xyzw[:, 0], "qy": quat_site_xyzw[:, 1],
                "qz": quat_site_xyzw[:, 2], "qw": quat_site_xyzw[:, 3]}
        commons = [timestamp_field(1, t) + _PARENT for t in t_ns]
        return self._transforms.encode([b""] * len(commons), commons, counts, keys, None, cols)

    def values(self, ticks: Sequence[int], t_s: Sequence[float], counts: np.ndarray,
               keys: np.ndarray, states: np.ndarray, columns: dict[str, np.ndarray]
               ) -> list[bytes]:
        """A FleetValues per tick; ``columns``: every VALUE_FIELDS name (NaN where a source
        does not hold it: a format-1 log's velocities between keyframes)."""
        heads = [(b"\x08" + varint(int(tk)) if tk else b"")
                 + (b"\x11" + struct.pack("<d", t) if t != 0.0 else b"")
                 for tk, t in zip(ticks, t_s)]
        return self._values.encode(heads, [b""] * len(heads), counts, keys, states, columns)


def tilt_deg(cos_tilt: np.ndarray) -> np.ndarray:
    """Tilt from its cosine, degrees, as export computes it (logs.derived.tilt_deg)."""
    return derived.tilt_deg(cos_tilt)


__all__ = ["SITE_FRAME", "TOPIC_TRANSFORMS", "TOPIC_LANDERS", "TOPIC_GROUND", "TOPIC_EVENTS",
           "TOPIC_SHIPS", "SCHEMAS", "VALUE_FIELDS", "LEVEL_BY_STATE", "scene_period",
           "lander_entity", "LanderCache", "scene_update", "ground_update", "ground_around",
           "event_log",
           "log_message", "timestamp_field",
           "Fixed", "RepeatedEncoder", "FleetEncoder", "tilt_deg"]
