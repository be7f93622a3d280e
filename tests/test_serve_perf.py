"""The service at scale (issue 24): what keeps a worker's tick short, checked for what it must
not change. Telemetry made as bytes from the step's arrays is the protobuf message the step's
outputs say; checkpoints are staggered (no tick takes two) and packed off the tick in a format
that still reads the last version's; flight logs at a fast zstd level, encoded on the writer's
thread, with headers of cached JSON, hold the same records and verify; a shard whose take-over
outlasts its lease keeps it; the telemetry stream's default cap. No timing is asserted here (the
machines are shared): ``touchdown bench serve`` measures."""
from __future__ import annotations

import threading
import time
import uuid
import zlib

import numpy as np
import pytest
import redis

import touchdown.scenarios as builtin
from touchdown.bench.speed import fleet_doc
from touchdown.logs.encode import ShipTables
from touchdown.logs.header import record_bytes, world_header, world_header_later
from touchdown.logs.reader import LogReader
from touchdown.logs.rotating import RotatingLog
from touchdown.proto import service_pb2 as spb
from redis_server import redis_url  # noqa: F401  (a pytest fixture)
from touchdown.replay.verify import verify
from touchdown.service import redis_io as rio
from touchdown.service.flightlog import ServiceLog
from touchdown.service.serve import (TELEMETRY_KEEP_S, ServeConfig, Worker, checkpoint_due,
                           shard_phase, telemetry_maxlen)
from touchdown.service.phases import Phases, SlowTicks
from touchdown.service.shard import Shard
from touchdown.service.telemetry import TelemetryEncoder
from touchdown.sim.scenario import parse, parse_text
from touchdown.sim.world import World

pytestmark = pytest.mark.redis


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """Two record arrays hold the same bits in every field (padding aside: a copy need not
    keep it)."""
    return a.shape == b.shape and all(
        np.ascontiguousarray(a[f]).tobytes() == np.ascontiguousarray(b[f]).tobytes()
        for f in a.dtype.names)


def _fleet_world(n: int = 600) -> World:
    doc = fleet_doc(n, 3600.0)
    doc["sim"] = {"dt": 0.1}
    return World.of(parse(doc, "perf"))


# -- telemetry -----------------------------------------------------------------------------
def test_telemetry_bytes_are_the_message_of_the_steps_outputs():
    """Every slice of a rolling period: the bytes are Telemetry(...).SerializeToString(), and
    what they say is the step's own outputs at those rows (state, position, velocity, altitude,
    tilt, fuel), bit for bit."""
    world = _fleet_world()
    for block in world.blocks(7):
        pass
    enc = TelemetryEncoder()
    every, dt = 10, world.params.sim.dt_s
    st, out = block.states[-1], block.outputs[-1]
    for offset in range(every):
        got = enc.encode(st, out, block.ship_ids, block.last_tick, dt, 2, offset, every)
        rows = np.arange(offset, len(block.ship_ids), every)
        assert got == Shard.telemetry(block, rows, dt, 2).SerializeToString()
        msg = spb.Telemetry.FromString(got)
        assert msg.tick == block.last_tick and msg.shard == 2
        assert list(msg.ship_ids) == [block.ship_ids[i] for i in rows]
        assert np.array_equal(np.array(msg.state), st["surface_state"][rows])
        for name, arr in (("pos_m", st["pos_m"]), ("vel_mps", st["vel_mps"]),
                          ("fuel_kg", st["fuel_kg"]), ("altitude_m", out["altitude_m"]),
                          ("cos_tilt", out["cos_tilt"])):
            want = np.ascontiguousarray(arr[rows]).ravel()
            assert np.array_equal(np.array(getattr(msg, name)).view(np.uint64),
                                  want.view(np.uint64)), name


