"""bench/chaos.py's Follower (what a gateway reads as it goes) keeps the latest version of each
event ``seq`` and each tick's results: after a rollback a new owner publishes its own history
under the numbers and ticks the old owner used. (Chaos run of 2026-11-27: the new owner's
rejection of a throttle, published as seq 0:508 and in tick 433's results, was hidden behind
the old owner's superseded 0:508 and tick 433, and the throttle counted lost.)"""
from __future__ import annotations

from touchdown.bench.chaos import Follower
from touchdown.service import redis_io as rio


class _Streams:
    """A client's XRANGE over streams held here (ids ascending)."""

    def __init__(self):
        self.streams: dict = {}

    def add(self, stream: str, entry_id: str, fields: dict) -> None:
        self.streams.setdefault(stream, []).append(
            (entry_id.encode(), {k.encode(): str(v).encode() for k, v in fields.items()}))

    def xrange(self, stream, start, end="+", count=None):
        def key(eid: bytes):
            ms, n = eid.decode().split("-")
            return int(ms), int(n)
        got = self.streams.get(stream, [])
        if start != "-":
            lo = key(start[1:].encode())
            got = [(i, f) for i, f in got if key(i) > lo]
        return got[:count]


def test_the_latest_version_of_a_seq_and_of_a_ticks_results_is_kept():
    keys = rio.Keys("chaos")
    f = Follower(lambda: None, keys, 1)
    c = _Streams()
    events, results = keys.all_events(1)[0], keys.shard_results(0)
    c.add(events, "100-0", {"event": "ship.contact", "ship_id": "s218", "seq": "0:508"})
    c.add(results, "433-1", {"tick": "433", "results": '{"s":{"applied":["1-0"]}}'})
    f.poll(c)
    # Redis rolled back; the new owner's history, under the same numbers and ticks
    c.add(events, "200-0", {"event": "ship.command_rejected", "ship_id": "s226", "seq": "0:508"})
    c.add(results, "433-2", {"tick": "433", "results": '{"s":{"rejected":["2-0"]}}'})
    f.poll(c)
    assert f.events["0:508"]["event"] == "ship.command_rejected"
    assert "rejected" in f.results[(0, "433")]["results"]
    assert len(f.events) == 1 and len(f.results) == 1
