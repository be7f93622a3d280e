"""Publishing transition events to a Redis stream (SPEC.md section 5).

Each entry carries ``event, ship_id, player_id, body`` as plain strings (as the seed shows), plus
``tick``, ``t_event`` (the instant it happened, s), ``from_state``, ``to_state`` and ``proto`` (the
encoded TransitionEvent). One pipeline per
tick keeps the round trips down.
"""
from __future__ import annotations

from typing import Sequence

import redis

from touchdown.logs import LogError
from touchdown.logs.header import LABELS
from touchdown.proto import touchdown_pb2 as pb
from touchdown.sim.enums import EventKind, SurfaceState

DEFAULT_URL = "redis://127.0.0.1:6379/0"
DEFAULT_STREAM = "galaxy:ships"
#: each event kind's topic by number (an enum's call costs a microsecond or two)
_TOPIC = {int(x): x.topic for x in EventKind}


def _instant(ev: pb.TransitionEvent) -> float:
    """When it happened, s (a log from before 0.6 has no t_event_s: the tick's end)."""
    return ev.t_event_s if ev.HasField("t_event_s") else ev.t_s


def _label(value: int) -> str:
    """``SurfaceState(value).label`` by a look-up (an IntEnum member hashes as its number)."""
    got = LABELS.get(value)
    return got if got is not None else SurfaceState(value).label


def entry_fields(ev: pb.TransitionEvent, data: bytes | None = None) -> dict[str, str | bytes]:
    """The stream entry of ``ev``; ``data``: its serialized bytes where the caller has them (the
    log's writer serialized it already)."""
    return {"event": ev.event, "ship_id": ev.ship_id, "player_id": ev.player_id, "body": ev.body,
            "tick": str(ev.tick), "t_event": repr(_instant(ev)),
            "from_state": _label(ev.from_state),
            "to_state": _label(ev.to_state),
            "proto": ev.SerializeToString() if data is None else data}


def event_entry(ev, player_id: str, body: str, data: bytes) -> dict[str, str | bytes]:
    """``entry_fields(m, data)`` of the message ``m`` that logs.header.event_message made of the
    step's event ``ev`` (sim.state.Event) with this ``player_id`` and ``body`` (``data``: its
    bytes), from the event's own numbers: reading ten fields back out of the message cost an
    event 3-5 us on the tick of a touchdown burst (about 1,000 events a tick at 50,000 ships).
    The message always has ``t_event_s`` (event_message sets it)."""
    topic = _TOPIC.get(int(ev.kind))
    return {"event": EventKind(ev.kind).topic if topic is None else topic,
            "ship_id": ev.ship_id, "player_id": player_id, "body": body,
            "tick": str(int(ev.tick)), "t_event": repr(float(ev.t_event_s)),
            "from_state": _label(int(ev.from_state)), "to_state": _label(int(ev.to_state)),
            "proto": data}


def _cluster_enabled(client: redis.Redis) -> bool:
    try:
        return bool(int(client.info("cluster").get("cluster_enabled", 0)))
    except (redis.exceptions.RedisError, ValueError, TypeError):
        return False


class EventPublisher:
    """XADD each event to ``stream``; errors become one-line :class:`LogError`s naming the URL."""

    def __init__(self, url: str = DEFAULT_URL, stream: str = DEFAULT_STREAM):
        self.url, self.stream = url, stream
        try:
            self._client = redis.Redis.from_url(url, socket_connect_timeout=3)
            self._client.ping()
            if _cluster_enabled(self._client):  # a node of a Redis Cluster: its slot map
                from redis.cluster import RedisCluster
                self._client.close()
                self._client = RedisCluster.from_url(url, socket_connect_timeout=3)
        except (redis.exceptions.RedisError, redis.exceptions.RedisClusterException,
                ValueError) as exc:
            raise LogError(f"redis {url}: {exc}") from None

    def publish(self, events: Sequence[pb.TransitionEvent]) -> None:
        if not events:
            return
        try:
            pipe = self._client.pipeline(transaction=False)
            for ev in events:
                pipe.xadd(self.stream, entry_fields(ev))
            pipe.execute()
        except (redis.exceptions.RedisError, redis.exceptions.RedisClusterException) as exc:
            raise LogError(f"redis {self.url}: {exc}") from None

    def close(self) -> None:
        self._client.close()
