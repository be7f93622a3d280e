"""The one way ``sim`` compiles its physics: numba, per ship, deterministic, cached on disk.

Every kernel is ``numba.njit`` with

* ``fastmath=False``: no reassociation, no fused multiply-add, no approximate reciprocals. IEEE
  +, -, *, / and sqrt are correctly rounded on every CPU, so a ship's numbers are the same bits
  whether the kernels were compiled for this host or for a generic x86-64 (``NUMBA_CPU_NAME=
  generic``; a test checks it). With fastmath on, 83% of positions differed (issue 9).
* ``error_model="numpy"``: a division by zero gives inf or nan as numpy does, never an exception
  raised from inside a kernel.
* ``nogil=True``: the log writer's thread runs while the ships are stepped.
* ``cache=True`` for the entry points (the functions Python calls): compiled code is kept on
  disk, so only the first run after an install compiles.

The inner kernels (every function only kernels call) are typed and lowered to LLVM IR, each
function optimized on its own, but they are neither optimized as a module nor turned into machine
code: an entry point links in the IR of everything it calls and LLVM optimizes and emits the
whole once (:class:`_LinkOnlyLibrary`). numba by default finalizes every function's library
(whole-module passes and machine code), then does it again in every caller that links it in; for
the step's ~180 kernels that was a third of a first compile (45 s to 31 s for the first
``touchdown record bounce``; the same machine code, the same bits). Inner kernels are not cached
on disk: nothing loads them but a compile of an entry point, which is cached whole.

numba's cache checks only the source file of the function it compiled, not the files of the
functions it calls (which it inlines); a change to ``sim/vec.py`` would leave ``sim/flight.py``'s
cached code stale. The cache directory is therefore named after a hash of every source file of
``sim/`` (and numba's version): any change to the physics compiles afresh.
"""
from __future__ import annotations

import hashlib
import os
import sys
import types
from pathlib import Path
from typing import Callable

import numba
from numba.core import cgutils, compiler, event
from numba.core import types as nb_types
from numba.extending import intrinsic
from numba.core.codegen import JITCodeLibrary
from numba.core.compiler_lock import require_global_compiler_lock
from numba.core.registry import CPUDispatcher
from numba.np.arrayobj import _empty_nd_impl, populate_array
from llvmlite import ir

_SIM_DIR = Path(__file__).resolve().parent


def _sources_hash() -> str:
    digest = hashlib.sha256(numba.__version__.encode())
    for path in sorted(_SIM_DIR.glob("*.py")):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _writable(path: Path) -> bool:
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / ".probe"
        probe.write_bytes(b"")
        probe.unlink()
        return True
    except OSError:
        return False


def cache_dir() -> Path:
    """Where compiled kernels are kept: ``$NUMBA_CACHE_DIR/touchdown-<hash>`` if that is set, else
    beside the sources (``sim/__pycache__``), else ``$XDG_CACHE_HOME/touchdown`` (``~/.cache``)."""
    name = f"kernels-{_sources_hash()}"
    user = os.environ.get("NUMBA_CACHE_DIR")
    candidates = [Path(user) / f"touchdown-{name}"] if user else []
    candidates.append(_SIM_DIR / "__pycache__" / name)
    xdg = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    candidates.append(Path(xdg) / "touchdown" / name)
    for path in candidates:
        if _writable(path):
            _prune_siblings(path)
            return path
    return candidates[-1]  # numba then compiles without caching, and says so


def _prune_siblings(path: Path) -> None:
    """Remove the kernels compiled from other versions of the sources beside ``path`` (best
    effort: another process may be using them, or the directory may not be ours to clean)."""
    import shutil
    prefix = path.name.split("-")[0] + "-"
    for other in path.parent.glob(prefix + "*"):
        if other != path and other.is_dir() and len(other.name) == len(path.name):
            shutil.rmtree(other, ignore_errors=True)


numba.config.CACHE_DIR = str(cache_dir())


#: every kernel's options (module docstring)
OPTIONS = dict(nopython=True, nogil=True, fastmath=False, error_model="numpy",
               no_cfunc_wrapper=True)