def test_telemetry_of_a_fleet_that_changed_and_of_no_ships():
    """The ids are encoded once per fleet: a fleet that changes (a ship retired) is encoded
    again; a slice with no ships is the three scalars alone."""
    world = _fleet_world(30)
    enc = TelemetryEncoder()
    for block in world.blocks(2):
        pass
    first = enc.encode(block.states[-1], block.outputs[-1], block.ship_ids, block.last_tick,
                       0.1, 0, 1, 10)
    world.retire(world.ship_ids[1])
    for block in world.blocks(4):
        pass
    rows = np.arange(1, len(block.ship_ids), 10)
    again = enc.encode(block.states[-1], block.outputs[-1], block.ship_ids, block.last_tick,
                       0.1, 0, 1, 10)
    assert again == Shard.telemetry(block, rows, 0.1, 0).SerializeToString() != first
    empty = enc.encode(block.states[-1][:0], block.outputs[-1][:0], (), 5, 0.1, 1, 0, 10)
    assert spb.Telemetry.FromString(empty) == spb.Telemetry(tick=5, t_s=0.5, shard=1)


def test_the_telemetry_streams_default_cap_is_ten_seconds_of_samples():
    """10,000 entries (250 s of samples: about 250 MB per 10,000 ships) was the default; now
    what the shards send in 10 simulated seconds, whatever the shard count; the option wins."""
    assert ServeConfig().telemetry_maxlen is None
    assert telemetry_maxlen(ServeConfig(), 0.1) == 400 == int(TELEMETRY_KEEP_S / 0.1) * 4
    assert telemetry_maxlen(ServeConfig(shards=12), 0.1) == 1200
    assert telemetry_maxlen(ServeConfig(telemetry_maxlen=50), 0.1) == 50


def test_the_cli_default_of_telemetry_maxlen(tmp_path):
    from click.testing import CliRunner
    from touchdown import cli
    seen = {}

    class Stop(Exception):
        pass

    def fake_worker(cfg):
        seen["cfg"] = cfg
        raise Stop
    import touchdown.service.serve as serve_mod
    real = serve_mod.Worker
    serve_mod.Worker = fake_worker
    try:
        res = CliRunner().invoke(cli.main, ["serve", "--log-dir", str(tmp_path)])
        assert isinstance(res.exception, Stop), res.output
        assert seen["cfg"].telemetry_maxlen is None
        res = CliRunner().invoke(cli.main, ["serve", "--telemetry-maxlen", "77"])
        assert seen["cfg"].telemetry_maxlen == 77
    finally:
        serve_mod.Worker = real


# -- where the slow ticks went -----------------------------------------------------------------
def test_the_slowest_ticks_are_kept_with_their_phases():
    """SlowTicks keeps the slowest loops (here 2 of 4), each with the wall time of its phases
    of 1 ms or more, slowest first: what bench serve prints beside a trial's p99."""
    into: dict = {}
    phases, slow = Phases(into), SlowTicks(into, keep=2)
    for loop, (step, log) in enumerate([(0.001, 0.0), (0.050, 0.002), (0.003, 0.030),
                                        (0.0005, 0.0)]):
        slow.start()
        phases.add("step", step, step)
        phases.add("log", log, log)
        slow.end(loop, step + log)
    assert slow.slowest() == [{"loop": 1, "tick_s": 0.052, "phases": {"step": 0.05, "log": 0.002}},
                              {"loop": 2, "tick_s": 0.033, "phases": {"step": 0.003, "log": 0.03}}]


# -- checkpoints -----------------------------------------------------------------------------
@pytest.mark.parametrize("shards,every", [(4, 50), (7, 50), (50, 50), (3, 10), (1, 5)])
def test_no_tick_takes_two_shards_checkpoints(shards, every):
    """Each shard's checkpoint comes once every ``every`` ticks, and no tick has two shards'
    (with no more shards than ticks in the period)."""
    per_tick = {}
    for k in range(shards):
        due = [t for t in range(3 * every) if checkpoint_due(k, t, every, shards)]
        assert len(due) == 3 and due[1] - due[0] == every == due[2] - due[1]
        assert due[0] == shard_phase(k, every, shards)  # the flight log's keyframes' too
        for t in due:
            per_tick.setdefault(t, []).append(k)
    assert max(len(v) for v in per_tick.values()) == 1


