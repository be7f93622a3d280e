"""The block encoder's word stores (logs.encode_block._put_fields: each eight-byte number stored
as a whole word, shifted across the buffer's words where a field begins off a word boundary)
give exactly the bytes of the byte-by-byte path, for fleets whose fields begin at every offset
mod 8, keyframes and in-between ticks, with and without keys."""
from __future__ import annotations

import struct

import numpy as np
import pytest

from touchdown import scenarios
from touchdown.logs import encode_block as eb
from touchdown.logs.header import KEYFRAME_ONLY
from touchdown.proto import touchdown_pb2 as pb
from touchdown.sim.scenario import parse_text
from touchdown.sim.run import run_blocks

#: an MCAP Message record's head as the library packs it (mcap.records.Message.write)
MESSAGE_HEAD = struct.Struct("<BQHIQQ")


def _encode(enc, block, keys, little, first_keyframe, head=(-1, 0, 0)):
    k, n = block.states.shape
    keys64 = (np.zeros((n, 1), np.uint64) if keys is None else
              np.ascontiguousarray(keys, dtype=np.int64).view(np.uint64).reshape(n, 1))
    views = [np.ascontiguousarray(a).view(np.uint8).reshape(k, n, a.dtype.itemsize)
             for a in (block.states, block.outputs, block.inputs)]
    ticks = np.arange(block.first_tick, block.first_tick + k, dtype=np.int64)
    t_s = ticks * enc.dt_s
    t_bytes = t_s.astype("<f8").view(np.uint8).reshape(k, 8)
    out = np.zeros((k * enc._bytes_per_tick(n) // 8 + 2) * 8, np.uint8)
    offsets = np.empty(k + 1, np.int64)
    assert eb._encode_ticks(*views, keys64, enc.table, ticks, t_s, t_bytes, enc.keyframe_interval,
                            enc.keyframe_phase, first_keyframe, out, offsets, little,
                            np.array(head, np.int64)) >= 0
    return out[:offsets[-1]].tobytes(), offsets


@pytest.mark.skipif(not eb.LITTLE, reason="word stores are the little-endian path")
def test_word_stores_give_the_bytes_of_byte_stores():
    scn = parse_text(scenarios.text("fleet"), "fleet", {"duration": 1.0})
    blocks = list(run_blocks(scn, max_ticks=4))
    seen_offsets = set()
    for interval in (1, 3):
        enc = eb.BlockEncoder(scn.params.sim.dt_s, KEYFRAME_ONLY, interval)
        for block in blocks:
            n = block.states.shape[1]
            for m in range(1, n + 1):  # fewer ships: fields begin elsewhere (mod 8)
                part = type(block)(block.first_tick, block.states[:, :m], block.outputs[:, :m],
                                   block.inputs[:, :m], [], block.ship_ids[:m])
                for keys in (np.arange(m, dtype=np.int64) * 1_000_003, None):
                    for first in (False, True):
                        words, o1 = _encode(enc, part, keys, True, first)
                        bytewise, o2 = _encode(enc, part, keys, False, first)
                        assert (o1 == o2).all() and words == bytewise, (interval, m, first)
                        seen_offsets.update(int(x) % 8 for x in o1)
                        # each tick as a Message record: the library's head, then the same tick
                        headed, o3 = _encode(enc, part, keys, True, first, (3, 11, 50_000_000))
                        assert headed == _encode(enc, part, keys, False, first,
                                                 (3, 11, 50_000_000))[0]
                        for j in range(len(o1) - 1):
                            body = words[o1[j]:o1[j + 1]]
                            tick = part.first_tick + j
                            assert headed[o3[j]:o3[j + 1]] == MESSAGE_HEAD.pack(
                                5, 22 + len(body), 3, 11 + j, tick * 50_000_000,
                                tick * 50_000_000) + body
                # and the public encoder's bytes are protobuf's TickBatch (a spot check)
                data, offsets = enc.encode(part.first_tick, part.states, part.outputs,
                                           part.inputs, np.arange(m))
                msg = pb.TickBatch()
                msg.ParseFromString(data[offsets[0]:offsets[1]].tobytes())
                assert msg.SerializeToString() == data[offsets[0]:offsets[1]].tobytes()
                assert msg.ship_count == m


def test_put_fields_keeps_the_bytes_around_it():
    """Numbers written at each offset mod 8 leave the bytes before and after them as they were,
    on both paths (word stores, and byte stores as a big-endian machine makes them)."""
    rng = np.random.default_rng(7)
    words = rng.integers(0, 2**63, size=(5, 3), dtype=np.int64).view(np.uint64)
    # one field of two numbers a ship, from words 1 and 2 of the ships' records (kind 0)
    table = np.array([(0, 8, 2, 8, 8, 0x0A, 0, 1, False)], np.int64)
    for little in (True, False):
        for o in range(16):
            out = rng.integers(0, 256, size=112, dtype=np.uint8)
            want = out.copy()
            want[o:o + 5 * 2 * 8] = words[:, 1:3].astype("<u8").view(np.uint8).ravel()
            assert eb._put_fields(0, words.view(np.uint8), words, table, np.array([o]), 0, 5,
                                  out, out.view(np.uint64), little) == 0
            assert (out == want).all(), (little, o)
