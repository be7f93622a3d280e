"""A corpus of damaged logs (issue 37, items 2-5), each with what ``touchdown doctor`` must say
and what ``replay --verify``, ``export`` and ``recover`` do with it.

``touchdown doctor`` is held to make every check of Go's ``mcap doctor`` (read in
foxglove/mcap, go/cli/mcap/cmd/doctor.go; its Rust successor makes the same) and more: each
damage below is one a user met, or one of those checks (the message in the Go doctor is quoted
where doctor words it the same). Where a damage is to a summary whose CRC would give it away,
the CRC is recomputed, as a writer with a bug would have written it, so that the check itself
is what must find it. Every file is made by the test from a log it records."""
from __future__ import annotations

import io
import signal
import struct
import subprocess
import sys
import time
import zlib
from pathlib import Path

import pytest
from click.testing import CliRunner
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from touchdown.cli import main
from touchdown.logs.examine import examine

ROOT = Path(__file__).resolve().parents[1]
FOOTER = 29


@pytest.fixture(scope="module")
def bounce(bounce_log):
    return bounce_log  # tests/conftest.py: recorded once a session, read-only


def invoke(*args):
    r = CliRunner().invoke(main, [str(a) for a in args])
    assert r.exception is None or isinstance(r.exception, SystemExit), r.exception
    return r


def records_of(data: bytes) -> list[tuple[int, int, int]]:
    """(offset, opcode, content length) of every top-level record, the footer included."""
    out, pos = [], 8
    while pos < len(data) - 8:
        op, n = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
        out.append((pos, op, n))
        if op == 0x02:
            break
        pos += 9 + n
    return out


def first(data, op: int, k: int = 0) -> tuple[int, int]:
    """(offset, content length) of the k-th record of opcode ``op``."""
    hits = [(o, n) for o, p, n in records_of(data) if p == op]
    return hits[k]


def fix_summary_crc(data: bytearray) -> None:
    """The footer's summary CRC recomputed over the summary as it now is."""
    at = len(data) - 8 - FOOTER
    start, offsets = struct.unpack_from("<QQ", data, at + 9)
    crc = zlib.crc32(bytes(data[start:at + 25]))
    struct.pack_into("<I", data, at + 25, crc)


def fix_data_crc(data: bytearray) -> None:
    """The Data End record's CRC recomputed over the data section as it now is."""
    at, _ = first(data, 0x0F)
    struct.pack_into("<I", data, at + 9, zlib.crc32(bytes(data[:at])))


# -- the damages: each a function of the log's bytes ------------------------------------------------
def header_string_past_record(d):
    """Item 2: the header's first string claims 271 bytes (Foxglove: "String length 271 exceeds
    bounds of buffer")."""
    struct.pack_into("<I", d, 8 + 9, 271)


def chunk_end_time_flipped(d):
    """Item 2: one bit of a chunk's message_end_time (disagreeing with its messages and with
    its chunk index)."""
    at, _ = first(d, 0x06, 1)
    d[at + 9 + 8 + 2] ^= 0x10


def chunk_start_time_and_index(d):
    """A chunk's message_start_time and its chunk index's, both later than its first message
    (a writer's bug: the summary's CRC fits): only the messages tell."""
    at, _ = first(d, 0x06, 1)
    t = struct.unpack_from("<Q", d, at + 9)[0] + 1
    struct.pack_into("<Q", d, at + 9, t)
    for o, op, _n in records_of(d):
        if op == 0x08 and struct.unpack_from("<Q", d, o + 9 + 16)[0] == at:
            struct.pack_into("<Q", d, o + 9, t)
    fix_data_crc(d)
    fix_summary_crc(d)


def summary_start_bit(d):
    """Item 3: one flipped bit in the footer's summary_start."""
    d[len(d) - 8 - FOOTER + 9 + 1] ^= 0x01


def footer_opcode(d):
    """The footer record's opcode overwritten."""
    d[len(d) - 8 - FOOTER] = 0x77


def metadata_byte(d):
    """Item 4: one byte of the `touchdown` metadata record's values (no other CRC covers it)."""
    at, n = first(d, 0x0C)
    d[at + 9 + n - 3] ^= 0x01


