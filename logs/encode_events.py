"""A block's transition events as TransitionEvent messages (log format 6), their bytes written
straight from the step's records, compiled: the bytes ``logs.header.event_message(...)
.SerializeToString()`` gives, without protobuf's Python objects.

An event's message through protobuf cost ~16-22 us (the ShipState's fields gathered, the
tilt's compiled call, four sub-messages built, the message built and serialized); a fleet of
10,000 landers touching down makes ~13,000 events a simulated second, ~0.28 us a ship-tick of a
log's ~0.7. Here one call a block: the events' numbers gathered from the block's records at
once, their tilts by sim.measure.tilt_from_vertical_rad (the format's own kernel, then
``* 180/pi``: math.degrees's multiplication), and every message written by :func:`_encode`.

The wire (protobuf's encoding, proto3): fields in number order; a double is its key and its
eight little-endian bytes, left out when its bits are all zero (0.0, not -0.0: protobuf keeps a
negative zero); an integer (tick, a state) is a varint, left out when 0; a string its key, its
UTF-8 length and bytes, left out when empty; a sub-message (the ship, its vectors) its key, its
length and its fields, always there (event_message sets each). ``t_event_s`` is an ``optional``
double: always there, 0.0 too. tests/test_event_bytes.py holds every byte to protobuf's.

Anything this path does not write as protobuf would (a state outside the enum, a number that is
no int64, a ship the table does not know, None for a number: a field left out) sends the block
to event_message, which raises or writes what it always did.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from operator import attrgetter

import numpy as np

from touchdown.logs.header import LOG_FORMAT_VERSION, PORTABLE_TILT_FORMAT, event_message
from touchdown.proto import touchdown_pb2 as pb
from touchdown.sim.compiled import kernel
from touchdown.sim.enums import EventKind, SurfaceState
from touchdown.sim.state import STATE_DTYPE, State

#: math.degrees's factor (CPython: radToDeg = 180.0 / Py_MATH_PI, times x)
RAD_TO_DEG = 180.0 / math.pi
#: each event kind's topic as UTF-8, by number
_TOPIC = {int(x): x.topic.encode() for x in EventKind}
#: each surface state's seed string as UTF-8 (ShipState.surface_contact_state), by number
_SEEDS = [SurfaceState(s).seed_string.encode() for s in range(max(SurfaceState) + 1)]
_FLYING = int(SurfaceState.FLYING)


def _word(name: str) -> int:
    offset = STATE_DTYPE.fields[name][1]
    if offset % 8:  # (the record's numbers are read as eight-byte words)
        raise AssertionError(f"{name} at byte {offset} of a state record")
    return offset // 8


#: where each of a ShipState's numbers is in a state record, in eight-byte words: position,
#: velocity, attitude, rates (their first), mass, fuel; and the surface state's byte
LAYOUT = np.array([_word(n) for n in ("pos_m", "vel_mps", "quat", "omega_body_radps", "mass_kg",
                                      "fuel_kg")], np.int64)
STATE_BYTE = STATE_DTYPE.fields["surface_state"][1]
if STATE_DTYPE.fields["surface_state"][0].itemsize != 1:
    raise AssertionError("surface_state: one byte")


@kernel
def _varint_size(value):
    n = 1
    while value > 127:
        value >>= 7
        n += 1
    return n


@kernel
def _put_varint(out, o, value):
    while value > 127:
        out[o] = (value & 0x7F) | 0x80
        value >>= 7
        o += 1
    out[o] = value
    return o + 1


@kernel
def _put_double(out, o, key, bits):
    """A double field (``key``: one byte) from its bits (int64), left out when they are 0."""
    if bits == 0:
        return o
    out[o] = key
    for b in range(8):
        out[o + 1 + b] = (bits >> (8 * b)) & 0xFF
    return o + 9


@kernel
def _put_uint(out, o, key, value):
    """A varint field (``key``: one byte), left out when 0."""
    if value == 0:
        return o
    out[o] = key
    return _put_varint(out, o + 1, value)


@kernel
def _put_string(out, o, key, blob, a, b):
    """A string field of ``blob[a:b]`` (its UTF-8), left out when empty."""
    n = b - a
    if n == 0:
        return o
    o = _put_varint(out, _put_varint(out, o, key), n)
    for j in range(n):
        out[o + j] = blob[a + j]
    return o + n


@kernel
def _string_size(key, n):
    return 0 if n == 0 else _varint_size(key) + _varint_size(n) + n


@kernel
def _doubles_size(words, e, w0, count):
    """The bytes of a Vec3's or Quaternion's fields (``count`` doubles from word ``w0``)."""
    n = 0
    for j in range(count):
        if words[e, w0 + j] != 0:
            n += 9
    return n


@kernel
def _put_doubles(out, o, key, words, e, w0, count, size):
    """A Vec3 or Quaternion field (``size``: its fields' bytes), always there."""
    out[o] = key
    o = _put_varint(out, o + 1, size)
    for j in range(count):
        o = _put_double(out, o, (j + 1) << 3 | 1, words[e, w0 + j])
    return o


@kernel
def _encode(words, states, layout, ints, bits, blob, strings, consts, out, offsets):
    """Each event's TransitionEvent into ``out``, one after another (event e is
    ``out[offsets[e]:offsets[e + 1]]``). Event e's ship: ``words[e]`` (its state record as
    int64 words: the doubles' bits, LAYOUT's ``layout``), ``states[e]`` its surface state;
    ``ints[e]`` = (tick, from_state, to_state); ``bits[e]`` = the bits of (t_s, tilt_deg,
    v_radial_mps, t_event_s); ``strings[e]`` = where its topic, ship id and player id begin in
    ``blob`` and where the player id ends. ``consts``: the body's name's start and end in
    ``blob``, the flying state's number, the number of states, then where each state's seed
    string begins in ``blob`` (and where the last ends). Returns the bytes written, or -1 (a
    state past the enum, a negative number: event_message's to say)."""
    body_a, body_b, flying, n_states = consts[0], consts[1], consts[2], consts[3]
    o = 0
    for e in range(words.shape[0]):
        offsets[e] = o
        st = np.int64(states[e])
        tick, from_state, to_state = ints[e, 0], ints[e, 1], ints[e, 2]
        if st >= n_states or tick < 0 or from_state < 0 or to_state < 0:
            return -1
        s_topic, s_ship, s_player, s_end = strings[e, 0], strings[e, 1], strings[e, 2], \
            strings[e, 3]
        seed_a, seed_b = consts[4 + st], consts[5 + st]
        named_body = st != flying
        pos, vel, quat, omega = layout[0], layout[1], layout[2], layout[3]
        vecs = (_doubles_size(words, e, pos, 3), _doubles_size(words, e, vel, 3),
                _doubles_size(words, e, quat, 4), _doubles_size(words, e, omega, 3))
        ship = (_string_size(0x0A, s_player - s_ship) + _string_size(0x12, s_end - s_player)
                + (_string_size(0x1A, body_b - body_a) if named_body else 0)
                + 4 + _varint_size(vecs[0]) + vecs[0] + _varint_size(vecs[1]) + vecs[1]
                + _varint_size(vecs[2]) + vecs[2] + _varint_size(vecs[3]) + vecs[3]
                + (9 if words[e, layout[4]] != 0 else 0)
                + (9 if words[e, layout[5]] != 0 else 0)
                + (1 + _varint_size(st) if st != 0 else 0)
                + (9 if bits[e, 1] != 0 else 0) + _string_size(30 << 3 | 2, seed_b - seed_a))
        # the event: 1 event, 2 tick, 3 t_s, 4 ship_id, 5 player_id, 6 body, 7 from, 8 to
        o = _put_string(out, o, 0x0A, blob, s_topic, s_ship)
        o = _put_uint(out, o, 0x10, tick)
        o = _put_double(out, o, 0x19, bits[e, 0])
        o = _put_string(out, o, 0x22, blob, s_ship, s_player)
        o = _put_string(out, o, 0x2A, blob, s_player, s_end)
        o = _put_string(out, o, 0x32, blob, body_a, body_b)
        o = _put_uint(out, o, 0x38, from_state)
        o = _put_uint(out, o, 0x40, to_state)
        # 9 ship: ship_id, player_id, landed_body_name, position, velocity, attitude, rates,
        # mass, fuel, state, tilt, surface_contact_state (30)
        out[o] = 0x4A
        o = _put_varint(out, o + 1, ship)
        o = _put_string(out, o, 0x0A, blob, s_ship, s_player)
        o = _put_string(out, o, 0x12, blob, s_player, s_end)
        if named_body:
            o = _put_string(out, o, 0x1A, blob, body_a, body_b)
        o = _put_doubles(out, o, 0x22, words, e, pos, 3, vecs[0])
        o = _put_doubles(out, o, 0x2A, words, e, vel, 3, vecs[1])
        o = _put_doubles(out, o, 0x32, words, e, quat, 4, vecs[2])
        o = _put_doubles(out, o, 0x3A, words, e, omega, 3, vecs[3])
        o = _put_double(out, o, 0x41, words[e, layout[4]])
        o = _put_double(out, o, 0x49, words[e, layout[5]])
        o = _put_uint(out, o, 0x50, st)
        o = _put_double(out, o, 0x59, bits[e, 1])
        o = _put_string(out, o, 30 << 3 | 2, blob, seed_a, seed_b)
        # 10 v_radial_mps, 11 t_event_s (optional: there at 0.0 too)
        o = _put_double(out, o, 0x51, bits[e, 2])
        out[o] = 0x59
        for b in range(8):
            out[o + 1 + b] = (bits[e, 3] >> (8 * b)) & 0xFF
        o += 9
    offsets[words.shape[0]] = o
    return o


#: the log format whose events this module writes (a test holds it to LOG_FORMAT_VERSION: a new
#: format's events go through event_message until this module writes them)
ENCODED_FORMAT = 6
if not PORTABLE_TILT_FORMAT <= ENCODED_FORMAT <= LOG_FORMAT_VERSION:
    raise AssertionError(f"events of format {ENCODED_FORMAT}")
#: the event's numbers, in one call an event (operator.attrgetter: no Python frame)
_NUMBERS = attrgetter("tick", "ship", "kind", "from_state", "to_state", "v_radial_mps",
                      "t_event_s", "ship_id")
#: what a block whose events this module cannot write raises on the way (a kind or ship not
#: known, a number that is no int64 or no double, an id that is no UTF-8): event_message's
_NOT_WRITTEN = (KeyError, IndexError, ValueError, TypeError, OverflowError, UnicodeError)


class EventMessages(Sequence):
    """A block's events as the log holds them: ``datas[e]``, event e's TransitionEvent bytes;
    ``player_ids[e]`` its player; ``body`` the log's body. Indexed, it is the TransitionEvent
    (parsed from its bytes when first asked for, then kept: the log's writer and the service
    need only the bytes, a publisher of messages the messages)."""

    __slots__ = ("datas", "player_ids", "body", "_msgs")

    def __init__(self, datas: list[bytes], player_ids: list[str], body: str,
                 msgs: list | None = None):
        self.datas, self.player_ids, self.body = datas, player_ids, body
        self._msgs = [None] * len(datas) if msgs is None else msgs

    def __len__(self) -> int:
        return len(self.datas)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self.datas)))]
        m = self._msgs[i]
        if m is None:
            m = self._msgs[i] = pb.TransitionEvent.FromString(self.datas[i])
        return m

    def __eq__(self, other) -> bool:
        if isinstance(other, (EventMessages, list, tuple)):
            return len(self) == len(other) and all(a == b for a, b in zip(self, other))
        return NotImplemented

    __hash__ = None


