"""logs.shards: which ticks of a live shard's flight logs are the world's when several workers
took the shard in turn, one of them dead before it could mark its file."""
from __future__ import annotations

import math

from touchdown.logs.shards import ShardFile, ShardTake, take_of, world_until
from touchdown.proto import touchdown_pb2 as pb


def test_a_file_is_the_worlds_up_to_and_with_the_first_tick_of_a_later_take():
    """a took shard 0 at tick 0 and was frozen; b took it from Redis's checkpoint at tick 140
    (its first record: the state after tick 140, with that tick's commands applied); a's file,
    never marked, is the world's through tick 140 and not after."""
    a = ShardFile("a", ShardTake(0, "1:a", 1_000), 0)
    b = ShardFile("b", ShardTake(0, "2:b", 2_000), 140)
    assert world_until([a, b]) == {"a": 141, "b": math.inf}


def test_takes_are_ordered_by_redis_clock_not_by_the_epochs_number():
    """Redis started from an older snapshot hands out an epoch number again: c's '2:c' came
    after b's '2:b' and supersedes it, from c's start (earlier than b's: the snapshot's)."""
    b = ShardFile("b", ShardTake(0, "2:b", 2_000), 300)
    c = ShardFile("c", ShardTake(0, "2:c", 3_000), 250)
    a = ShardFile("a", ShardTake(0, "1:a", 1_000), 0)
    got = world_until([b, c, a])
    assert got == {"a": 251, "b": 251, "c": math.inf}


def test_the_files_own_mark_the_other_shards_and_files_without_a_take():
    marked = ShardFile("a", ShardTake(0, "1:a", 1_000), 0, superseded_after_tick=90)
    later = ShardFile("b", ShardTake(0, "2:b", 2_000), 120)
    other_shard = ShardFile("x", ShardTake(1, "1:x", 5_000), 0)
    # (one take's rotated files share its time: neither supersedes the other)
    rotated = [ShardFile("b2", ShardTake(0, "2:b", 2_000), 400)]
    recorded = ShardFile("r", None, 0, superseded_after_tick=None)
    got = world_until([marked, later, other_shard, recorded, *rotated])
    assert got == {"a": 90, "b": math.inf, "x": math.inf, "r": math.inf, "b2": math.inf}


def test_a_take_is_stamped_into_a_header_and_read_back():
    header = pb.ScenarioRecord(name="fleet", start_tick=140, open_ended=True)
    assert take_of(header) is None  # not a service's shard log
    took = ShardTake(3, "7:worker-b", 1_796_218_355_758_944)
    took.stamp(header)
    assert take_of(pb.ScenarioRecord.FromString(header.SerializeToString())) == took
    header.shard_taken_us = 0  # a take without a time (none such is written): no order
    assert take_of(header) is None