def metadata_not_utf8(d):
    """A metadata string that is not UTF-8 (the data section's CRC made to fit)."""
    at, n = first(d, 0x0C)
    d[at + 9 + n - 3] = 0xFF
    fix_data_crc(d)


def message_index_entry(d):
    """A message index entry pointing at another message of its chunk (within bounds)."""
    at, n = max(((o, n) for o, op, n in records_of(d) if op == 0x07), key=lambda r: r[1])
    second = struct.unpack_from("<Q", d, at + 9 + 6 + 16 + 8)[0]
    struct.pack_into("<Q", d, at + 9 + 6 + 8, second)  # the first entry at the second's message
    fix_data_crc(d)


def statistics_count(d):
    """Statistics.message_count one too many (the summary's CRC made to fit)."""
    at, _ = first(d, 0x0B)
    n = struct.unpack_from("<Q", d, at + 9)[0]
    struct.pack_into("<Q", d, at + 9, n + 1)
    fix_summary_crc(d)


def summary_offset(d):
    """A summary offset whose group starts 9 bytes late (the summary's CRC made to fit)."""
    at, _ = first(d, 0x0E, 1)
    start = struct.unpack_from("<Q", d, at + 9 + 1)[0]
    struct.pack_into("<Q", d, at + 9 + 1, start + 9)
    fix_summary_crc(d)


def data_end_crc(d):
    """The Data End record's CRC itself."""
    at, _ = first(d, 0x0F)
    d[at + 9] ^= 0xFF


def summary_byte(d):
    """One byte of the statistics record (the summary's CRC gives it away)."""
    at, _ = first(d, 0x0B)
    d[at + 9 + 8 + 1] ^= 0x04


def chunk_index_message_index_offset(d):
    """A chunk index's message index offset one record late (the summary's CRC made to fit)."""
    at, _ = first(d, 0x08)
    n_map = struct.unpack_from("<I", d, at + 9 + 32)[0]
    assert n_map >= 10
    ch, off = struct.unpack_from("<HQ", d, at + 9 + 36)
    struct.pack_into("<Q", d, at + 9 + 38, off + 1)
    fix_summary_crc(d)


#: name -> (damage, doctor's words (each must appear in a problem line), what replay --verify
#: does: "note" exit 0 with a one-line note of the damage naming this part, "quiet" exit 0)
CORPUS = {
    "header string past its record": (
        header_string_past_record,
        ["header at byte 8: the header record: its profile's length 271 runs past the end"],
        ("note", "header at byte 8")),
    "chunk end time flipped": (
        chunk_end_time_flipped,
        ["Chunk.message_end_time", "does not match the latest message log time",
         "its message end time is"],
        ("note", "chunk at byte")),
    "chunk start time, index agreeing": (
        chunk_start_time_and_index,
        ["Chunk.message_start_time", "does not match the earliest message log time"],
        ("note", "chunk at byte")),
    "summary_start bit flipped": (
        summary_start_bit,
        ["footer at byte", "its summary_start", "is not where the summary section begins"],
        ("note", "footer at byte")),
    "footer record damaged": (
        footer_opcode, ["not a Footer record"], ("note", "footer at byte")),
    "metadata byte (data CRC)": (
        metadata_byte, ["the data section's CRC does not match its bytes"],
        ("note", "the data section's CRC does not match")),
    "metadata not UTF-8": (
        metadata_not_utf8, ["metadata at byte", "is not valid UTF-8"],
        ("note", "metadata at byte")),
    "message index entry misplaced": (
        message_index_entry, ["does not point at a message of channel"], ("quiet", "")),
    "statistics message count": (
        statistics_count, ["Statistics.message_count is 608, the file holds 607"],
        ("note", "its statistics count 608 messages")),
    "summary offset misplaced": (
        summary_offset, ["the summary offset of the", "records says bytes"], ("quiet", "")),
    "data end CRC": (
        data_end_crc, ["the data section's CRC does not match its bytes"],
        ("note", "the data section's CRC does not match")),
    "summary byte (summary CRC)": (
        summary_byte, ["summary at byte", "its CRC does not match the footer's"],
        ("note", "summary at byte")),
    "chunk index's message index offset": (
        chunk_index_message_index_offset, ["points at message indexes that are not there"],
        ("note", "message index at byte")),
}


