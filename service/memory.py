"""The worker's freed memory kept for its next tick, not given back to the system.

Each tick of a shard makes its block's arrays afresh (sim.world: its states, telemetry and
inputs: 14.6 MB a tick for a 30,000-ship shard), held until the flight log's writer has them
encoded. glibc's malloc gives the top of its heap back to the system whenever more than its trim
threshold (by default twice the largest block it has freed, ~20 MB here) lies free there: as the
writers' queues drain, tens of megabytes go back, and the next ticks take them again as new
pages, each a page fault that zeroes it (on a virtual machine also the host's own fault). On
bench serve's 2-core KVM guest a 10 MiB array filled in new pages took ~11 ms against ~0.2 ms in
pages already the process's (docs/issue36/session18-serve.txt): a step of ~20 ms became 100-145 ms
at ~120,000 ships. With a trim threshold of 1 GiB the heap keeps what it has freed (the process's
resident memory stays at its high mark, which the fleet sets), and blocks up to 32 MiB (glibc's
largest mmap threshold) come from the heap rather than from a mapping of their own, unmapped
when freed. Nothing here changes what is computed.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import sys

#: glibc's mallopt parameters (malloc.h)
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
#: freed memory at the top of a heap that stays the process's
TRIM_THRESHOLD_BYTES = 1 << 30
#: blocks under this come from the heap (glibc takes at most 32 MiB on 64-bit systems)
MMAP_THRESHOLD_BYTES = 32 << 20


def keep_freed_memory() -> bool:
    """Tell glibc's malloc to keep freed memory (see the module's note); True if it did.
    Nothing elsewhere (another C library, another system)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    return bool(mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES)
                and mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES))
