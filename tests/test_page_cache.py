"""A live service's flight logs leave the page cache as they are written (logs.page_cache), and
their bytes are the same as a log left to the kernel."""
from __future__ import annotations

import ctypes
import mmap
import os
from pathlib import Path

import pytest

from touchdown.logs import page_cache
from touchdown.logs.header import scenario_message
from touchdown.logs.page_cache import DropWritten
from touchdown.logs.writer import LogWriter
from touchdown.replay.verify import verify
from touchdown.sim.scenario import parse
from touchdown.sim.world import World

PAGE = mmap.PAGESIZE


def _resident_bytes(path: Path) -> int:
    """Bytes of ``path`` in the page cache now (mincore(2) over a mapping of the file)."""
    size = path.stat().st_size
    libc = ctypes.CDLL(None, use_errno=True)
    libc.mmap.restype = ctypes.c_void_p
    libc.mmap.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int, ctypes.c_int,
                          ctypes.c_int, ctypes.c_long]
    libc.mincore.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p]
    libc.munmap.argtypes = [ctypes.c_void_p, ctypes.c_size_t]
    fd = os.open(path, os.O_RDONLY)
    try:
        addr = libc.mmap(None, size, mmap.PROT_READ, mmap.MAP_SHARED, fd, 0)
        assert addr not in (None, ctypes.c_void_p(-1).value), os.strerror(ctypes.get_errno())
        try:
            vec = (ctypes.c_ubyte * ((size + PAGE - 1) // PAGE))()
            assert libc.mincore(ctypes.c_void_p(addr), size, vec) == 0
            return sum(b & 1 for b in vec) * PAGE
        finally:
            libc.munmap(ctypes.c_void_p(addr), size)
    finally:
        os.close(fd)


def _write(path: Path, total: int, drop: DropWritten | None) -> bytes:
    piece = os.urandom(256 << 10)
    with open(path, "wb") as f:
        while f.tell() < total:
            f.write(piece)
            if drop is not None:
                drop.written(f)
    return piece


@pytest.mark.skipif(not hasattr(os, "posix_fadvise"), reason="no posix_fadvise on this system")
def test_written_pages_leave_the_cache_a_step_behind_and_read_back_the_same(tmp_path):
    kept, dropped = tmp_path / "kept.bin", tmp_path / "dropped.bin"
    total, step = 32 << 20, 2 << 20
    _write(kept, total, None)
    piece = _write(dropped, total, DropWritten(step))
    # left to the kernel, the file stays cached (what makes the other figure mean something)
    assert _resident_bytes(kept) > total // 2
    # dropped: at most the last step (and what the page cache's readahead keeps of the tail)
    assert _resident_bytes(dropped) <= step + (256 << 10)
    with open(dropped, "rb") as f:  # read again from the disk, byte for byte
        data = f.read()
    assert len(data) == total and data == piece * (total // len(piece))


def _scenario(n_ships: int = 300):
    ships = [{"id": f"s{i}", "initial": {"altitude": 2.0 + i % 7, "vertical_speed": -3.0 - i % 5,
                                         "east": 12.0 * i}} for i in range(n_ships)]
    return parse({"name": "cache", "duration": 2.0, "ships": ships}, "cache")


def _record(path: Path, drop_cache: bool) -> None:
    scn = _scenario()
    world = World.of(scn)
    with LogWriter(path, scenario_message(scn, "cache", keyframe_interval=1), chunk_size=1 << 16,
                   zstd_level=-8, drop_cache=drop_cache) as writer:
        writer.write_block(world.first_block())
        for block in world.blocks(40, max_ticks=1):
            writer.write_block(block)


def test_a_log_written_out_of_the_cache_is_the_same_log(tmp_path, monkeypatch):
    monkeypatch.setattr(page_cache, "STEP_BYTES", 64 << 10)  # many steps in a small log
    plain, dropped = tmp_path / "plain.mcap", tmp_path / "dropped.mcap"
    _record(plain, False)
    _record(dropped, True)
    assert plain.stat().st_size > 10 * (64 << 10)
    assert _resident_bytes(dropped) < plain.stat().st_size // 2  # (before reading it back)
    assert dropped.read_bytes() == plain.read_bytes()
    res = verify(str(dropped))
    assert res.identical, res.report()


def test_a_services_flight_log_leaves_the_cache_and_keep_cache_leaves_it(tmp_path, monkeypatch):
    from touchdown.service.flightlog import ServiceLog

    monkeypatch.setattr(page_cache, "STEP_BYTES", 64 << 10)
    resident = {}
    for drop in (True, False):
        world = World.of(_scenario())
        folder = tmp_path / f"drop-{drop}"
        log = ServiceLog(folder, lambda: world, lambda *a: None, prefix="w", keyframe_interval=1,
                         max_bytes=1 << 30, name="n", source="s", zstd_level=-8,
                         drop_cache=drop)
        log.start()
        for block in world.blocks(40, max_ticks=1):
            log.write_block(block)
        log.close()
        (path,) = folder.iterdir()
        assert path.stat().st_size > 10 * (64 << 10)
        resident[drop] = _resident_bytes(path) / path.stat().st_size
    assert resident[True] < 0.5 < resident[False], resident
