"""A shard's telemetry sample (``Telemetry`` in proto/service.proto) as bytes, made from the
step's own outputs without building a protobuf message per ship.

A sample is a rolling slice of the fleet: the ships at rows ``offset, offset + every, ...`` of the
block's last tick. The protobuf wire format of a message is its fields in number order, so the
sample is put together from pieces: the three scalars (tick, t_s, shard) by the protobuf library,
then the ship ids (each a length-prefixed string, encoded once per fleet and kept), then the
packed numbers, which are the arrays' own little-endian bytes behind a tag and a length. The
bytes are exactly what ``Telemetry(...).SerializeToString()`` gives (``test_serve``: a test
compares them), at a tenth of its cost for a large shard.
"""
from __future__ import annotations

import numpy as np

from touchdown.logs.codec import varint
from touchdown.proto import service_pb2 as spb


def _field(number: int, payload: bytes) -> bytes:
    """A length-delimited field (packed numbers, a string): tag, length, bytes."""
    return varint(number << 3 | 2) + varint(len(payload)) + payload


class TelemetryEncoder:
    """Encodes one shard's samples; keeps the encoded ship ids of the fleet it last saw (the
    same tuple while the fleet is the same)."""

    def __init__(self) -> None:
        self._ids: tuple = ()
        self._encoded: list[bytes] = []
        self._slices: dict[tuple[int, int], bytes] = {}

    def _id_bytes(self, ids: tuple, offset: int, every: int) -> bytes:
        if ids is not self._ids:
            self._ids = ids
            self._encoded = [_field(4, sid.encode()) for sid in ids]
            self._slices = {}
        got = self._slices.get((offset, every))
        if got is None:
            got = self._slices[(offset, every)] = b"".join(self._encoded[offset::every])
        return got

    def encode(self, states: np.ndarray, outputs: np.ndarray, ids: tuple, tick: int,
               dt_s: float, shard: int, offset: int, every: int) -> bytes:
        """The sample of the ships at rows ``offset::every`` of one tick's ``states`` and
        ``outputs`` (STATE_DTYPE, OUTPUTS_DTYPE rows of the fleet ``ids``)."""
        head = spb.Telemetry(tick=tick, t_s=tick * dt_s, shard=shard).SerializeToString()
        st = states[offset::every]
        if not len(st):
            return head
        outs = outputs[offset::every]
        surface = st["surface_state"].astype(np.int64)
        if surface.min() < 0 or surface.max() > 127:  # not one byte each as varints: the slow way
            return _message(states, outputs, ids, tick, dt_s, shard, offset, every)
        parts = [head, self._id_bytes(ids, offset, every),
                 _field(5, surface.astype(np.uint8).tobytes())]
        for number, arr in ((6, st["pos_m"]), (7, st["vel_mps"]), (8, outs["altitude_m"]),
                            (9, outs["cos_tilt"]), (10, st["fuel_kg"])):
            parts.append(_field(number, np.ascontiguousarray(arr, dtype="<f8").tobytes()))
        return b"".join(parts)


def _message(states, outputs, ids, tick, dt_s, shard, offset, every) -> bytes:
    """The same sample through the protobuf library (what ``encode`` must equal)."""
    rows = np.arange(offset, len(ids), every)
    return telemetry_message(states, outputs, ids, rows, tick, dt_s, shard).SerializeToString()


def telemetry_message(states, outputs, ids, rows, tick, dt_s, shard) -> spb.Telemetry:
    """A sample of the ships at ``rows`` as a protobuf message, field by field."""
    st, outs = states[rows], outputs[rows]
    msg = spb.Telemetry(tick=tick, t_s=tick * dt_s, shard=shard,
                        ship_ids=[ids[i] for i in rows])
    if not len(rows):
        return msg
    msg.state.extend(st["surface_state"].astype(np.int32).tolist())
    msg.pos_m.extend(st["pos_m"].ravel().tolist())
    msg.vel_mps.extend(st["vel_mps"].ravel().tolist())
    msg.altitude_m.extend(outs["altitude_m"].tolist())
    msg.cos_tilt.extend(outs["cos_tilt"].tolist())
    msg.fuel_kg.extend(st["fuel_kg"].tolist())
    return msg
