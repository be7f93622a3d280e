"""A block's transition events as TransitionEvent messages (log format 6), their bytes written
straight from the step's records, compiled: the bytes ``logs.header.event_message(...)
.SerializeToString()`` gives, without protobuf's Python objects.

An event's message through protobuf cost ~12 us alone, ~18 inside ``touchdown record`` (the
ShipState's fields gathered, the tilt's compiled call, four sub-messages built, the message
built and serialized); 10,000 landers touching down make ~13,000 events a simulated second:
~1.2 us of each ship-tick's ~3.6. Here one compiled call a block (:func:`_encode`, ~1-2 us an
event): each ship's numbers read from the block's records in place, its tilt by the format's
kernels (sim.measure's: quat_axis_z, unit, angle_between, then ``* 180/pi``, math.degrees's
multiplication), its ids from a table of the ShipTable's UTF-8 (with the writer's keys) or
from the events.

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

import functools
import math
import weakref
from collections.abc import Sequence
from operator import attrgetter

import numpy as np

from touchdown.logs.header import (LOG_FORMAT_VERSION, PORTABLE_TILT_FORMAT, ShipTable,
                                   event_message)
from touchdown.proto import touchdown_pb2 as pb
from touchdown.sim.compiled import kernel
from touchdown.sim.enums import EventKind, SurfaceState
from touchdown.sim.state import STATE_DTYPE, State
from touchdown.sim.vec import angle_between, quat_axis_z, unit

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


STATE_BYTE = STATE_DTYPE.fields["surface_state"][1]
if STATE_DTYPE.fields["surface_state"][0].itemsize != 1 or STATE_DTYPE.itemsize % 8:
    raise AssertionError("surface_state: one byte; a record: whole words")
#: where each of a ShipState's numbers is in a state record, in eight-byte words: position,
#: velocity, attitude, rates (their first), mass, fuel; then the surface state's byte
LAYOUT = np.array([_word(n) for n in ("pos_m", "vel_mps", "quat", "omega_body_radps", "mass_kg",
                                      "fuel_kg")] + [STATE_BYTE], np.int64)


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
def _doubles_size(w, w0, count):
    """The bytes of a Vec3's or Quaternion's fields (``count`` doubles from word ``w0``)."""
    n = 0
    for j in range(count):
        if w[w0 + j] != 0:
            n += 9
    return n


@kernel
def _put_doubles(out, o, key, w, w0, count, size):
    """A Vec3 or Quaternion field (``size``: its fields' bytes), always there."""
    out[o] = key
    o = _put_varint(out, o + 1, size)
    for j in range(count):
        o = _put_double(out, o, (j + 1) << 3 | 1, w[w0 + j])
    return o


@kernel
def _encode(words, floats, recs, layout, ev, bits, names, names_at, text, text_at, dt_s, out,
            offsets):
    """Each event's TransitionEvent into ``out``, one after another (event e is
    ``out[offsets[e]:offsets[e + 1]]``). The block's state records (K, N) as int64 words
    (``words``: the doubles' bits, where LAYOUT's ``layout`` says), the same as doubles
    (``floats``) and as bytes (``recs``: the surface state at byte STATE_BYTE); ``ev[e]`` =
    (its tick's row k, its ship's column, tick, from_state, to_state, kind, key), ``bits[e]`` =
    the bits of (v_radial_mps, t_event_s). Key k's ship id is ``names[names_at[2k]:names_at[2k
    + 1]]`` and its player id the next. ``text``: the body's name, each state's seed string and
    each kind's topic (by number: "" for a number no kind has), ``text_at`` = (the flying
    state, the number of states, of kinds, 0 (where the body's name begins), where the body's
    name ends, then where each seed ends, then where each topic ends: each begins where the one
    before ends). t_s = tick * dt_s, and the tilt as
    sim.measure.tilt_from_vertical_rad and math.degrees give it (the same kernels, then the
    same multiplication). Returns the bytes written, or -1 (a state or kind past the enum, a
    negative number: event_message's to say)."""
    flying, n_states, n_kinds = text_at[0], text_at[1], text_at[2]
    body_a, body_b = text_at[3], text_at[4]
    pos, vel, quat, omega = layout[0], layout[1], layout[2], layout[3]
    mass, fuel, state_byte = layout[4], layout[5], layout[6]
    o = 0
    for e in range(ev.shape[0]):
        offsets[e] = o
        k, i, tick, from_state, to_state, kind, key = (ev[e, 0], ev[e, 1], ev[e, 2], ev[e, 3],
                                                       ev[e, 4], ev[e, 5], ev[e, 6])
        st = np.int64(recs[k, i, state_byte])
        if (st >= n_states or kind < 0 or kind >= n_kinds or tick < 0 or from_state < 0
                or to_state < 0):
            return -1
        topic_a, topic_b = text_at[4 + n_states + kind], text_at[5 + n_states + kind]
        if topic_a == topic_b:  # (no such kind)
            return -1
        seed_a, seed_b = text_at[4 + st], text_at[5 + st]
        ship_a, ship_b, player_b = names_at[2 * key], names_at[2 * key + 1], \
            names_at[2 * key + 2]
        w = words[k, i]
        f = floats[k, i]
        ez = quat_axis_z((f[quat], f[quat + 1], f[quat + 2], f[quat + 3]))
        tilt = angle_between(ez, unit((f[pos], f[pos + 1], f[pos + 2]))) * RAD_TO_DEG
        tilt_bits = np.float64(tilt).view(np.int64)
        t_bits = np.float64(tick * dt_s).view(np.int64)
        named_body = st != flying
        vecs = (_doubles_size(w, pos, 3), _doubles_size(w, vel, 3), _doubles_size(w, quat, 4),
                _doubles_size(w, omega, 3))
        ship = (_string_size(0x0A, ship_b - ship_a) + _string_size(0x12, player_b - ship_b)
                + (_string_size(0x1A, body_b - body_a) if named_body else 0)
                + 4 + _varint_size(vecs[0]) + vecs[0] + _varint_size(vecs[1]) + vecs[1]
                + _varint_size(vecs[2]) + vecs[2] + _varint_size(vecs[3]) + vecs[3]
                + (9 if w[mass] != 0 else 0) + (9 if w[fuel] != 0 else 0)
                + (1 + _varint_size(st) if st != 0 else 0)
                + (9 if tilt_bits != 0 else 0) + _string_size(30 << 3 | 2, seed_b - seed_a))
        # the event: 1 event, 2 tick, 3 t_s, 4 ship_id, 5 player_id, 6 body, 7 from, 8 to
        o = _put_string(out, o, 0x0A, text, topic_a, topic_b)
        o = _put_uint(out, o, 0x10, tick)
        o = _put_double(out, o, 0x19, t_bits)
        o = _put_string(out, o, 0x22, names, ship_a, ship_b)
        o = _put_string(out, o, 0x2A, names, ship_b, player_b)
        o = _put_string(out, o, 0x32, text, body_a, body_b)
        o = _put_uint(out, o, 0x38, from_state)
        o = _put_uint(out, o, 0x40, to_state)
        # 9 ship: ship_id, player_id, landed_body_name, position, velocity, attitude, rates,
        # mass, fuel, state, tilt, surface_contact_state (30)
        out[o] = 0x4A
        o = _put_varint(out, o + 1, ship)
        o = _put_string(out, o, 0x0A, names, ship_a, ship_b)
        o = _put_string(out, o, 0x12, names, ship_b, player_b)
        if named_body:
            o = _put_string(out, o, 0x1A, text, body_a, body_b)
        o = _put_doubles(out, o, 0x22, w, pos, 3, vecs[0])
        o = _put_doubles(out, o, 0x2A, w, vel, 3, vecs[1])
        o = _put_doubles(out, o, 0x32, w, quat, 4, vecs[2])
        o = _put_doubles(out, o, 0x3A, w, omega, 3, vecs[3])
        o = _put_double(out, o, 0x41, w[mass])
        o = _put_double(out, o, 0x49, w[fuel])
        o = _put_uint(out, o, 0x50, st)
        o = _put_double(out, o, 0x59, tilt_bits)
        o = _put_string(out, o, 30 << 3 | 2, text, seed_a, seed_b)
        # 10 v_radial_mps, 11 t_event_s (optional: there at 0.0 too)
        o = _put_double(out, o, 0x51, bits[e, 0])
        out[o] = 0x59
        for b in range(8):
            out[o + 1 + b] = (bits[e, 1] >> (8 * b)) & 0xFF
        o += 9
    offsets[ev.shape[0]] = o
    return o


#: the log format whose events this module writes (a test holds it to LOG_FORMAT_VERSION: a new
#: format's events go through event_message until this module writes them)
ENCODED_FORMAT = 6
if not PORTABLE_TILT_FORMAT <= ENCODED_FORMAT <= LOG_FORMAT_VERSION:
    raise AssertionError(f"events of format {ENCODED_FORMAT}")
#: the event's numbers, in one call an event (operator.attrgetter: no Python frame); the
#: ship's id only where there are no keys (reading it touches each id's string: ~0.8 us an
#: event of a 10,000-ship block, its cache lines cold)
_NUMBERS = attrgetter("tick", "ship", "kind", "from_state", "to_state", "v_radial_mps",
                      "t_event_s")
_SHIP_ID = attrgetter("ship_id")
#: what a block whose events this module cannot write raises on the way (a kind or ship not
#: known, a number that is no int64 or no double, an id that is no UTF-8): event_message's
_NOT_WRITTEN = (KeyError, IndexError, ValueError, TypeError, OverflowError, UnicodeError)


class EventMessages(Sequence):
    """A block's events as the log holds them: ``datas[e]``, event e's TransitionEvent bytes;
    ``player_ids[e]`` its player; ``body`` the log's body. Indexed, it is the TransitionEvent
    (parsed from its bytes when first asked for, then kept: the log's writer and the service
    need only the bytes, a publisher of messages the messages)."""

    __slots__ = ("datas", "_players", "body", "_msgs")

    def __init__(self, datas: list[bytes], player_ids, body: str, msgs: list | None = None):
        """``player_ids``: a list, or a function that makes it (when first asked for)."""
        self.datas, self._players, self.body = datas, player_ids, body
        self._msgs = [None] * len(datas) if msgs is None else msgs

    @property
    def player_ids(self) -> list[str]:
        if callable(self._players):
            self._players = self._players()
        return self._players

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


class _Names:
    """A ShipTable's ship and player ids as UTF-8, one run of bytes: key k's ship id is
    ``blob[at[2k]:at[2k + 1]]``, its player's the next; extended as ships join (a table only
    grows), its room doubled when full. (Made again for each new table: a rotating log's new
    file with other ships than the file before's.)"""

    def __init__(self):
        self.count = 0
        self.blob = np.empty(1 << 12, np.uint8)
        self.at = np.zeros(1 << 10, np.int64)

    def update(self, ids: list[str], players: list[str]) -> None:
        n = len(ids)
        if n == self.count:
            return
        m = 2 * (n - self.count)
        pairs: list = [None] * m  # each ship's id, then its player's
        pairs[0::2] = ids[self.count:n]
        pairs[1::2] = players[self.count:n]
        text = "\0".join(pairs)
        start = int(self.at[2 * self.count])
        if text.isascii() and text.count("\0") == m - 1:
            # ids of ASCII without NULs (a service's): one encode, the ids' ends where the NULs
            # are, less those before them (a call an id was 5 ms of a new table at 20,000)
            raw = np.frombuffer(text.encode("ascii"), np.uint8)
            nul = raw == 0
            ends = np.empty(m, np.int64)
            ends[:-1] = np.flatnonzero(nul) - np.arange(m - 1)
            ends[-1] = raw.shape[0] - (m - 1)
            ends += start
            raw = raw[~nul]
        else:
            new = [x.encode() for x in pairs]
            ends = start + np.cumsum(np.fromiter(map(len, new), np.int64, len(new)))
            raw = np.frombuffer(b"".join(new), np.uint8)
        end = int(ends[-1])
        if 2 * n + 1 > len(self.at):
            self.at = np.concatenate([self.at, np.zeros(max(len(self.at), 2 * n + 1), np.int64)])
        if end > len(self.blob):
            self.blob = np.concatenate([self.blob, np.empty(max(len(self.blob), end),
                                                            np.uint8)])
        self.at[2 * self.count + 1:2 * n + 1] = ends
        self.blob[start:end] = raw
        self.count = n


#: each ShipTable's _Names (while the table lives)
_NAMES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
#: the body's name, the seed strings and the topics as _encode takes them (``text``,
#: ``text_at``), by the body's name
_TEXTS: dict[str, tuple[np.ndarray, np.ndarray]] = {}


def _texts(body: str) -> tuple[np.ndarray, np.ndarray]:
    got = _TEXTS.get(body)
    if got is None:
        kinds = max(_TOPIC) + 1
        parts = [body.encode(), *_SEEDS, *(_TOPIC.get(k, b"") for k in range(kinds))]
        ends = np.cumsum([len(x) for x in parts]).tolist()
        text_at = np.array([_FLYING, len(_SEEDS), kinds, 0, *ends], np.int64)
        got = (np.frombuffer(b"".join(parts) or b"\0", np.uint8), text_at)
        if len(_TEXTS) < 64:
            _TEXTS[body] = got
    return got


def event_messages(ships, body: str, dt_s: float, states: np.ndarray, first_tick: int,
                   events: Sequence, log_format: int = LOG_FORMAT_VERSION,
                   keys: np.ndarray | None = None) -> EventMessages:
    """The ``events`` (sim.state.Event) of the ticks whose state records are ``states`` (K, N,
    row k tick ``first_tick + k``: a Block's ``states``; or (N,), one tick's) as
    ``event_message(ships, body, dt_s, State(rows=<its tick's row>), ev,
    log_format=log_format)`` makes each (``ships``: a ShipTable, or what has its ``players``
    and ``key``), its bytes the same: written here for format ENCODED_FORMAT, by event_message
    for any other (or anything this module does not write: module docstring). ``keys``: the
    key in ``ships`` (a ShipTable) of each column's ship (ShipTable.keys of the block's
    ship_ids: an event's ship is ``ev.ship``'s key, its id not read)."""
    states = states.reshape(1, -1) if states.ndim == 1 else states
    if not events:
        return EventMessages([], [], body)
    if log_format == ENCODED_FORMAT and states.dtype == STATE_DTYPE:
        try:
            got = _written(ships, body, dt_s, states, first_tick, events, keys)
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
             events: Sequence, keys: np.ndarray | None) -> EventMessages | None:
    """event_messages's, written by :func:`_encode` (None: a block it does not write)."""
    n = len(events)
    ticks, rows, kinds, froms, tos, v_radial, t_event = zip(*map(_NUMBERS, events))
    if None in v_radial or None in t_event:  # (a field left out: numpy would make it a NaN)
        return None
    ints = np.array((ticks, rows, ticks, froms, tos, kinds, rows), dtype=None)
    if ints.dtype.kind not in "iu" or ints.dtype.itemsize > 8 or ints.dtype == np.uint64:
        return None  # (a float, or a number past int64: protobuf's to refuse or write)
    # (E, 7), rows made keys below; C order whatever E (ints.T is Fortran-ordered, and one
    # event's (1, 7) is both: numba would compile _encode once for each layout)
    ev = np.ascontiguousarray(ints.T, dtype=np.int64)
    ev[:, 0] -= first_tick
    k, i = ev[:, 0], ev[:, 1]
    if (k < 0).any() or (k >= states.shape[0]).any() or (i < 0).any() or \
            (i >= states.shape[1]).any():
        return None
    if keys is not None and type(ships) is ShipTable:
        names = _NAMES.get(ships)
        if names is None:
            names = _NAMES[ships] = _Names()
        names.update(ships.ids, ships.players)
        ev[:, 6] = keys[i]
        player_ids = functools.partial(_players_of, ships.players, ev[:, 6])
        blob, at = names.blob, names.at
    else:  # the events' own ids and players, event e's at key e
        ship_ids = list(map(_SHIP_ID, events))
        key, players = ships.key, ships.players
        player_ids = [players[key(sid)] for sid in ship_ids]
        new = [x.encode() for pair in zip(ship_ids, player_ids) for x in pair]
        at = np.zeros(2 * n + 1, np.int64)
        np.cumsum(np.fromiter(map(len, new), np.int64, 2 * n), out=at[1:])
        # writable, as the table's (numba types a read-only array apart: one more compile)
        blob = np.frombuffer(bytearray(b"".join(new) or b"\0"), np.uint8)
        ev[:, 6] = np.arange(n)
    doubles = np.empty((n, 2))
    doubles[:, 0] = v_radial
    doubles[:, 1] = t_event
    text, text_at = _texts(body)
    records = np.ascontiguousarray(states)
    kk, nn = records.shape
    words = records.view(np.int64).reshape(kk, nn, STATE_DTYPE.itemsize // 8)
    # room: each event's ids twice, its body's name twice, its topic and seed, the rest bounded
    room = int((2 * (at[2 * ev[:, 6] + 2] - at[2 * ev[:, 6]])).sum()) + n * (
        2 * int(text_at[4]) + int(text_at[-1] - text_at[4]) + 400)
    out = np.empty(room, np.uint8)
    offsets = np.empty(n + 1, np.int64)
    end = _encode(words, words.view(np.float64), records.view(np.uint8).reshape(kk, nn, -1),
                  LAYOUT, ev, doubles.view(np.int64), blob, at, text, text_at, float(dt_s), out,
                  offsets)
    if end < 0:
        return None
    raw = out[:end].tobytes()
    at = offsets.tolist()
    return EventMessages([raw[a:b] for a, b in zip(at, at[1:])], player_ids, body)


def _players_of(players: list[str], keys: np.ndarray) -> list[str]:
    return [players[k] for k in keys.tolist()]


__all__ = ["ENCODED_FORMAT", "EventMessages", "LAYOUT", "RAD_TO_DEG", "event_messages"]
