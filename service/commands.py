"""Player commands as they arrive on the command stream (SPEC.md section 5), checked field by field.

An entry is a flat map of strings: ``cmd``, ``ship_id`` and ``player_id`` (the player the game's
gateway authenticated: docs/SERVICE.md, "Who may command a ship"), plus per command

    throttle  value        0..1 of the ship's max thrust
    rcs       x, y, z      -1..1 of its max RCS torque per body axis
    hold      mode         off | kill_rotation | radial
    spawn     ship         JSON of one [[ships]] table (section 3), ``initial`` included
    retire    (nothing)
    autoland  (nothing)    the landing autopilot (service.autopilot)

Each command is a row of one table (service.kinds.KINDS: its fields and their checks, and what
it does to the fleet), from which both :func:`parse` and the shard's applying are read.

:func:`parse` turns an entry into a :class:`Request` or a :class:`Rejected` with a one-line
reason; it looks at nothing but the entry (what a ship is, or whether it exists, is the shard's
question, service.shard). Whatever an entry holds (unknown fields, bytes that are not UTF-8, NaN,
1e308, a megabyte of JSON), parsing it returns; it never raises.

A parsed request is also what the shard's journal keeps (``as_json``): a worker that takes a
shard over re-applies the journal's requests at their ticks and reaches the same decisions.
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass, field

from touchdown.service.kinds import KINDS, show

#: fields each command may carry besides ``cmd``, ``ship_id`` and ``player_id``
FIELDS: dict[str, tuple[str, ...]] = {k.name: tuple(f.name for f in k.fields)
                                      for k in KINDS.values()}
MAX_SHIP_ID = 128  # characters
MAX_VALUE = 64 * 1024  # bytes of any one field (a spawn's JSON is the largest)
MAX_FIELDS = 16


@dataclass(frozen=True)
class Request:
    """A well-formed command: ``values`` holds its numbers (throttle, rcs x/y/z), its hold mode
    or its ship table, by field name."""

    entry_id: str
    cmd: str
    ship_id: str
    values: dict = field(default_factory=dict, hash=False)
    player_id: str = ""
    size: int = 0  # the entry's bytes, for the tick's budget (not journaled)
    origin: str = ""  # its id on the shared stream it was routed from ("" if sent directly)

    def as_json(self) -> dict:
        return {"id": self.entry_id, "cmd": self.cmd, "ship_id": self.ship_id,
                "values": self.values, "player_id": self.player_id, "origin": self.origin}


@dataclass(frozen=True)
class Rejected:
    """An entry that is not a command; ``reason`` is one line naming the field."""

    entry_id: str
    ship_id: str
    reason: str
    cmd: str = ""
    player_id: str = ""
    size: int = 0
    origin: str = ""

    def as_json(self) -> dict:
        return {"id": self.entry_id, "cmd": self.cmd, "ship_id": self.ship_id,
                "reject": self.reason, "player_id": self.player_id, "origin": self.origin}


def from_json(d: dict) -> Request | Rejected:
    """A journal's record back to what :func:`parse` gave."""
    if "reject" in d:
        return Rejected(d["id"], d["ship_id"], d["reject"], d.get("cmd", ""),
                        d.get("player_id", ""), origin=d.get("origin", ""))
    return Request(d["id"], d["cmd"], d["ship_id"], d["values"], d.get("player_id", ""),
                   origin=d.get("origin", ""))


def shard_of(ship_id: str, shards: int) -> int:
    """The shard that owns ``ship_id``: CRC-32 of its UTF-8 bytes modulo the shard count (the
    same on every machine and every run, unlike Python's salted ``hash``)."""
    return zlib.crc32(ship_id.encode("utf-8", "surrogateescape")) % shards


def decode_entry(raw: dict) -> dict[str, str]:
    """Redis gives bytes; undecodable bytes survive as surrogates (and are rejected by parse)."""
    out = {}
    for k, v in raw.items():
        k = k.decode("utf-8", "surrogateescape") if isinstance(k, bytes) else str(k)
        v = v.decode("utf-8", "surrogateescape") if isinstance(v, bytes) else str(v)
        out[k] = v
    return out


def parse(entry_id: str, fields: dict[str, str]) -> Request | Rejected:
    """Check one entry; see the module's docstring for what each command carries."""
    ship_id = fields.get("ship_id", "")
    cmd = fields.get("cmd", "")
    player = fields.get("player_id", "")
    shown_id = ship_id[:MAX_SHIP_ID]
    size = sum(len(k) + len(v) for k, v in fields.items())

    def no(reason: str) -> Rejected:
        ok = len(player) <= MAX_SHIP_ID and _printable(player)
        return Rejected(entry_id, shown_id if _printable(shown_id) else "", reason,
                        cmd if cmd in FIELDS else "", player if ok else "", size)

    if len(fields) > MAX_FIELDS:
        return no(f"{len(fields)} fields (at most {MAX_FIELDS})")
    for k, v in fields.items():
        if len(v) > MAX_VALUE or len(k) > 64:
            return no(f"field {show(k)}: longer than {MAX_VALUE:,} characters")
        if not _printable(k) or (k not in _RAW and not _printable(v)):
            return no(f"field {show(k)}: not printable UTF-8 text")
    if cmd not in FIELDS:
        return no(f"cmd: unknown command {show(cmd)} (one of {', '.join(FIELDS)})")
    if not ship_id:
        return no("ship_id: missing")
    if len(ship_id) > MAX_SHIP_ID:
        return no(f"ship_id: longer than {MAX_SHIP_ID} characters")
    if not player:
        return no("player_id: missing (every command names the player it comes from)")
    if len(player) > MAX_SHIP_ID:
        return no(f"player_id: longer than {MAX_SHIP_ID} characters")
    allowed = {"cmd", "ship_id", "player_id", *FIELDS[cmd]}
    extra = sorted(set(fields) - allowed)
    if extra:
        return no(f"{cmd}: unknown field {show(extra[0])} (it takes "
                  f"{', '.join(FIELDS[cmd]) or 'no fields'} besides cmd, ship_id and "
                  f"player_id)")
    missing = [f for f in FIELDS[cmd] if f not in fields]
    if missing:
        return no(f"{cmd}: missing field {missing[0]!r}")
    kind = KINDS[cmd]
    values: dict = {}
    for f in kind.fields:
        x = f.value(fields[f.name])
        if x is None:
            return no(f"{cmd}: {f.name} must be {f.expects}, got {show(fields[f.name])}")
        values[f.name] = x
    if kind.check is not None:
        values = kind.check(values, ship_id, player)
        if isinstance(values, str):
            return no(values)
    return Request(entry_id, cmd, ship_id, values, player, size)


def _printable(s: str) -> bool:
    return s.isprintable() and not any(0xD800 <= ord(c) <= 0xDFFF for c in s)


#: fields any text may be in (checked by their command: a spawn's JSON)
_RAW = {f.name for k in KINDS.values() for f in k.fields if not f.printable}
