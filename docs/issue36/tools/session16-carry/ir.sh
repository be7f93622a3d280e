#!/bin/sh
# ir.sh PY TAG ROW N : callgrind Ir of states row ROW with N ships (ROW=env: ir_cases N)
. /tmp/carry-x/env.sh
export NUMBA_CACHE_DIR=/tmp/carry-x/nc-$2
PY=/work/wt-carry/.venv/bin/python; TAG=$2; ROW=$3; N=$4
[ "$1" = START ] && export PYTHONPATH=/tmp/carry-x/START.pkg
mkdir -p /tmp/carry-x/out
if [ "$ROW" = env ]; then
  $PY /work/wt-carry/docs/issue36/tools/ir_cases.py 1 >/dev/null 2>&1
  valgrind --tool=callgrind --instr-atstart=no --callgrind-out-file=/tmp/carry-x/out/cg-$TAG-env-$N $PY /work/wt-carry/docs/issue36/tools/ir_cases.py $N /tmp/carry-x/out/cols-$TAG-$N.npz 2>&1 | grep Collected
else
  $PY /tmp/carry-x/ir_states.py $ROW 1 2>/dev/null
  valgrind --tool=callgrind --instr-atstart=no --callgrind-out-file=/tmp/carry-x/out/cg-$TAG-$ROW-$N $PY /tmp/carry-x/ir_states.py $ROW $N 2>&1 | grep Collected
fi
