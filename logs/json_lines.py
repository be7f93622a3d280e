"""The compiled pass that interleaves a block's formatted columns into JSON Lines
(logs.export.write_jsonl_blocks): each row's keys, its columns' texts (Arrow's shortest
round-trip text of doubles, ``.0`` added where Python's JSON writes it) and ``null`` for a number
the log does not hold. Compiled (sim.compiled): imported by the JSON Lines export alone.
"""
from __future__ import annotations

from touchdown.sim.compiled import separate


def json_lines(offsets, data, bases, kinds, missing, key_bytes, key_off, out) -> int:
    if out is None:
        return int(_json_size(offsets, data, bases, kinds, missing, key_off))
    _json_fill(offsets, data, bases, kinds, missing, key_bytes, key_off, out)
    return out.shape[0]


@separate
def _needs_point(data, a, b):
    """A double's text with neither a point nor an exponent (Arrow writes 3 for 3.0): Python's
    JSON writes 3.0."""
    for i in range(a, b):
        c = data[i]
        if c == 46 or c == 101 or c == 69 or c == 110:  # . e E n
            return False
    return True


@separate
def _json_size(offsets, data, bases, kinds, missing, key_off):
    total = 0
    nc, R = offsets.shape[0], offsets.shape[1] - 1
    for r in range(R):
        for k in range(nc):
            total += key_off[k + 1] - key_off[k]
            if missing[k, r]:
                total += 4
                continue
            a, b = bases[k] + offsets[k, r], bases[k] + offsets[k, r + 1]
            total += b - a
            if kinds[k] == 1 and _needs_point(data, a, b):
                total += 2
        total += 2
    return total


@separate
def _json_fill(offsets, data, bases, kinds, missing, key_bytes, key_off, out):
    o = 0
    nc, R = offsets.shape[0], offsets.shape[1] - 1
    for r in range(R):
        for k in range(nc):
            n = key_off[k + 1] - key_off[k]
            out[o:o + n] = key_bytes[key_off[k]:key_off[k + 1]]
            o += n
            if missing[k, r]:
                out[o], out[o + 1], out[o + 2], out[o + 3] = 110, 117, 108, 108  # null
                o += 4
                continue
            a, b = bases[k] + offsets[k, r], bases[k] + offsets[k, r + 1]
            out[o:o + b - a] = data[a:b]
            o += b - a
            if kinds[k] == 1 and _needs_point(data, a, b):
                out[o], out[o + 1] = 46, 48  # .0
                o += 2
        out[o], out[o + 1] = 125, 10  # }\n
        o += 2


__all__ = ["json_lines"]