def event_messages(ships, body: str, dt_s: float, states: np.ndarray, first_tick: int,
                   events: Sequence, log_format: int = LOG_FORMAT_VERSION) -> EventMessages:
    """The ``events`` (sim.state.Event) of the ticks whose state records are ``states`` (K, N,
    row k tick ``first_tick + k``: a Block's ``states``; or (N,), one tick's) as
    ``event_message(ships, body, dt_s, State(rows=<its tick's row>), ev,
    log_format=log_format)`` makes each (``ships``: a ShipTable, or what has its ``players``
    and ``key``), its bytes the same: written here for format ENCODED_FORMAT, by event_message
    for any other (or anything this module does not write: module docstring)."""
    states = states.reshape(1, -1) if states.ndim == 1 else states
    if not events:
        return EventMessages([], [], body)
    if log_format == ENCODED_FORMAT and states.dtype == STATE_DTYPE:
        try:
            got = _written(ships, body, dt_s, states, first_tick, events)
        except _NOT_WRITTEN:
            got = None
        if got is not None:
            return got
    msgs = [event_message(ships, body, dt_s, State(rows=states[ev.tick - first_tick],
                                                   tick=ev.tick), ev, log_format=log_format)
            for ev in events]
    return EventMessages([m.SerializeToString() for m in msgs], [m.player_id for m in msgs],
                         body, msgs)