class _Inner(CPUDispatcher):
    """A kernel compiled without the CPython wrapper numba gives every function by default: the
    kernels call each other's native code, and a wrapper (about a fifth of a first compile,
    measured: 157 of them) is only for calls from Python. Such a call (a test calling a phase, a
    tool calling a helper) runs a twin compiled with the wrapper, once, cached apart (its name
    ends in ``_py``); called as it is, numba would jump to a null entry point."""

    def twin(self) -> CPUDispatcher:
        """The twin that calls from Python run: made on first use, compiled on its first call."""
        twin = self.__dict__.get("_twin")
        if twin is None:
            fn = self.py_func
            clone = types.FunctionType(fn.__code__, fn.__globals__, fn.__name__, fn.__defaults__,
                                       fn.__closure__)
            clone.__qualname__, clone.__module__ = fn.__qualname__ + "_py", fn.__module__
            clone.__doc__ = fn.__doc__
            opts = {k: v for k, v in self.targetoptions.items() if k != "no_cpython_wrapper"}
            twin = self.__dict__["_twin"] = _dispatcher(clone, CPUDispatcher, **opts)
        return twin

    def __call__(self, *args, **kws):
        twin = self.__dict__.get("_twin")
        return (self.twin() if twin is None else twin)(*args, **kws)


class _LinkOnlyLibrary(JITCodeLibrary):
    """An inner kernel's code: its functions, each optimized on its own, and its callees linked in,
    but no whole-module optimization and no machine code. Nothing calls an inner kernel except
    through an entry point, whose library links this one in and optimizes the whole once."""

    def finalize(self):
        require_global_compiler_lock()
        self._raise_if_finalized()
        seen = set()
        for library in self._linking_libraries:
            if library not in seen:
                seen.add(library)
                self._reload_init.update(library._reload_init)
                self._final_module.link_in(library._get_module_for_linking(), preserve=True)
        self._finalized = True

    def get_pointer_to_function(self, name):
        self._ensure_finalized()
        return 0

    def _optimize_functions(self, ll_module):
        """Each function's own passes at -O1 (numba: -O3), a pass manager per module (numba: per
        function): they only tidy the IR before the entry point optimizes the whole at -O3 (the
        same machine code; a fifth of LLVM's share of a first compile, measured)."""
        ll_module.data_layout = self._codegen._data_layout
        fpm, pb = self._codegen._function_pass_manager(opt=1)
        for func in ll_module.functions:
            fpm.run(func, pb)

    @property
    def codegen(self):
        return _NoEnvCodegen(self._codegen)


class _NoEnvCodegen:
    """The codegen of a :class:`_LinkOnlyLibrary`: its environment pointer has no address in the
    engine (the library is never added to it), so there is nothing to set."""

    def __init__(self, codegen):
        self._codegen = codegen

    def set_env(self, env_name, env):
        pass

    def __getattr__(self, name):
        return getattr(self._codegen, name)


class _InnerCompiler(compiler.Compiler):
    def __init__(self, typingctx, targetctx, library, *args, **kws):
        if library is None:
            library = _LinkOnlyLibrary(targetctx.codegen(), "inner")
        super().__init__(typingctx, targetctx, library, *args, **kws)


def _dispatcher(fn: Callable, cls: type, **options) -> Callable:
    if cls is _Inner:
        return cls(py_func=fn, locals={}, targetoptions=options, pipeline_class=_InnerCompiler)
    disp = cls(py_func=fn, locals={}, targetoptions=options)
    disp.enable_caching()
    return disp


def in_cache(fn: Callable) -> bool:
    """Whether kernel ``fn`` (an entry point, or a kernel called from Python: its twin) has code
    in the on-disk cache for its source as it is now, so that its first call loads it rather
    than compiles it (numba's index of the function's cached overloads; False where there is
    none, or where numba's cache does not say)."""
    disp = fn.twin() if isinstance(fn, _Inner) else fn
    try:
        return bool(disp._cache._cache_file._load_index())
    except (AttributeError, OSError):
        return False


def kernel(fn: Callable) -> Callable:
    """Compile ``fn`` as a deterministic, cached, GIL-free numba function (module docstring),
    whose machine code LLVM inlines into every caller (numba's ``forceinline``): a vector
    operation or a phase costs its arithmetic, not a call that passes its tuples through memory
    (2 to 4 times faster than calls, measured). Numba still types it once. For kernels: called
    from Python it compiles a twin (:class:`_Inner`)."""
    return _dispatcher(fn, _Inner, **OPTIONS, no_cpython_wrapper=True, forceinline=True)


def separate(fn: Callable) -> Callable:
    """:func:`kernel` compiled as a function of its own and called, not inlined: the large
    functions called from several places (a contact evaluation, the friction solve, a method's
    sub-step), which inlined everywhere would multiply the code LLVM optimizes (a first compile
    of two minutes instead of one) for little speed. ``forceinline`` is set to False explicitly:
    numba lets a function that does not set it inherit its caller's."""
    return _dispatcher(fn, _Inner, **OPTIONS, no_cpython_wrapper=True, forceinline=False)


