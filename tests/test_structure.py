"""logs/structure.py: a log's MCAP structure as ``mcap doctor`` checks it, held to mcap's own reader
(the independent reference): on a sound log it finds every chunk, message index and summary
record the reader's summary lists, nothing wrong, and the data section's CRC right; on a damaged
one it names the part and the byte (a cut file, a wrong footer, a summary whose CRC fails, a
message index entry that points elsewhere, a changed byte of the data section), and says in one
line what other readers will do."""
from __future__ import annotations

import io
import struct
from pathlib import Path

import pytest
from mcap.reader import make_reader

from touchdown.logs.structure import check, check_entries, data_crc_matches


def summary_of(data: bytes):
    return make_reader(io.BytesIO(data)).get_summary()


def checked(data: bytes):
    return check(io.BytesIO(data))


@pytest.fixture(scope="module")
def sound(bounce_log: Path) -> bytes:
    return bounce_log.read_bytes()


def test_a_sound_log_has_what_mcaps_reader_finds_and_nothing_wrong(sound):
    s = checked(sound)
    ref = summary_of(sound)
    assert not s.damaged and s.problems == [] and s.line() == ""
    assert s.footer_ok and s.summary_ok and s.content_reachable and not s.walk_cut
    assert [c.offset for c in s.chunks] == sorted(ci.chunk_start_offset
                                                  for ci in ref.chunk_indexes)
    assert s.chunk_indexes == len(ref.chunk_indexes) > 1
    assert s.indexed_chunks == [c.offset for c in s.chunks]
    assert [c.length for c in s.chunks] == [ci.chunk_length for ci in
                                            sorted(ref.chunk_indexes,
                                                   key=lambda ci: ci.chunk_start_offset)]
    assert s.message_indexes == sum(len(ci.message_index_offsets) for ci in ref.chunk_indexes)
    assert data_crc_matches(io.BytesIO(sound), s) is True
    # every message index entry points at its message: as many as the statistics count
    assert check_entries(io.BytesIO(sound), s, "bounce.mcap") == ref.statistics.message_count
    assert s.problems == []


def test_not_an_mcap_file():
    s = checked(b"certainly not an mcap file" * 10)
    assert s.damaged and s.problems[0].part == "magic" and s.problems[0].where == 0


def test_a_cut_log_is_a_missing_footer_at_its_end_and_the_walk_stops_in_the_data(sound):
    cut = sound[: len(sound) * 2 // 3]
    s = checked(cut)
    parts = [p.part for p in s.problems]
    assert parts[0] == "footer" and s.problems[0].where == len(cut)
    assert "ends without a footer" in s.problems[0].what
    assert not s.content_reachable  # the Data End record is in the part cut off
    assert data_crc_matches(io.BytesIO(cut), s) is None
    # the chunks before the cut are found whole
    whole = [c.offset for c in checked(sound).chunks]
    assert 0 < len(s.chunks) < len(whole) and [c.offset for c in s.chunks] == \
        whole[:len(s.chunks)]
    assert "the log's structure is damaged: footer at byte" in s.line()


def test_a_footer_pointing_at_the_wrong_summary_start_is_the_footers_fault(sound):
    data = bytearray(sound)
    footer_at = len(data) - 8 - 29  # magic (8) after a footer record (1 + 8 + 20)
    start = struct.unpack_from("<Q", data, footer_at + 9)[0]
    struct.pack_into("<Q", data, footer_at + 9, start + 9)
    s = checked(bytes(data))
    assert s.problems[0].part in ("footer", "summary")
    assert any(p.part == "footer" and p.where == footer_at for p in s.problems)
    assert not s.footer_ok and s.content_reachable  # the data is walked whatever it says


def test_a_changed_summary_byte_fails_its_crc_and_the_content_is_still_reachable(sound):
    data = bytearray(sound)
    footer_at = len(data) - 8 - 29
    start = struct.unpack_from("<Q", data, footer_at + 9)[0]
    data[start + 20] ^= 0x01
    s = checked(bytes(data))
    assert [(p.part, p.where) for p in s.problems] == [("summary", start)]
    assert "CRC" in s.problems[0].what
    assert not s.summary_ok and s.content_reachable and len(s.chunks) == len(checked(sound).chunks)
    assert "read through its chunks" in s.line()


def test_a_changed_data_byte_is_found_by_the_data_sections_crc(sound):
    s0 = checked(sound)
    data = bytearray(sound)
    first = s0.chunks[0]
    data[first.offset + first.length // 2] ^= 0x40  # inside the compressed records
    s = checked(bytes(data))
    assert s.problems == []  # the framing is intact: the walk alone cannot tell
    assert data_crc_matches(io.BytesIO(bytes(data)), s) is False


def test_a_message_index_entry_pointing_elsewhere_is_found_by_the_deep_check(sound):
    s0 = checked(sound)
    chunk = next(c for c in s0.chunks if c.indexes)
    channel, (at, entries) = next(iter(chunk.indexes.items()))
    data = bytearray(sound)
    # the first entry's offset (9-byte record head, channel u16, entries' length u32, then
    # (time u64, offset u64) pairs) moved one byte on
    off_at = at + 9 + 2 + 4 + 8
    struct.pack_into("<Q", data, off_at, int(entries[0]["off"]) + 1)
    s = checked(bytes(data))
    assert s.problems == []  # its framing is sound
    assert check_entries(io.BytesIO(bytes(data)), s, "x.mcap") > 0
    assert [(p.part, p.where) for p in s.problems] == [("message index", at)]
    assert f"does not point at a message of channel {channel}" in s.problems[0].what
