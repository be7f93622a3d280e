"""The MCAP log: stock readers decode it, it is chunked and compressed with schemas embedded, log
times are simulation time, the fast codec is exact protobuf, and the generated code is current."""
import filecmp
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from google.protobuf.descriptor_pb2 import FileDescriptorSet
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from touchdown.cli import main
from touchdown.logs import LogError
from touchdown.logs.codec import PACKED, encode_tick
from touchdown.logs.decode import decode_tick
from touchdown.logs.header import (TOPIC_EVENTS, TOPIC_SCENARIO, TOPIC_SUMMARY, TOPIC_TICKS,
    scenario_message)
from touchdown.logs.reader import LogReader
from touchdown.logs.writer import LogWriter
from touchdown.proto import touchdown_pb2 as pb
from touchdown.sim.scenario import parse, parse_text
from touchdown import scenarios
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def fleet_log(fleet_log_20s):
    return fleet_log_20s  # recorded once a session (conftest.py)


def test_the_stock_protobuf_decoder_reads_every_message(fleet_log):
    counts = {}
    with open(fleet_log, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _schema, channel, message, decoded in reader.iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == TOPIC_TICKS and message.log_time == 0:
                first = decoded
    assert counts[TOPIC_SCENARIO] == 1 and counts[TOPIC_SUMMARY] == 1
    assert counts[TOPIC_TICKS] == 401 and counts[TOPIC_EVENTS] > 0
    with LogReader(fleet_log) as r:
        mine = next(r.ticks())
    assert first.ship_count == 6 and len(first.pos_m) == 18
    assert list(first.altitude_m) == list(mine.arrays["altitude_m"])
    assert list(first.surface_state) == list(mine.arrays["surface_state"])


def test_chunked_compressed_with_schemas_embedded(fleet_log):
    with open(fleet_log, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary.chunk_indexes and all(c.compression == "zstd" for c in summary.chunk_indexes)
    for schema in summary.schemas.values():
        assert schema.encoding == "protobuf"
        fds = FileDescriptorSet.FromString(schema.data)
        assert any(m.name == schema.name.split(".")[-1] for fd in fds.file for m in fd.message_type)


def test_log_times_are_simulation_time_and_two_recordings_are_identical(tmp_path):
    paths = [tmp_path / "a.mcap", tmp_path / "b.mcap"]
    for p in paths:
        assert CliRunner().invoke(main, ["record", "bounce", "--set", "duration=3", "-o",
                                         str(p)]).exit_code == 0
    msgs = []
    for p in paths:
        with open(p, "rb") as f:
            msgs.append([(c.topic, m.log_time, m.data) for _, c, m in make_reader(f).iter_messages()])
    assert msgs[0] == msgs[1]
    ticks = [(t, d) for topic, t, d in msgs[0] if topic == TOPIC_TICKS]
    assert [t for t, _ in ticks] == [k * 50_000_000 for k in range(len(ticks))]


def random_arrays(rng, n):
    arrays = {}
    for _, name, dt in PACKED:
        width = 4 if "quat" in name else 3 if name in (
            "pos_m", "vel_mps", "omega_body_radps", "pin_pos_bf_m", "pin_pivot_bf_m",
            "rcs_torque_body_nm", "input_rcs") else 1
        if dt == "u1":
            arrays[name] = rng.integers(0, 5 if "state" in name else 2, n * width)
        elif dt == "<i8":
            arrays[name] = rng.integers(-2 ** 40, 2 ** 40, n * width)
        else:
            a = rng.normal(size=n * width) * 10.0 ** rng.integers(-5, 8, n * width)
            a[::7] = 0.0
            a[1::11] = -0.0
            arrays[name] = a
    return arrays


@pytest.mark.parametrize("n", [1, 3, 257])
def test_the_fast_codec_is_exactly_protobuf(n):
    rng = np.random.default_rng(n)
    arrays = random_arrays(rng, n)
    msg = pb.TickBatch(tick=123456, t_s=6172.8, ship_count=n,
                       **{name: arrays[name].tolist() for _, name, _ in PACKED})
    assert encode_tick(123456, 6172.8, n, arrays) == msg.SerializeToString()
    tick, t_s, count, back = decode_tick(msg.SerializeToString())
    assert (tick, t_s, count) == (123456, 6172.8, n)
    for _, name, _ in PACKED:
        assert np.array_equal(back[name], arrays[name]), name


@pytest.mark.parametrize("data", [b"\xff" * 20, b"\x2a\xff\xff\xff\xff\x0f", b"\x2a\x10abc",
                                  b"\x0f", b"\x08"])
def test_decoding_garbage_is_a_log_error(data):
    with pytest.raises(LogError):
        decode_tick(data)


def test_generated_protobuf_code_is_up_to_date(tmp_path):
    r = subprocess.run([sys.executable, str(ROOT / "proto" / "generate.py"), str(tmp_path)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    for name in ("touchdown_pb2.py", "touchdown_pb2.pyi", "service_pb2.py", "service_pb2.pyi",
                 "views_pb2.py", "views_pb2.pyi"):
        assert filecmp.cmp(tmp_path / name, ROOT / "proto" / name, shallow=False), \
            f"proto/{name} is out of date with proto/*.proto: run `python proto/generate.py`"


def test_the_recorded_scenario_reparses_to_the_same_scenario(fleet_log):
    with LogReader(fleet_log) as r:
        rec = r.scenario
    original = parse_text(scenarios.text("fleet"), "fleet", {"duration": 20})
    again = parse(json.loads(rec.resolved_json), "log")
    assert again.resolved == original.resolved
    assert rec.project_version and rec.integrator == "hybrid" and rec.dt_s == 0.05
    assert list(rec.ship_ids) == list(original.params.ships.ship_id)


def test_writer_close_is_idempotent_and_failure_leaves_no_log(tmp_path):
    scn = parse_text(scenarios.text("bounce"), "bounce", {"duration": 1})
    path = tmp_path / "w.mcap"
    w = LogWriter(path, scenario_message(scn, "bounce"))
    w.close()
    w.close()
    assert path.exists()
    bad = tmp_path / "bad.mcap"
    with pytest.raises(RuntimeError):
        with LogWriter(bad, scenario_message(scn, "bounce")):
            raise RuntimeError("boom")
    assert not bad.exists() and not Path(str(bad) + ".partial").exists()


@pytest.mark.parametrize("interval", [1, 3])
def test_the_recorder_encodes_a_block_as_protobuf_does_each_tick(interval):
    """The recorder's compiled block encoder (logs.encode_block.BlockEncoder) gives, for every tick of a
    run, the bytes protobuf gives for that tick's TickBatch (keyframe fields only on keyframes)."""
    from touchdown.logs.encode_block import BlockEncoder
    from touchdown.logs.header import KEYFRAME_ONLY, tick_arrays
    from touchdown.sim.run import run_blocks

    scn = parse_text(scenarios.text("fleet"), "fleet", {"duration": 3.0})
    enc = BlockEncoder(scn.params.sim.dt_s, KEYFRAME_ONLY, interval)
    checked = 0
    for block in run_blocks(scn, max_ticks=7):
        keys = np.arange(len(block.ship_ids))
        data, offsets = enc.encode(block.first_tick, block.states, block.outputs, block.inputs,
                                   keys)
        for k, rec in enumerate(block.records()):
            arrays = tick_arrays(rec, keys)
            keyframe = rec.tick % interval == 0
            msg = pb.TickBatch(
                tick=rec.tick, t_s=rec.tick * scn.params.sim.dt_s, ship_count=rec.state.n,
                **{name: np.asarray(a).ravel().tolist() for name, a in arrays.items()
                   if keyframe or name not in KEYFRAME_ONLY})
            assert data[offsets[k]:offsets[k + 1]].tobytes() == msg.SerializeToString(), rec.tick
            checked += 1
    assert checked == scn.params.sim.n_ticks + 1


def test_the_field_registry_and_the_proto_schema_agree_field_by_field():
    """sim.fields declares each per-ship quantity once; the TickBatch schema (written
    schema-first) holds exactly those, plus the ships' keys, each with the wire type its record
    type needs, and the step's records are built from the registry."""
    from google.protobuf.descriptor import FieldDescriptor as FD

    from touchdown.sim import fields
    from touchdown.sim.state import INPUTS_DTYPE, OUTPUTS_DTYPE, STATE_DTYPE

    packed = {f.name: f for f in pb.TickBatch.DESCRIPTOR.fields
              if f.name not in ("tick", "t_s", "ship_count")}
    assert set(packed) == set(fields.BY_LOG_NAME) | {"ship_key"}
    wire = {"f8": FD.TYPE_DOUBLE, "i8": FD.TYPE_SFIXED64, "?": FD.TYPE_BOOL}
    for f in fields.FIELDS:
        d = packed[f.in_log]
        assert d.is_repeated, f.name
        if f.dtype in wire:
            assert d.type == wire[f.dtype], f.name
        else:  # one-byte enums and flags
            assert d.type in (FD.TYPE_ENUM, FD.TYPE_BOOL, FD.TYPE_UINT32), f.name
        assert f.unit == "" or f.name.endswith(("_m", "_mps", "_radps", "_kg", "_n", "_nm", "_j", "_s")), \
            f"{f.name}: a quantity with a unit names it"
    for record, dtype in (("state", STATE_DTYPE), ("outputs", OUTPUTS_DTYPE),
                          ("inputs", INPUTS_DTYPE)):
        assert dtype.names == tuple(f.name for f in fields.of_record(record))