def test_a_sound_log_has_nothing_said_of_it(bounce):
    r = invoke("doctor", bounce)
    assert r.exit_code == 0, r.stdout
    assert "verdict: ok" in r.stdout and "problem" not in r.stdout and "warning" not in r.stdout
    assert "data section CRC matches" in r.stdout and "its CRC matches" in r.stdout
    assert "607 message(s)" in r.stdout and "607 entries checked" in r.stdout


@pytest.mark.parametrize("name", sorted(CORPUS))
def test_doctor_names_each_damage_and_verify_reads_around_it(bounce, tmp_path, name):
    damage, words, (verify_does, note) = CORPUS[name]
    data = bytearray(bounce.read_bytes())
    damage(data)
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    r = invoke("doctor", bad)
    assert r.exit_code == 1, r.stdout
    problems = [ln for ln in r.stdout.splitlines() if ln.strip().startswith("problem:")]
    for w in words:
        assert any(w in ln for ln in problems), (w, r.stdout)
    assert "601 tick record(s)" in r.stdout  # the content is all there, and said to be
    r = invoke("replay", bad, "--verify")
    assert r.exit_code == 0 and "identical: ticks 0..600" in r.stdout, r.output
    notes = [ln for ln in r.stdout.splitlines() if "structure is damaged" in ln]
    if verify_does == "note":
        assert len(notes) == 1 and note in notes[0], r.stdout
    else:
        assert not notes, r.stdout


def test_a_flipped_bit_in_summary_start_is_read_around_by_every_command(bounce, tmp_path):
    """Item 3: the streaming readers of both MCAP libraries read all 607 messages; so does
    Touchdown now (it refused the log, exit 2), and says what is damaged."""
    data = bytearray(bounce.read_bytes())
    summary_start_bit(data)
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    assert sum(1 for _ in StreamReader(io.BytesIO(bytes(data))).records
               if type(_).__name__ == "Message") == 607
    r = invoke("export", bad)
    assert r.exit_code == 0 and len(r.stdout.splitlines()) == 601, r.stderr
    assert "footer at byte" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = invoke("export", bad, "--events")
    assert r.exit_code == 0 and len(r.stdout.splitlines()) == 4


def test_a_changed_metadata_byte_is_found_by_the_data_crc_and_by_mcaps_reader(bounce, tmp_path):
    """Item 4: the data section's CRC is written; mcap's own StreamReader with CRCs on finds
    the change too."""
    data = bytearray(bounce.read_bytes())
    metadata_byte(data)
    with pytest.raises(Exception, match="crc validation failed in DataEnd"):
        for _ in StreamReader(io.BytesIO(bytes(data)), validate_crcs=True).records:
            pass
    for _ in StreamReader(io.BytesIO(bounce.read_bytes()), validate_crcs=True).records:
        pass  # the sound log's CRCs all match


