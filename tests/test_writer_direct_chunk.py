"""A tick record over the chunk size is written as a chunk of its own straight from the encoder's
buffer (logs.writer.LogWriter._put_chunk, a live service's flight log at scale): the file reads
as the library's own in every reader (the seeking one, the streaming one with its CRCs, the
doctor, replay --verify), with the same messages in the same order."""
from __future__ import annotations

from pathlib import Path

import pytest

from click.testing import CliRunner
from mcap.reader import NonSeekingReader, make_reader

from touchdown.cli import main
from touchdown.logs.encode_block import MESSAGE_HEAD_BYTES
from touchdown.logs.header import TOPIC_TICKS, scenario_message
from touchdown.logs.writer import LogWriter
from touchdown.replay.verify import verify
from touchdown.sim.scenario import parse
from touchdown.sim.world import World


def _scenario(n_ships: int = 40):
    ships = []
    for i in range(n_ships):
        ships.append({"id": f"s{i}", "initial": (
            {"altitude": 2.0 + i % 7, "vertical_speed": -3.0 - i % 5, "east": 12.0 * i}
            if i % 2 else {"state": "landed", "east": 12.0 * i})})
    return parse({"name": "direct", "duration": 1.5, "ships": ships}, "direct")


def _record(path: Path, chunk_size: int, blocks_of: int, n_ships: int = 40,
            flush_every: int = 7) -> None:
    scn = _scenario(n_ships)
    world = World.of(scn)
    with LogWriter(path, scenario_message(scn, "direct", keyframe_interval=10),
                   chunk_size=chunk_size, zstd_level=-8, flush_every_ticks=flush_every) as writer:
        writer.write_block(world.first_block())
        t = 0
        while t < 30:
            if t == 5:
                world.command("s1", throttle=0.7)
            if t == 12:
                world.spawn({"id": "late", "initial": {"altitude": 1.0, "vertical_speed": -9.0,
                                                        "north": 40.0}})
            if t == 20:
                world.retire("s2")
            for block in world.blocks(min(t + blocks_of, 30), max_ticks=blocks_of):
                writer.write_block(block)
            t += blocks_of


def _messages(path: Path, seeking: bool):
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True) if seeking else \
            NonSeekingReader(f, validate_crcs=True)
        return [(c.topic, m.log_time, m.publish_time, m.sequence, bytes(m.data))
                for _s, c, m in reader.iter_messages(log_time_order=False)]


def test_a_tick_over_the_chunk_size_is_a_chunk_read_as_the_librarys(tmp_path):
    plain, direct = tmp_path / "plain.mcap", tmp_path / "direct.mcap"
    _record(plain, 1 << 20, 1)
    _record(direct, 256, 1)  # every tick's record over the chunk size: written directly
    want = _messages(plain, seeking=False)
    assert sum(t == "/ticks" or t.endswith("ticks") for t, *_ in want) > 25
    assert _messages(direct, seeking=False) == want  # file order, CRCs checked
    assert _messages(direct, seeking=True) == _messages(plain, seeking=True)
    with open(direct, "rb") as f:
        summary = make_reader(f).get_summary()
    with open(plain, "rb") as f:
        plain_summary = make_reader(f).get_summary()
    assert summary.statistics.message_count == plain_summary.statistics.message_count
    assert summary.statistics.channel_message_counts == \
        plain_summary.statistics.channel_message_counts
    assert (summary.statistics.message_start_time, summary.statistics.message_end_time) == \
        (plain_summary.statistics.message_start_time, plain_summary.statistics.message_end_time)
    assert summary.statistics.chunk_count == len(summary.chunk_indexes) > 30
    r = CliRunner().invoke(main, ["doctor", str(direct)])
    assert r.exit_code == 0, r.stdout
    assert "verdict: ok" in r.stdout and "problem" not in r.stdout and "warning" not in r.stdout
    assert "data section CRC matches" in r.stdout
    res = verify(str(direct))
    assert res.identical, res.report()


def test_blocks_of_several_ticks_take_the_direct_chunk_for_their_first(tmp_path):
    plain, direct = tmp_path / "plain.mcap", tmp_path / "direct.mcap"
    _record(plain, 1 << 20, 4)
    _record(direct, 256, 4)
    assert _messages(direct, seeking=False) == _messages(plain, seeking=False)
    assert _messages(direct, seeking=True) == _messages(plain, seeking=True)
    assert verify(str(direct)).identical


def _library_put(self, topic: str, tick: int, data) -> None:
    """The writer's messages through the library's own ``Writer.add_message``: the reference."""
    t_ns = tick * self._dt_ns
    self._mcap.add_message(self._channels[topic], log_time=t_ns, data=data, publish_time=t_ns,
                           sequence=self._seq[topic])
    self._seq[topic] += 1


def _library_put_ticks(self, first_tick: int, data, offsets, k0: int, k1: int) -> None:
    """Each tick's TickBatch (after the head the encoder put before it) through the library."""
    view = memoryview(data)
    for k in range(k0, k1):
        _library_put(self, TOPIC_TICKS, first_tick + k,
                     view[offsets[k] + MESSAGE_HEAD_BYTES:offsets[k + 1]])


def _library_put_all(self, topic, tick, datas):
    """A tick's events (LogWriter._put_all) one by one through the library."""
    for data in datas:
        _library_put(self, topic, tick, data)


@pytest.mark.parametrize("n_ships,chunk_size,blocks_of,flush_every", [
    (40, 1 << 20, 1, 7), (40, 2048, 4, 7), (40, 700, 30, 7), (3, 1000, 30, 7), (3, 2500, 7, 7),
    (3, 1000, 30, 0), (3, 1 << 20, 30, 25), (1, 600, 30, 0),
    (300, 2048, 1, 7)])  # (300 ships: up to 20 events a tick, chunk breaks among them)
def test_the_writers_messages_are_the_librarys_byte_for_byte(tmp_path, monkeypatch, n_ships,
                                                             chunk_size, blocks_of, flush_every):
    """LogWriter._put packs each message itself (the library's add_message was nine tenths of a
    small fleet's log), _put_all a tick's events at once: the same file, byte for byte, as
    through the library, chunk breaks, message indexes, statistics and CRCs included (chunks of
    700 bytes: a break every few ticks, 40 ships' records over it, which _put_chunk writes; 3
    ships' a few hundred bytes)."""
    ours, theirs = tmp_path / "ours.mcap", tmp_path / "theirs.mcap"
    _record(ours, chunk_size, blocks_of, n_ships, flush_every)
    with monkeypatch.context() as m:
        m.setattr(LogWriter, "_put", _library_put)
        m.setattr(LogWriter, "_put_ticks", _library_put_ticks)
        m.setattr(LogWriter, "_put_all", _library_put_all)
        _record(theirs, chunk_size, blocks_of, n_ships, flush_every)
    assert len(_messages(ours, seeking=False)) > 30
    assert ours.read_bytes() == theirs.read_bytes()
