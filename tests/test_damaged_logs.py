"""Damaged and hostile logs: recover what a killed writer left, refuse the rest with one line and
exit 2 -- never a hang, a crash or unbounded memory. Every file here is made by the test."""
import os
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from touchdown.cli import main

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def good(bounce_log):
    return bounce_log  # the built-in bounce (30 s), tests/conftest.py: once a session, read-only


def run_cli(*args):
    r = CliRunner().invoke(main, list(map(str, args)))
    # a user error or a result: never an uncaught exception
    assert r.exception is None or isinstance(r.exception, SystemExit), r.exception
    return r


def assert_one_line_error(r, name):
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and name in lines[0] and "Traceback" not in r.output, r.output


def chunk_offsets(path: Path) -> list[int]:
    from mcap.reader import make_reader
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
        return sorted(ci.chunk_start_offset for ci in summary.chunk_indexes)


def test_a_log_cut_short_replays_its_intact_part(good, tmp_path):
    data = good.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    r = run_cli("replay", cut, "--verify")
    assert r.exit_code == 0, r.output
    assert "ends without a footer" in r.output and "recovered" in r.output
    n = int(r.output.split("recovered ")[1].split(" tick")[0])
    assert 50 < n < 601


def test_a_killed_writer_leaves_a_partial_file_that_verifies(tmp_path):
    out = tmp_path / "killed.mcap"
    proc = subprocess.Popen([sys.executable, str(ROOT / "cli.py"), "record", "bounce", "--set",
                             "duration=100000", "-o", str(out)], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    partial = Path(str(out) + ".partial")
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and (not partial.exists() or partial.stat().st_size < 40_000):
        time.sleep(0.2)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    assert partial.exists() and not out.exists()  # no file under the final name
    r = run_cli("replay", partial, "--verify")
    assert r.exit_code == 0, r.output
    assert "recovered" in r.output


def test_garbage_is_refused(tmp_path):
    bad = tmp_path / "garbage.mcap"
    bad.write_bytes(os.urandom(4096))
    assert_one_line_error(run_cli("replay", bad, "--verify"), "garbage.mcap")
    assert_one_line_error(run_cli("export", bad), "garbage.mcap")


def test_a_file_cut_before_its_scenario_is_refused(good, tmp_path):
    bad = tmp_path / "stub.mcap"
    bad.write_bytes(good.read_bytes()[:30])
    assert_one_line_error(run_cli("replay", bad, "--verify"), "stub.mcap")


def test_a_flipped_byte_inside_a_chunk_is_refused(good, tmp_path):
    data = bytearray(good.read_bytes())
    offsets = chunk_offsets(good)
    pos = offsets[len(offsets) // 2] + 200
    data[pos] ^= 0x40
    bad = tmp_path / "flipped.mcap"
    bad.write_bytes(bytes(data))
    assert_one_line_error(run_cli("replay", bad, "--verify"), "flipped.mcap")


@pytest.mark.parametrize("footer", [True, False])
def test_a_chunk_claiming_gigabytes_is_refused_before_allocating(good, tmp_path, footer):
    data = bytearray(good.read_bytes())
    first = chunk_offsets(good)[0]
    # Chunk record: opcode(1) length(8) message_start(8) message_end(8) uncompressed_size(8)
    struct.pack_into("<Q", data, first + 1 + 8 + 8 + 8, 8 * 1024 ** 3)
    if not footer:
        data = data[: len(data) - 100]
    bad = tmp_path / "bomb.mcap"
    bad.write_bytes(bytes(data))
    # in a process whose address space is capped at 1.5 GiB: refusing must not need the memory
    code = ("import resource,sys; resource.setrlimit(resource.RLIMIT_AS, (3 << 29, 3 << 29)); "
            "sys.argv=['touchdown','replay',sys.argv[1],'--verify']; import cli; cli.main()")
    r = subprocess.run([sys.executable, "-c", code, str(bad)], cwd=ROOT, capture_output=True,
                       text=True, timeout=120)
    if footer:
        assert r.returncode == 2, (r.stdout, r.stderr)
        assert "claims" in r.stderr and "Traceback" not in r.stderr
        assert len(r.stderr.strip().splitlines()) == 1
    else:  # no footer: the damage is where the recovery stops (here, at once)
        assert r.returncode in (0, 1, 2) and "Traceback" not in r.stderr, r.stderr
