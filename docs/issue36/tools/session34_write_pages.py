"""CPU of writing N MB to a new file, left to the kernel or dropped from the page cache
(session 34; docs/issue36/session29-lead.txt). On a Firecracker guest a page of memory never
used before costs its first touch: run `nodrop` twice with the file deleted between, and after
a run of `sync`, to see the pages' reuse.

    python session34_write_pages.py nodrop|drop|sync MB [STEP_MB]

nodrop: plain writes; drop: posix_fadvise(DONTNEED) a step behind, without a sync (the version
not kept: most pages stayed cached, dirty); sync: logs.page_cache.DropWritten as shipped
(fdatasync, then DONTNEED, every STEP_MB, default 8).
"""
import os
import sys
import time

from touchdown.logs.page_cache import DropWritten

buf = os.urandom(1 << 20)


def busy():
    v = [int(x) for x in open('/proc/stat').readline().split()[1:]]
    return (sum(v) - v[3] - v[4]) / os.sysconf('SC_CLK_TCK')


class AdviseOnly:
    """DONTNEED a step behind the writes, no sync (measured, not kept)."""

    def __init__(self, step):
        self.step, self.kicked, self.dropped = step, 0, 0

    def written(self, f):
        pos = f.tell()
        if pos - self.kicked < self.step:
            return
        f.flush()
        if self.kicked > self.dropped:
            os.posix_fadvise(f.fileno(), self.dropped, self.kicked - self.dropped,
                             os.POSIX_FADV_DONTNEED)
            self.dropped = self.kicked
        os.posix_fadvise(f.fileno(), self.kicked, pos - self.kicked, os.POSIX_FADV_DONTNEED)
        self.kicked = pos


def run(path, mb, mode, step):
    d = {"sync": lambda: DropWritten(step), "drop": lambda: AdviseOnly(step),
         "nodrop": lambda: None}[mode]()
    b0 = busy()
    t0 = time.process_time()
    w0 = time.perf_counter()
    with open(path, 'wb') as f:
        for _ in range(mb):
            f.write(buf)
            if d is not None:
                d.written(f)
    t = time.process_time() - t0
    w = time.perf_counter() - w0
    time.sleep(3)
    return f"process CPU {t:.2f} s, wall {w:.2f} s; system busy (3 s after included) {busy() - b0:.2f} s"


if __name__ == "__main__":
    mode, mb = sys.argv[1], int(sys.argv[2])
    step = (int(sys.argv[3]) if len(sys.argv) > 3 else 8) << 20
    print(mode, mb, "MB:", run(f"{mode}.bin", mb, mode, step))