def _written(ships, body: str, dt_s: float, states: np.ndarray, first_tick: int,
             events: Sequence) -> EventMessages | None:
    """event_messages's, written by :func:`_encode` (None: a block it does not write)."""
    from touchdown.sim.measure import tilt_from_vertical_rad  # (compiled: a writer's)
    n = len(events)
    ticks, rows, kinds, froms, tos, v_radial, t_event, ship_ids = zip(*map(_NUMBERS, events))
    ints = np.array((ticks, froms, tos, rows), dtype=None)
    if ints.dtype.kind not in "iu" or ints.dtype.itemsize > 8 or ints.dtype == np.uint64:
        return None  # (a float, or a number past int64: protobuf's to refuse or write)
    ints = ints.astype(np.int64)
    if None in v_radial or None in t_event:  # (a field left out: numpy would make it a NaN)
        return None
    doubles = np.empty((n, 4))
    doubles[:, 2] = v_radial
    doubles[:, 3] = t_event
    key, players = ships.key, ships.players
    player_ids = [players[key(sid)] for sid in ship_ids]
    parts = []
    for kind, sid, pid in zip(kinds, ship_ids, player_ids):
        parts += (_TOPIC[kind], sid.encode(), pid.encode())
    k = ints[0] - first_tick
    if (k < 0).any() or (ints[3] < 0).any():  # (a negative index would wrap around)
        return None
    recs = states[k, ints[3]]  # (E,) each event's ship's record at its tick, a copy
    words = recs.view(np.int64).reshape(n, STATE_DTYPE.itemsize // 8)
    surface = np.ascontiguousarray(recs.view(np.uint8).reshape(n, -1)[:, STATE_BYTE])
    doubles[:, 0] = ints[0] * dt_s  # (ev.tick * dt_s: an int made a double, then multiplied)
    doubles[:, 1] = tilt_from_vertical_rad(recs["pos_m"], recs["quat"]) * RAD_TO_DEG
    lengths = np.fromiter(map(len, parts), np.int64, 3 * n)
    ends = np.cumsum(lengths)
    strings = np.empty((n, 4), np.int64)
    strings[:, 0] = ends[0::3] - lengths[0::3]
    strings[:, 1] = ends[0::3]
    strings[:, 2] = ends[1::3]
    strings[:, 3] = ends[2::3]
    at = int(ends[-1])
    body_utf8 = body.encode()
    seeds = np.cumsum([at + len(body_utf8)] + [len(s) for s in _SEEDS])
    consts = np.array([at, at + len(body_utf8), _FLYING, len(_SEEDS), *seeds.tolist()],
                      np.int64)
    blob = np.frombuffer(b"".join(parts) + body_utf8 + b"".join(_SEEDS), np.uint8)
    out = np.empty(2 * at + n * (2 * len(body_utf8) + max(map(len, _SEEDS)) + 400), np.uint8)
    offsets = np.empty(n + 1, np.int64)
    end = _encode(words, surface, LAYOUT, ints[:3].T.copy(), doubles.view(np.int64), blob,
                  strings, consts, out, offsets)
    if end < 0:
        return None
    raw = out[:end].tobytes()
    at = offsets.tolist()
    return EventMessages([raw[a:b] for a, b in zip(at, at[1:])], player_ids, body)


__all__ = ["ENCODED_FORMAT", "EventMessages", "LAYOUT", "RAD_TO_DEG", "event_messages"]
