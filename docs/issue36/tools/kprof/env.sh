# source me: numba compiles for the host CPU with every AVX-512/AMX/AVX10 feature off (valgrind
# executes none of them); the same target for every tree, so their counts compare.
: "${KPROF:=/tmp/kprof}"; : "${KPROF_PY:=/work/main/.venv/bin/python}"
export KPROF KPROF_PY PYTHONHASHSEED=0
export NUMBA_CPU_NAME="$($KPROF_PY -c 'import llvmlite.binding as b; print(b.get_host_cpu_name())')"
export NUMBA_CPU_FEATURES="$($KPROF_PY -c 'from numba.core.codegen import JITCPUCodegen
f = JITCPUCodegen("x")._tm_features.split(",")
print(",".join(("-" + x[1:]) if any(k in x for k in ("avx512", "amx", "avx10")) else x for x in f))')"
mkdir -p "$KPROF"
