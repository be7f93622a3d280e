"""The scripts that keep a shard's history in Redis exactly once (issue 34), each against a
private redis-server: the epoch's fence (a lapsed lease taken back; another owner refused; a
shard whose state Redis lost), the journal written before a tick applies its requests (a write
whose reply never came retracted by the next in one step; a refused XADD changes nothing; a
journal behind what the worker saw refused), the results stream written once, and a read's
reply lost with no error found by the pending count."""
from __future__ import annotations

import json
import time

import pytest
import redis

from touchdown.service import redis_io as rio
from touchdown.service.commands import Request
from touchdown.service.store import JournalWrite, ShardStore
from test_serve_ops import _ready, _server, _stop

pytestmark = pytest.mark.redis


@pytest.fixture
def store(tmp_path):
    server, port = _server(tmp_path / "redis")
    client = redis.Redis(port=port)
    _ready(client)
    keys = rio.Keys("j")
    made = []

    def make(worker: str) -> ShardStore:
        s = ShardStore(f"redis://127.0.0.1:{port}/0", None, keys, worker)
        s.ensure_group(0)
        made.append(s)
        return s
    make.client, make.keys = client, keys
    try:
        yield make
    finally:
        for s in made:
            s.close()
        client.close()
        _stop(server)


def _throttle(eid: str, value: str = "0.5") -> Request:
    return Request(eid, "throttle", "s1", {"value": float(value)}, "p1")


def _send(client, keys, n: int) -> list[str]:
    return [client.xadd(keys.shard_commands(0), {"cmd": "throttle", "ship_id": "s1",
                                                 "player_id": "p1", "value": "0.5"}).decode()
            for _ in range(n)]


def test_a_lapsed_lease_nobody_took_is_taken_back_and_another_owner_is_refused(store):
    a, b = store("a"), store("b")
    client, keys = store.client, store.keys
    fence = a.take_lease(0, 300)
    assert fence.epoch == "1:a"
    assert b.take_lease(0, 300) is None  # held
    time.sleep(0.5)  # lapsed: nobody took it
    assert client.get(keys.shard(0, "owner")) is None
    got = a.journal([JournalWrite(0, fence, 5, [], [], -1)])
    assert got[0].code == 1 and client.get(keys.shard(0, "owner")) == b"a"  # taken back
    time.sleep(0.5)
    assert b.take_lease(0, 300).epoch == "2:b"  # a real new owner: a new epoch
    time.sleep(0.5)  # b's lease lapsed too: a's epoch is not the shard's any more
    assert a.journal([JournalWrite(0, fence, 6, [], [], -1)])[0].code == -1
    keeper = a.lease_keeper(1.0)
    assert keeper.renew([(0, fence.epoch)], 300) == [0]
    keeper.close()
    client.delete(keys.shard(0, "epoch"))  # Redis lost the shard's state
    assert a.journal([JournalWrite(0, fence, 7, [], [], -1)])[0].code == -3


def test_a_journal_write_whose_reply_was_lost_is_retracted_by_the_next_in_one_step(store):
    a = store("a")
    client, keys = store.client, store.keys
    fence = a.take_lease(0, 5000)
    ids = _send(client, keys, 3)
    got = client.xreadgroup(rio.Keys.group(0), "a", {keys.shard_commands(0): ">"})
    assert len(got[0][1]) == 3
    reqs = [_throttle(i) for i in ids]
    # tick 10: written, and the worker never saw the reply (it did not apply them)
    assert a.journal([JournalWrite(0, fence, 10, reqs, [], -1)])[0].code == 1
    assert client.xpending(keys.shard_commands(0), rio.Keys.group(0))["pending"] == 0
    # tick 13: the same requests, the unsure write at 10 retracted in the same script
    assert a.journal([JournalWrite(0, fence, 13, reqs, [10], -1)])[0].code == 1
    journal = client.xrange(keys.shard(0, "journal"))
    assert [e[0] for e in journal] == [b"13-1"]
    assert [r["id"] for r in json.loads(journal[0][1][b"requests"])] == ids
    # a re-send of the same write (its reply lost again) adds nothing
    assert a.journal([JournalWrite(0, fence, 13, reqs, [10], -1)])[0].code == 1
    assert len(client.xrange(keys.shard(0, "journal"))) == 1
    # a worker that saw tick 13 journaled finds a journal behind it (Redis lost writes): -5,
    # nothing written
    client.set(keys.shard(0, "journaled"), 9)
    assert a.journal([JournalWrite(0, fence, 14, reqs, [], 13)])[0].code == -5
    assert len(client.xrange(keys.shard(0, "journal"))) == 1
    # a tick below the journal's last id that is not there: -4, nothing acknowledged
    client.set(keys.shard(0, "journaled"), 13)
    assert a.journal([JournalWrite(0, fence, 12, [_throttle("1-1")], [], 13)])[0].code == -4


