"""service/store.py on a real Redis (the shared one, under a prefix of the test's own): what a
worker relies on from it. One worker holds a shard at a time and a new holder gets a new epoch;
the first worker's shard count and scenario are the service's; a journal written by the holder
reads back as it was sent, one by a worker that lost the shard is refused; a checkpoint is the
holder's alone and what the next holder loads; a renewal says which leases are still this
worker's; Redis's refusals are named as an operator reads them."""
from __future__ import annotations

import uuid

import pytest
import redis

from redis_server import remove_prefix
from touchdown.service import redis_io as rio
from touchdown.service.commands import Rejected, Request
from touchdown.service.store import (CheckpointWrite, Fence, JournalWrite, ShardStore,
                                     refusal_kind)

pytestmark = pytest.mark.redis

LEASE_MS = 5_000


@pytest.fixture
def stores(redis_url):
    """Two workers' stores on one service (prefix of this test's own), removed afterwards."""
    prefix = f"test:store:{uuid.uuid4().hex}"
    keys = rio.Keys(prefix)
    a = ShardStore(redis_url, None, keys, "worker-a")
    b = ShardStore(redis_url, None, keys, "worker-b")
    try:
        yield a, b
    finally:
        a.close()
        b.close()
        remove_prefix(redis_url, prefix)


def test_a_shard_has_one_holder_and_each_holder_a_new_epoch(stores):
    a, b = stores
    took_a = a.take_lease(0, LEASE_MS)
    epoch_a = took_a.epoch
    assert epoch_a == "1:worker-a"
    assert b.take_lease(0, LEASE_MS) is None  # held: refused, whatever b asks
    assert a.holds_lease(0) and not b.holds_lease(0)
    assert b.take_lease(1, LEASE_MS).epoch == "1:worker-b"  # another shard is free
    b.release(0, Fence("worker-b", epoch_a, LEASE_MS))  # not b's to release: nothing happens
    assert a.holds_lease(0)
    a.release(0, Fence("worker-a", epoch_a, LEASE_MS))
    assert not a.holds_lease(0)
    took_b = b.take_lease(0, LEASE_MS)
    assert took_b.epoch == "2:worker-b"  # the epoch counts every holder: an old one is told apart
    # and Redis's clock orders the takes where a number may repeat (an older snapshot)
    assert took_b.taken_us > took_a.taken_us > 1_700_000_000 * 1_000_000


def test_the_first_workers_shard_count_and_scenario_are_the_services(stores):
    a, b = stores
    assert a.agree_on_config(4, '{"name": "fleet"}') == (4, '{"name": "fleet"}')
    assert b.agree_on_config(8, '{"name": "other"}') == (4, '{"name": "fleet"}')


def _requests(tick: int) -> list:
    return [Request(f"{tick}-5", "throttle", "ship-1", {"value": 0.25}, "player-1"),
            Rejected(f"{tick}-6", "ship-2", "throttle: value must be a number in 0..1",
                     "throttle", "player-2")]


def test_the_holders_journal_reads_back_as_written_and_a_lost_holders_is_refused(stores):
    a, b = stores
    a.ensure_group(0)
    fence_a = a.take_lease(0, LEASE_MS)
    got = a.journal([JournalWrite(0, fence_a, 7, _requests(7), None, -1),
                     JournalWrite(0, fence_a, 8, _requests(8), None, 7)])
    assert [(j.k, j.code, j.refused) for j in got] == [(0, 1, None), (0, 1, None)]
    tail = a.journal_since(0, 8)
    assert list(tail.requests) == [8]  # from tick 8 on
    assert tail.requests[8] == _requests(8)
    assert tail.ids == {"8-5", "8-6"}
    # a journal of an earlier tick than the journal holds is refused (-4), nothing written
    earlier = JournalWrite(0, fence_a, 6, _requests(6), None, 8)
    assert [j.code for j in a.journal([earlier])] == [-4]
    assert set(a.journal_since(0, 0).requests) == {7, 8}
    # another worker, even with the holder's epoch, does not hold the lease: -1, nothing written
    not_b = Fence("worker-b", fence_a.epoch, LEASE_MS)
    assert [j.code for j in b.journal([JournalWrite(0, not_b, 9, _requests(9), None, 8)])] == [-1]
    assert set(a.journal_since(0, 0).requests) == {7, 8}


def test_a_checkpoint_is_the_holders_alone_and_what_the_next_holder_loads(stores):
    a, b = stores
    fence_a = a.take_lease(0, LEASE_MS)
    a.write_tables(0, {"ship-1": '[3, {"id": "ship-1"}]'}, {"ship-1": b"params"})
    assert a.checkpoint(0, fence_a, CheckpointWrite(b"state at 10", 10, 0, ())) == 1
    # b, not holding the lease, cannot overwrite it
    assert b.checkpoint(0, Fence("worker-b", fence_a.epoch, LEASE_MS),
                        CheckpointWrite(b"b's state", 11, 0, ())) == -1
    # a checkpoint counting entries that are not on the stream yet would lose them: refused
    assert a.checkpoint(0, fence_a, CheckpointWrite(b"ahead", 12, 5, ())) == -2
    a.release(0, fence_a)
    assert b.take_lease(0, LEASE_MS).epoch == "2:worker-b"
    loaded = b.load(0)
    assert loaded.blob == b"state at 10"
    assert loaded.specs == {"ship-1": [3, {"id": "ship-1"}]}
    assert b.params(0, ["ship-1", "ship-9"]) == [b"params", None]
    assert b.load(1).blob is None  # a new shard: nothing to load


