"""The compiled scan of tick records (sim.compiled): every message's fields in one pass over its
bytes, at compiled speed whatever the bytes hold. :mod:`logs.decode` scans the records a writer
writes in plain Python and numpy (a Touchdown tick record has at most a few dozen fields, and a
log's records share a handful of layouts); a record of more fields than that (only a hostile or
damaged one: unknown fields are legal protobuf) is scanned here, so that no input costs more
than a pass over its bytes. Imported only then: reading a log loads no compiled code.
"""
from __future__ import annotations

import numpy as np

from touchdown.sim.compiled import separate


@separate
def _varint(data, i, end):
    """(value, next index, error): a varint of at most ten bytes starting at ``i``."""
    result = np.uint64(0)
    shift = np.uint64(0)
    for _ in range(10):
        if i >= end:
            return result, i, 1
        b = np.uint64(data[i])
        i += 1
        result |= (b & np.uint64(0x7F)) << shift
        if not (b & np.uint64(0x80)):
            return result, i, 0
        shift += np.uint64(7)
    return result, i, 2


@separate
def scan_messages(data, begins, ends, num_index, wire, header, t_at, starts, lengths):
    """Fields of every message ``data[begins[k]:ends[k]]``: ``header[k]`` = (tick, ship
    count), ``t_at[k]`` where its time's 8 bytes are (-1: absent, 0.0), ``starts[k, f]`` and
    ``lengths[k, f]`` where field f's numbers are (start -1: absent). Returns (error code, the
    message it is in); (0, -1) when all is well."""
    nf = starts.shape[1]
    for k in range(begins.shape[0]):
        i, end = begins[k], ends[k]
        header[k, 0] = 0
        header[k, 1] = 0
        t_at[k] = -1
        for f in range(nf):
            starts[k, f] = -1
            lengths[k, f] = 0
        while i < end:
            key, i, err = _varint(data, i, end)
            if err:
                return err, k
            num = key >> np.uint64(3)
            wt = key & np.uint64(7)
            f = num_index[num] if num < np.uint64(64) else -1
            if wt == 0:
                val, i, err = _varint(data, i, end)
                if err:
                    return err, k
                if num == 1:
                    header[k, 0] = np.int64(val)
                elif num == 3:
                    header[k, 1] = np.int64(val)
                elif f >= 0:
                    return 3, k
            elif wt == 1:
                if i + 8 > end:
                    return 4, k
                if num == 2:
                    t_at[k] = i
                i += 8
            elif wt == 2:
                length, i, err = _varint(data, i, end)
                if err:
                    return err, k
                if length > np.uint64(end - i):
                    return 5, k
                n = np.int64(length)
                if f >= 0:
                    if starts[k, f] >= 0:
                        return 8, k
                    if wire[f] == 1:
                        for j in range(i, i + n):
                            if data[j] > 127:
                                return 6, k
                    elif n % 8:
                        return 7, k
                    starts[k, f] = i
                    lengths[k, f] = n
                i += n
            elif wt == 5:
                i += 4
            else:
                return 9, k
        if i != end:
            return 10, k
    return 0, -1


__all__ = ["scan_messages"]