def test_a_refused_journal_write_changes_nothing(store, tmp_path):
    """At maxmemory (noeviction) the XADD is refused: the retracted write stays and nothing is
    acknowledged (the XADD comes first in the script)."""
    a = store("a")
    client, keys = store.client, store.keys
    fence = a.take_lease(0, 5000)
    ids = _send(client, keys, 2)
    client.xreadgroup(rio.Keys.group(0), "a", {keys.shard_commands(0): ">"})
    reqs = [_throttle(i) for i in ids]
    assert a.journal([JournalWrite(0, fence, 10, reqs[:1], [], -1)])[0].code == 1
    client.config_set("maxmemory-policy", "noeviction")
    client.config_set("maxmemory", "1")
    try:
        got = a.journal([JournalWrite(0, fence, 11, reqs, [10], -1)])[0]
        assert got.refused is not None
    finally:
        client.config_set("maxmemory", "0")
    assert [e[0] for e in client.xrange(keys.shard(0, "journal"))] == [b"10-1"]
    assert client.xpending(keys.shard_commands(0), rio.Keys.group(0))["pending"] == 1


def test_results_are_written_once_per_tick(store):
    a = store("a")
    client, keys = store.client, store.keys
    for _ in range(2):
        assert client.eval(rio.RESULTS, 1, keys.shard_results(0), "7-1", 100, 7,
                           '{"s":{"applied":["1-1"],"rejected":[]}}') in (0, 1)
    assert len(client.xrange(keys.shard_results(0))) == 1


def test_a_read_whose_reply_was_lost_shows_in_the_pending_count(store):
    a = store("a")
    client, keys = store.client, store.keys
    _send(client, keys, 4)
    # read for a's consumer elsewhere (the reply a never saw: a re-sent pipeline's first batch)
    client.xreadgroup(rio.Keys.group(0), "a", {keys.shard_commands(0): ">"}, count=3)
    got = a.read([(0, ">", 10)])[0]
    assert len(got.entries) == 1 and got.mine == 4 and got.others == 0
    # entries pending to another consumer (an owner that lost the shard): seen as others
    _send(client, keys, 2)
    client.xreadgroup(rio.Keys.group(0), "old-owner", {keys.shard_commands(0): ">"})
    got = a.read([(0, ">", 10)])[0]
    assert got.others == 2


def test_shard_of_is_crc32_ieee_of_the_utf8_id_as_docs_service_says():
    """The test vectors docs/SERVICE.md gives a gateway in any language."""
    from touchdown.service.commands import shard_of
    import zlib
    for sid, crc, of4, of12 in (("s1", 0x141538F0, 0, 4), ("ship-42", 0x183E5A9B, 3, 7),
                                ("Ω-7", 0xF9E8DF26, 2, 10)):
        assert zlib.crc32(sid.encode("utf-8")) == crc
        assert (shard_of(sid, 4), shard_of(sid, 12)) == (of4, of12)
    assert "Ω-7".encode("utf-8") == bytes.fromhex("cea92d37")