def test_a_checkpoint_drops_the_ships_that_left(stores):
    a, _b = stores
    fence = a.take_lease(0, LEASE_MS)
    a.write_tables(0, {"s1": "[0, {}]", "s2": "[0, {}]"}, {"s1": b"p1", "s2": b"p2"})
    assert a.checkpoint(0, fence, CheckpointWrite(b"cp", 4, 0, ("s1",))) == 1
    assert set(a.load(0).specs) == {"s2"}
    assert a.params(0, ["s1", "s2"]) == [None, b"p2"]


def test_renewal_keeps_this_workers_leases_and_says_which_are_anothers(stores):
    a, b = stores
    e0 = a.take_lease(0, LEASE_MS).epoch
    e1 = b.take_lease(1, LEASE_MS).epoch
    keeper = a.lease_keeper(timeout=2.0)
    try:
        assert keeper.renew([(0, e0), (1, e1), (2, "1:worker-a")], LEASE_MS) == [1, 0, -3]
        assert keeper.heartbeat(5.0) >= 1
        assert a.live_workers() >= 1
    finally:
        keeper.close()


@pytest.mark.parametrize("exc, text, kind", [
    (redis.exceptions.OutOfMemoryError, "command not allowed when used memory > 'maxmemory'",
     "OOM"),
    (redis.exceptions.ReadOnlyError, "You can't write against a read only replica.", "READONLY"),
    (redis.exceptions.NoPermissionError, "this user has no permissions to run the 'xadd' command",
     "NOPERM"),
    (redis.exceptions.ResponseError, "NOPERM User u has no permissions to run the 'eval' command",
     "NOPERM"),
    (redis.exceptions.ResponseError, "MISCONF Redis is configured to save RDB snapshots", "MISCONF"),
    (redis.exceptions.ResponseError, "something lower case", "ResponseError"),
])
def test_a_refusal_is_named_by_redis_error_code(exc, text, kind):
    assert refusal_kind(exc(text), text) == kind


def test_a_lost_holder_learns_the_tick_its_successor_goes_on_from(stores):
    """Where a worker that lost a shard marks its flight log superseded: its successor's
    ``began`` once the current epoch wrote one, and before that (the successor re-stepping, or a
    rollback that lost its ``began`` or kept an older epoch's) what Redis holds: past the last
    journaled tick and the recorded one. (Chaos run of 2026-11-27: Redis back from a snapshot
    holding tick 419 of a shard whose holder had delivered 439; the holder, finding no
    ``began``, kept 439, and a command it applied at 419 that its successor applied at 420 was
    counted twice.)"""
    a, b = stores
    a.ensure_group(0)
    fence_a = a.take_lease(0, LEASE_MS)
    a.began(0, fence_a, 3)  # a's own start: kept by the rollback below
    got = a.journal([JournalWrite(0, fence_a, 7, _requests(7), None, -1),
                     JournalWrite(0, fence_a, 8, _requests(8), None, 7)])
    assert [j.code for j in got] == [1, 1]
    a.r.set(a.keys.shard(0, "tick"), 6)  # the events out up to tick 6 (a snapshot's)
    assert a.successor_start(0, fence_a.epoch) == 9  # nobody else: what Redis holds
    a.release(0, fence_a)
    fence_b = b.take_lease(0, LEASE_MS)
    assert fence_b.epoch == "2:worker-b"
    # b re-stepping: no began of its epoch (a's older one is not b's start)
    assert a.successor_start(0, fence_a.epoch) == 9
    b.began(0, fence_b, 9)
    b.r.set(b.keys.shard(0, "tick"), 20)  # b goes on
    assert a.successor_start(0, fence_a.epoch) == 9
    a.r.set(a.keys.shard(0, "tick"), 12)
    assert a.successor_start(0, fence_a.epoch) == 9  # (b's began, not what it has written since)


def test_a_released_lease_stays_free_while_the_renewals_go_on(stores):
    """A worker that hands a shard over (or stops) frees its lease while its renewal thread runs
    on: a renewal that read the leases before the release must not take the freed one back
    (RENEW takes a lapsed lease back), or the next owner waits a whole lease. Renewals every
    5 ms and 200 releases at whatever moment each comes: without the lock about them a
    renewal lands on some release's heels nearly every run."""
    import time
    from types import SimpleNamespace

    from touchdown.service.leases import Leases

    a, _b = stores
    lease_s = 0.02
    worker = SimpleNamespace(cfg=SimpleNamespace(lease_s=lease_s), store=a, owned={},
                             id="worker-a", where="", log_every=lambda *args: None,
                             _text=str)
    leases = Leases(worker, RuntimeError)
    leases.start()
    held = []
    try:
        for k in range(200):
            fence = a.take_lease(k, 10_000)
            leases.fences[k] = fence
            worker.owned[k] = None
            time.sleep(0.001 * (k % 7))
            leases.release(k, fence)
            time.sleep(0.012)  # more than two renewals
            if a.r.get(a.keys.shard(k, "owner")) is not None:
                held.append(k)
    finally:
        leases.stop()
    assert held == []
