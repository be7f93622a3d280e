"""A live service's shard logs taken together (``touchdown serve``): which ticks of each file are
the world's.

A shard's run is written by whichever worker holds it, each take of it (an epoch, ``N:worker``)
into files of its own, whose header names the shard, the epoch and when Redis granted the take
(``ScenarioRecord.shard``, ``shard_epoch``, ``shard_taken_us``). A new owner goes on from what
Redis holds: its first file begins with the shard's checkpoint, the state after tick
``start_tick`` (the joins, leaves and commands of that tick applied), and it re-steps the ticks
Redis journaled after it, with the same commands at the same ticks. What a file of an earlier
take holds after that ``start_tick`` is either the same again or a history the world did not keep
(its worker was cut off or frozen, or Redis lost its writes), and that worker may die before it
can say so: ``LogSummary.superseded_after_tick`` is written only by a worker that lives to see it
lost the shard. So a file is the world's run for the ticks before

    until = min(superseded_after_tick, 1 + start_tick of every file of the shard taken later)

Takes are ordered by Redis's clock (``TIME`` in the TAKE script, service.redis_io), not by the
epoch's number: Redis started from an older snapshot hands out a number again. Files without a
take (``touchdown record``, or a service older than touchdown 0.8) are read to their mark alone.
"""
from __future__ import annotations

from collections.abc import Hashable, Iterable
from dataclasses import dataclass

from touchdown.proto import touchdown_pb2 as pb


@dataclass(frozen=True)
class ShardTake:
    """One take of a shard: the shard, its epoch (``N:worker``), and when Redis granted it
    (µs since 1970, by Redis's clock)."""
    shard: int
    epoch: str
    taken_us: int

    def stamp(self, header: pb.ScenarioRecord) -> None:
        """Write this take into a file's header."""
        header.shard = self.shard
        header.shard_epoch = self.epoch
        header.shard_taken_us = self.taken_us


def take_of(header: pb.ScenarioRecord) -> ShardTake | None:
    """The take a file's header names, or None (not a service's shard log, or an older one)."""
    if not header.HasField("shard") or not header.shard_taken_us:
        return None
    return ShardTake(int(header.shard), header.shard_epoch, int(header.shard_taken_us))


@dataclass(frozen=True)
class ShardFile:
    """What the rule needs of one file: its key (a path, say), its take, its first tick, and the
    tick its own summary says it is superseded after (None: no mark)."""
    key: Hashable
    take: ShardTake | None
    start_tick: int
    superseded_after_tick: int | None = None


def shard_file(reader, key: Hashable) -> ShardFile:
    """What the rule needs of an open log (a logs.reader.LogReader), under ``key``."""
    summary = reader.read_summary() if reader.status.complete else None
    mark = summary.superseded_after_tick if summary is not None and summary.HasField(
        "superseded_after_tick") else None
    return ShardFile(key, take_of(reader.scenario), reader.start_tick, mark)


def world_until(files: Iterable[ShardFile]) -> dict[Hashable, float]:
    """Each file's ``until``: the world's run is its ticks ``< until`` (``inf``: all of them)."""
    files = list(files)
    starts: dict[int, list[tuple[int, int]]] = {}  # shard -> [(taken_us, start_tick)]
    for f in files:
        if f.take is not None:
            starts.setdefault(f.take.shard, []).append((f.take.taken_us, f.start_tick))
    out: dict[Hashable, float] = {}
    for f in files:
        until = float("inf") if f.superseded_after_tick is None else f.superseded_after_tick
        if f.take is not None:
            for taken_us, start in starts[f.take.shard]:
                if taken_us > f.take.taken_us:
                    until = min(until, start + 1)
        out[f.key] = until
    return out


__all__ = ["ShardTake", "ShardFile", "take_of", "shard_file", "world_until"]
