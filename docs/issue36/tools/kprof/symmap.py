"""The compiled kernels' symbols for callgrind: numba's object code (compiled now or loaded from
its cache) is captured as it is set, and after a warm run each object's symbols are placed at
the addresses the JIT gave them, as ``ADDR SIZE NAME`` lines (``write``); ``short`` turns a
mangled name into ``module.kernel``. ``install`` must run before the project is imported."""
from __future__ import annotations

import os
import re
import subprocess
import tempfile

SAVED: list[bytes] = []


def install() -> None:
    from numba.core import codegen as cg
    set_obj = cg.CPUCodeLibrary._set_compiled_object
    compiled = cg.CPUCodeLibrary._object_compiled_hook.__func__

    def on_set(self, value):
        SAVED.append(bytes(value))
        return set_obj(self, value)

    def on_compiled(cls, ll_module, buf):
        SAVED.append(bytes(buf))
        return compiled(cls, ll_module, buf)

    cg.CPUCodeLibrary._set_compiled_object = on_set
    cg.CPUCodeLibrary._object_compiled_hook = classmethod(on_compiled)


def write(folder: str) -> str:
    """``folder``/syms-PID.txt from every object seen so far (its objects kept in
    ``folder``/objs for objdump); returns the map's path."""
    from numba.core.registry import cpu_target
    eng = cpu_target.target_context.codegen()._engine
    objs = os.path.join(folder, "objs")
    os.makedirs(objs, exist_ok=True)
    lines = []
    for k, buf in enumerate(SAVED):
        name = os.path.join(objs, f"{os.getpid()}-{k}.o")
        with open(name, "wb") as f:
            f.write(buf)
        out = subprocess.run(["nm", "-S", "--defined-only", name], capture_output=True,
                             text=True).stdout
        syms = []
        for ln in out.splitlines():
            parts = ln.split()
            if len(parts) == 4 and parts[2] in "tTwW":
                syms.append((int(parts[0], 16), int(parts[1], 16), parts[2], parts[3]))
        base = None
        for off, _size, kind, s in syms:  # one exported symbol's JIT address places them all
            if kind in "TW" and "touchdown" in s:
                try:
                    a = eng.get_function_address(s)
                except Exception:
                    a = 0
                if a:
                    base = a - off
                    break
        if base is not None:
            lines += [f"{base + off:x} {size:x} {s}" for off, size, _kind, s in syms]
    for name, size in (("NRT_incref", 0x10), ("NRT_decref", 0x20)):  # numba's reference counts
        try:
            a = eng.get_function_address(name)
        except Exception:
            a = 0
        if a:
            lines.append(f"{a:x} {size:x} {name}")
    path = os.path.join(folder, f"syms-{os.getpid()}.txt")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    return path


def short(mangled: str) -> str:
    """``_ZN9touchdown3sim11integrators3rk4B..v..`` -> ``integrators.rk4``,
    ``_ZN9touchdown5sweep5fleet14sweep_ticks_pyB..`` -> ``sweep.fleet.sweep_ticks_py``: the
    Itanium name's length-prefixed parts, without ``cpython``, ``touchdown`` and ``sim``; a name
    of something else as it is."""
    m = re.match(r"_ZN(?:7cpython)?9touchdown(.*)", mangled)
    if not m:
        return mangled
    rest, parts = m.group(1), []
    while True:
        n = re.match(r"(\d+)", rest)
        if not n:
            break
        k, start = int(n.group(1)), len(n.group(1))
        parts.append(rest[start:start + k])
        rest = rest[start + k:]
    if parts[:1] == ["sim"]:
        parts = parts[1:]
    return ".".join(parts) or mangled


def load(path: str) -> list[tuple[int, int, str]]:
    """A map's (start, end, short name) ranges."""
    out = []
    for ln in open(path):
        a, size, name = ln.split()[:3]
        out.append((int(a, 16), int(a, 16) + int(size, 16), short(name)))
    return out


def name_at(ranges, addr: int) -> str:
    for lo, hi, n in ranges:
        if lo <= addr < hi:
            return n
    return "?"


def callgrind(on: bool) -> None:
    """Instrumentation on or off, where the process runs under callgrind (--instr-atstart=no)."""
    if "vgpreload" in os.environ.get("LD_PRELOAD", ""):
        subprocess.run(["callgrind_control", "-i", "on" if on else "off", str(os.getpid())],
                       check=True, capture_output=True)