@pytest.mark.slow
def test_a_killed_writers_log_is_recovered_whole_indexed_and_verified(tmp_path):
    """Item 5: a killed writer's .partial file; Python's make_reader cannot open it;
    ``touchdown recover`` rewrites its whole ticks as a complete, indexed MCAP that
    make_reader reads with every CRC, that doctor passes and that verifies; with
    --require-complete, verify says it is not the whole run (exit 1)."""
    out = tmp_path / "killed.mcap"
    proc = subprocess.Popen([sys.executable, str(ROOT / "cli.py"), "record", "bounce", "--set",
                             "duration=100000", "-o", str(out)], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    partial = Path(f"{out}.partial")
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and (not partial.exists()
                                           or partial.stat().st_size < 60_000):
        time.sleep(0.2)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    with open(partial, "rb") as f, pytest.raises(Exception):
        list(make_reader(f).iter_messages())
    r = invoke("doctor", partial)
    assert r.exit_code == 1 and "does not end with MCAP's magic" in r.stdout, r.stdout
    fixed = tmp_path / "fixed.mcap"
    r = invoke("recover", partial, "-o", fixed)
    assert r.exit_code == 0 and "a summary was added" in r.stdout, r.output
    with open(fixed, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        assert summary.chunk_indexes and summary.statistics.message_count > 100
        n = sum(1 for _ in reader.iter_messages())
    assert n == summary.statistics.message_count
    r = invoke("doctor", fixed)
    assert r.exit_code == 0 and "verdict: ok" in r.stdout, r.stdout
    r = invoke("replay", fixed, "--verify")
    assert r.exit_code == 0 and "identical" in r.stdout and "recovered" in r.stdout, r.stdout
    r = invoke("replay", fixed, "--verify", "--require-complete")
    assert r.exit_code == 1 and "not complete" in r.stdout, r.stdout
    assert not Path(f"{fixed}.partial").exists()


def test_recover_of_a_sound_log_is_the_same_log_and_of_a_damaged_one_its_readable_part(
        bounce, tmp_path):
    same = tmp_path / "same.mcap"
    assert invoke("recover", bounce, "-o", same).exit_code == 0
    r = invoke("replay", same, "--verify", "--require-complete")
    assert r.exit_code == 0 and "identical: ticks 0..600" in r.stdout, r.stdout
    # a flipped byte inside a chunk (its CRC fails): the ticks before that chunk are kept
    data = bytearray(bounce.read_bytes())
    at, n = first(data, 0x06, 2)
    data[at + n // 2] ^= 0x40
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    assert invoke("replay", bad, "--verify").exit_code == 2  # refused, as before
    part = tmp_path / "part.mcap"
    r = invoke("recover", bad, "-o", part)
    assert r.exit_code == 0 and "CRC" in r.stdout, r.stdout
    r = invoke("replay", part, "--verify")
    assert r.exit_code == 0 and "identical: ticks 0.." in r.stdout, r.stdout
    garbage = tmp_path / "garbage.mcap"
    garbage.write_bytes(b"not an MCAP file at all")
    r = invoke("recover", garbage, "-o", tmp_path / "g.mcap")
    assert r.exit_code == 2 and "not an MCAP file" in r.stderr
    assert not (tmp_path / "g.mcap").exists()


def test_require_complete_tells_a_cut_log_from_a_whole_one(bounce, tmp_path):
    """Item 6: a log cut after its first ticks verifies its readable part with exit 0 (as
    documented); --require-complete exits 1 and says why."""
    r = invoke("replay", bounce, "--verify", "--require-complete")
    assert r.exit_code == 0 and "not complete" not in r.stdout
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(bounce.read_bytes()[:12_000])
    r = invoke("replay", cut, "--verify")
    assert r.exit_code == 0 and "recovered" in r.stdout, r.stdout
    r = invoke("replay", cut, "--verify", "--require-complete")
    assert r.exit_code == 1 and "not complete: the log ends without a footer" in r.stdout
    assert invoke("replay", bounce, "--verify", "--require-complete", "--from-tick",
                  "5").exit_code == 2


def test_the_doctor_checks_any_mcap_file_attachments_and_metadata_too(tmp_path):
    """A file of the stock writer with an attachment, metadata and uncompressed chunks: sound;
    its attachment's CRC changed: found; a message record outside a chunk is allowed."""
    buf = io.BytesIO()
    w = Writer(buf, compression=CompressionType.NONE, enable_data_crcs=True)
    w.start(profile="", library="test")
    sid = w.register_schema("s", "jsonschema", b"{}")
    cid = w.register_channel("/a", "json", sid)
    for k in range(50):
        w.add_message(cid, log_time=k, data=b'{"k": %d}' % k, publish_time=k)
    w.add_attachment(create_time=1, log_time=2, name="notes.txt", media_type="text/plain",
                     data=b"hello")
    w.add_metadata("m", {"a": "b"})
    w.finish()
    data = bytearray(buf.getvalue())
    path = tmp_path / "any.mcap"
    path.write_bytes(bytes(data))
    with open(path, "rb") as f:
        x = examine(f, str(path))
    assert not x.errors and x.messages == 50 and x.data_crc == "matches", x.findings
    at, n = first(data, 0x09)
    data[at + 9 + n - 6] ^= 0x01  # a byte of the attachment's data
    path.write_bytes(bytes(data))
    with open(path, "rb") as f:
        x = examine(f, str(path))
    assert any("the attachment 'notes.txt''s CRC does not match" in e.what for e in x.errors)