def entry(fn: Callable) -> Callable:
    """:func:`separate` for a function Python calls (an entry point: the loop over ticks, the
    telemetry of a state, the placing of starts): compiled with numba's CPython wrapper."""
    return _dispatcher(fn, CPUDispatcher, **OPTIONS, forceinline=False)


def constructor(fn: Callable) -> Callable:
    """:func:`kernel` for a function that builds a tuple holding a record (``Ground``,
    ``FreeBody``), or a phase called once whose own compiled library would only repeat its
    caller's work (sim.phases.step_ship): its code is inlined where it is called, before typing
    (numba's ``inline="always"``; numba cannot return a tuple holding a record from a call)."""
    return _dispatcher(fn, _Inner, **OPTIONS, no_cpython_wrapper=True, inline="always")


# -- what numba emits for nothing ----------------------------------------------------------------
# numba lowers every variable as if it might hold reference-counted memory (an array, a list): it
# walks a tuple's fields to find what to incref and decref, loads a variable's old value before
# each store and zeroes it when it dies. The step's tuples hold none (floats, ints, bools, records,
# which are views): for them the walk emitted an extractvalue per field per use, which LLVM then
# deleted, 40% of the IR of a first compile. And it types every scalar `a * b` against numpy's
# array operators, searching numpy's ufunc loops (10,000 searches) before it checks for an array.
# The three short-cuts below skip that work only where its result is known to be nothing; a type
# holding managed memory goes the usual way (tests/test_determinism.py checks nothing leaks).
# Same machine code, same bits; the first `touchdown record bounce` 0.8x the CPU (MODEL-NOTES 34).
# They replace numba 0.68's own methods (NRTContext.get_meminfos, Lower.delvar, the array
# operators' typing), which is why pyproject pins numba to 0.68.x.
_HOLDS_MEMINFO: dict = {}


def _holds_meminfo(context, fe_type) -> bool:
    """Whether a value of ``fe_type`` holds reference-counted memory anywhere inside it (numba's
    contains_nrt_meminfo walks the type itself and everything inside it)."""
    held = _HOLDS_MEMINFO.get(fe_type)
    if held is None:
        held = _HOLDS_MEMINFO[fe_type] = context.data_model_manager[fe_type].contains_nrt_meminfo()
    return held


def _emit_less() -> None:
    from numba.core.lowering import Lower
    from numba.core.runtime.context import NRTContext
    from numba.core.typing.npydecl import NumpyRulesArrayOperator

    get_meminfos = NRTContext.get_meminfos

    def meminfos(self, builder, ty, val):
        return get_meminfos(self, builder, ty, val) if _holds_meminfo(self._context, ty) else []

    delvar = Lower.delvar

    def lower_del(self, name):
        fe_type = self.typeof(name)
        if _holds_meminfo(self.context, fe_type) or self._disable_sroa_like_opt:
            return delvar(self, name)
        # numba's own bookkeeping, less the load, the decref and the zero-fill
        if name not in self._blk_local_varmap:
            self._singly_assigned_vars.discard(name)
        self._alloca_var(name, fe_type)

    array_operator = NumpyRulesArrayOperator.generic

    def array_operator_if_array(self, args, kws):
        if not any(isinstance(a, (nb_types.ArrayCompatible, nb_types.Optional)) for a in args):
            return None  # numba's own answer for operands none of which is an array
        return array_operator(self, args, kws)

    NRTContext.get_meminfos = meminfos
    Lower.delvar = lower_del
    NumpyRulesArrayOperator.generic = array_operator_if_array


_emit_less()


@intrinsic
def zeros(typingctx, shape, dtype):
    """``np.zeros(shape, dtype)`` for a kernel's scratch arrays (``shape`` an int or a tuple of
    ints, ``dtype`` a numpy scalar type, e.g. ``np.float64``): the array is allocated and zeroed
    where it is used. numba's np.zeros is a function of its own, compiled once per shape and dtype
    (with numba's checks of the arguments): 0.1 s of a first compile each, for 4-element arrays."""
    if isinstance(shape, nb_types.Integer):
        ndim = 1
    elif isinstance(shape, nb_types.UniTuple) and isinstance(shape.dtype, nb_types.Integer):
        ndim = len(shape)
    else:
        return None
    if not isinstance(dtype, nb_types.NumberClass):
        return None
    array_t = nb_types.Array(dtype.dtype, ndim, "C")

    def codegen(context, builder, sig, args):
        dims = [args[0]] if isinstance(shape, nb_types.Integer) else \
            cgutils.unpack_tuple(builder, args[0], ndim)
        intp = context.get_value_type(nb_types.intp)
        dims = [builder.sext(d, intp) if d.type.width < intp.width else d for d in dims]
        ary = _empty_nd_impl(context, builder, array_t, dims)
        cgutils.memset(builder, ary.data, builder.mul(ary.itemsize, ary.nitems), 0)
        return ary._getvalue()

    return array_t(shape, dtype), codegen


