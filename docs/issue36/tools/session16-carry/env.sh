export NUMBA_CPU_NAME=znver3
export NUMBA_CPU_FEATURES="$(/work/wt-carry/.venv/bin/python -c 'from numba.core.codegen import JITCPUCodegen; f=JITCPUCodegen("x")._tm_features; print(",".join(("-"+x[1:]) if ("avx512" in x or "amx" in x) else x for x in f.split(",")))')"