def test_checkpoints_pack_later_and_the_last_versions_still_read():
    """The records are copied at the tick (the world may move on before the packing runs);
    format 3 (zstd) reads back exactly, and format 2 (zlib, 0.6.0's) still reads."""
    world = _fleet_world(400)
    for _ in world.blocks(5):
        pass
    state, inputs, tick = world.state.rows.copy(), world.inputs.rows.copy(), world.tick
    pack = rio.checkpoint_later(1, 4, world, ["x"], 17)
    for _ in world.blocks(9):  # the world steps on before the packing
        pass
    cp, st, ins = rio.read_checkpoint(pack())
    assert cp.format == 3 and st.tick == tick and list(cp.autoland) == ["x"]
    assert _same(st.rows, state) and _same(ins.rows, inputs)
    old = spb.ShardCheckpoint.FromString(pack())
    old.format = 2
    old.state_rows = zlib.compress(state.tobytes(), 1)
    old.input_rows = zlib.compress(inputs.tobytes(), 1)
    cp2, st2, ins2 = rio.read_checkpoint(old.SerializeToString())
    assert _same(st2.rows, state) and _same(ins2.rows, inputs)
    bad = spb.ShardCheckpoint.FromString(pack())
    bad.state_rows = bad.state_rows[:-9]
    with pytest.raises(ValueError):
        rio.read_checkpoint(bad.SerializeToString())


# -- the flight log --------------------------------------------------------------------------
def test_a_fast_zstd_log_holds_the_same_records_and_verifies(tmp_path):
    """The same world logged at the default level, at zstd -3 and at the service's level
    (encoded on the writer's thread either way): the same tick records, the chunks zstd, and
    each verifies."""
    paths = []
    for level in (None, -3, ServeConfig().log_zstd_level):
        world = _fleet_world(300)
        d = tmp_path / f"level{level}"
        log = RotatingLog(d, world, prefix="f", keyframe_interval=10, open_ended=True,
                          zstd_level=level)
        log.write_block(world.first_block())
        for block in world.blocks(40):
            log.write_block(block)
        log.close()
        assert len(log.files) == 1
        paths.append(log.files[0])
    for other in paths[1:]:
        with LogReader(paths[0]) as a, LogReader(other) as b:
            ta, tb = list(a.ticks()), list(b.ticks())
            assert [t.tick for t in ta] == [t.tick for t in tb] == list(range(0, 41))
            for x, y in zip(ta, tb):
                assert x.arrays.keys() == y.arrays.keys()
                assert all(np.array_equal(x.arrays[f], y.arrays[f]) for f in x.arrays)
    for p in paths:
        res = verify(str(p))
        assert res.divergence is None and res.ticks_compared > 0, res


def test_the_writers_queue_is_bounded_by_bytes_and_always_takes_one():
    """The blocks waiting for a live service's writer are bounded by their bytes (a block in
    the writer's hands counts until it is done) and a count: a put that does not fit waits, and
    says how long; one block larger than the bound goes into an empty queue."""
    from touchdown.logs.writer import _BlockQueue
    q = _BlockQueue(64, 100)
    assert q.put("a", 60) == 0.0 and q.put("b", 30) == 0.0

    def writer():
        time.sleep(0.05)
        assert q.get() == "a"
        q.done()
    th = threading.Thread(target=writer)
    th.start()
    assert q.put("c", 20) > 0.0  # waited for "a" to be done
    th.join()
    assert [q.get(), q.done(), q.get(), q.done()][::2] == ["b", "c"]
    assert q.put("big", 1000) == 0.0 and q.get() == "big"
    q.done()
    few = _BlockQueue(2)  # a count alone (a recording run flat out: QUEUE_BLOCKS)
    assert few.put("a", 10**9) == 0.0 and few.put("b", 10**9) == 0.0
    th = threading.Thread(target=lambda: (time.sleep(0.05), few.get(), few.done()))
    th.start()
    assert few.put("c") > 0.0
    th.join()