@intrinsic(prefer_literal=True)
def stack_zeros(typingctx, shape, dtype):
    """:func:`zeros` on the stack of the function that calls it (``shape`` literal ints): an
    array with no meminfo, in an alloca of the function's entry block (LLVM moves it into the
    caller's where it inlines the function), zeroed where it is used. No malloc, no free, and
    its views' reference counts are the NRT's null check (the friction solve's scratch: 2.3
    mallocs and frees a contact sub-step, and ~30 views' increfs and decrefs each, 3.9% of a
    touchdown's instructions: MODEL-NOTES 49). It must not outlive its function: only for
    scratch that no result holds."""
    if isinstance(shape, nb_types.IntegerLiteral):
        dims = (shape.literal_value,)
    elif isinstance(shape, nb_types.BaseTuple) and all(
            isinstance(d, nb_types.IntegerLiteral) for d in shape.types):
        dims = tuple(d.literal_value for d in shape.types)
    else:
        return None
    if not isinstance(dtype, nb_types.NumberClass):
        return None
    ndim = len(dims)
    array_t = nb_types.Array(dtype.dtype, ndim, "C")
    count = 1
    for d in dims:
        count *= d

    def codegen(context, builder, sig, args):
        ary = context.make_array(array_t)(context, builder)
        item_t = context.get_data_type(array_t.dtype)
        itemsize = context.get_abi_sizeof(item_t)
        with builder.goto_entry_block():
            data = builder.alloca(item_t, size=ir_const(context, count))
        intp = context.get_value_type(nb_types.intp)
        strides = []
        stride = itemsize
        for d in reversed(dims):
            strides.append(stride)
            stride *= d
        strides.reverse()
        populate_array(ary, data=data,
                       shape=[ir.Constant(intp, d) for d in dims],
                       strides=[ir.Constant(intp, s) for s in strides],
                       itemsize=ir.Constant(intp, itemsize), meminfo=None)
        cgutils.memset(builder, ary.data, ir.Constant(intp, itemsize * count), 0)
        return ary._getvalue()

    return array_t(shape, dtype), codegen


@intrinsic
def borrowed(typingctx, arr):
    """``arr`` itself (its data, shape and strides) without its meminfo: an array whose reference
    counts are the NRT's null check, not an atomic add. numba counts references to every array
    a function is given, at each call of it, forceinline or not (the counts are emitted before
    LLVM inlines), and to an array a variable holds in a branch or a loop: the step's event log
    (sim.ship.EventLog), handed down through the flight's phases each piece and sub-step, paid
    ~5,700 of the envelope touchdown's ~6,600 counts (4% of the kernels' time; 0.7% with it
    borrowed: docs/issue36/session25-nrt.txt). Same code otherwise, same bits. Only for an array
    that outlives every use of what is made from it: one a caller holds for the whole of a call
    (an entry point's argument)."""
    if not isinstance(arr, nb_types.Array):
        return None

    def codegen(context, builder, sig, args):
        ary = context.make_array(arr)(context, builder, args[0])
        ary.meminfo = cgutils.get_null_value(ary.meminfo.type)
        return ary._getvalue()

    return arr(arr), codegen


def ir_const(context, n):
    """An LLVM intp constant."""
    return ir.Constant(context.get_value_type(nb_types.intp), n)


class _CompileNotice(event.Listener):
    def __init__(self, say: Callable[[str], None]):
        self.say = say
        self.said = False

    def on_start(self, ev: event.Event) -> None:
        if not self.said:
            self.said = True
            self.say("compiling the physics kernels for this CPU (once after an install or a "
                     "change to sim/, unless `touchdown warm` did it; half a minute or more) ...")

    def on_end(self, ev: event.Event) -> None:
        pass


_NOTICE: _CompileNotice | None = None


def notify_compilation(say: Callable[[str], None] | None = None) -> None:
    """Call ``say`` once, when a kernel starts compiling rather than loading from the cache
    (default: a line on stderr, if stderr is a terminal). For the command line; the core itself
    prints nothing. Calling it again replaces ``say`` (and says it again at the next compile)."""
    global _NOTICE
    if say is None:
        def say(text: str) -> None:
            if sys.stderr.isatty():
                print(f"touchdown: {text}", file=sys.stderr, flush=True)
    if _NOTICE is None:
        _NOTICE = _CompileNotice(say)
        event.register("numba:compile", _NOTICE)
    else:
        _NOTICE.say, _NOTICE.said = say, False
