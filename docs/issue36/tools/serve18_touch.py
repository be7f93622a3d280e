# session 18 (serve): filling 10 MiB in new pages (an anonymous mapping of its own), in a new numpy array
# (malloc: usually pages the process had), and in the same array again; min/median/max of 30.
# usage: taskset -c 0 PY serve18_touch.py [nohuge]
import numpy as np, time, mmap, sys, os
if len(sys.argv) > 1 and sys.argv[1] == "nohuge":
    np._core.multiarray._set_madvise_hugepage(False)
n = 10 << 20
def fresh():
    m = mmap.mmap(-1, n)  # fresh anonymous pages
    a = np.frombuffer(m, np.uint8)
    t = time.thread_time_ns(); a[:] = 1; d = time.thread_time_ns() - t
    del a; m.close(); return d / 1e6
def numpy_new():
    t = time.thread_time_ns(); a = np.empty(n, np.uint8); a[:] = 1; d = time.thread_time_ns() - t
    return d / 1e6
b = np.empty(n, np.uint8); b[:] = 0
def reused():
    t = time.thread_time_ns(); b[:] = 1; d = time.thread_time_ns() - t; return d / 1e6
for f in (fresh, numpy_new, reused):
    xs = sorted(f() for _ in range(30))
    print(f"{f.__name__:10s} 10 MiB fill: min {xs[0]:.2f} med {xs[15]:.2f} max {xs[-1]:.2f} ms")