def test_headers_from_cached_ship_json_are_the_same_bytes():
    world = _fleet_world(200)
    cached = ShipTables()
    a = world_header(world, "n", "s", 10, True, tables=cached)
    b = world_header(world, "n", "s", 10, True, tables=cached)  # from the cache
    c = world_header(world, "n", "s", 10, True, tables={})
    assert a.SerializeToString() == b.SerializeToString() == c.SerializeToString()
    # a rotation's header, its JSON joined as bytes and spliced in on the writer's thread:
    # the bytes the protobuf library writes for the whole message (a description, a phase)
    later, json_of = world_header_later(world, "n", "s", 10, True, description="resumed",
                                        tables=cached, keyframe_phase=3)
    whole = world_header(world, "n", "s", 10, True, description="resumed", tables={},
                         keyframe_phase=3)
    assert record_bytes(later, json_of()) == whole.SerializeToString()
    with pytest.raises(ValueError):
        record_bytes(whole, b"{}")
    assert len(cached.json) == 200
    empty = World.empty(world.scene)
    assert world_header(empty, "n", "s", tables=ShipTables()).resolved_json == \
        world_header(empty, "n", "s", tables={}).resolved_json


def test_the_shards_first_files_are_staggered(tmp_path):
    """Shard k's first file is bounded at (k+1)/S of the bound, so that the shards' rotations
    (each a header of every ship's table and a keyframe) fall on different ticks; the next
    files have the whole bound."""
    world = _fleet_world(200)
    log = ServiceLog(tmp_path, lambda: world, lambda *a: None, prefix="w", keyframe_interval=10,
                     max_bytes=2_000_000, name="n", source="s", first_bytes=500_000)
    log.start()
    assert log.log.max_bytes == 500_000
    while len(log.files) < 2:
        for block in world.blocks(world.tick + 1):
            log.write_block(block)
    assert log.log.max_bytes == 2_000_000
    log.close()
    for p in log.files:
        res = verify(str(p))
        assert res.divergence is None and res.ticks_compared > 0, res


# -- leases ----------------------------------------------------------------------------------
def test_a_take_over_longer_than_the_lease_keeps_the_shard(redis_url, tmp_path):  # noqa: F811
    """Restoring a large shard can outlast the lease (12,500 ships took 2 s): its lease is
    renewed meanwhile, so the worker does not lose the shard it is taking and take it again."""
    prefix = f"test:perf:{uuid.uuid4().hex[:10]}"
    said: list[str] = []
    fleet = parse_text(builtin.text("fleet"), "fleet")
    w = Worker(ServeConfig(url=redis_url, prefix=prefix, scenario=fleet, rate_hz=20.0,
                           ticks=20, shards=2, lease_s=0.4, log_dir=tmp_path / "flight"),
               say=said.append)
    real = w._take_over
    client = redis.Redis.from_url(redis_url)
    grabbed = []

    def slow(k, fence):
        time.sleep(0.6)  # past the lease, with the shard not yet owned
        grabbed.append(client.set(f"{prefix}:shard:{{{k}}}:owner", "intruder", nx=True,
                                  px=5000))
        time.sleep(0.4)
        real(k, fence)
    w._take_over = slow
    try:
        w.run()
    finally:
        keys = list(client.scan_iter(f"{prefix}:*", count=1000))
        if keys:
            client.delete(*keys)
        client.close()
    assert grabbed == [None, None]
    assert not [line for line in said if "lost" in line], said
    assert sum(": taken (" in line for line in said) == 2
