#!/bin/bash
# cg.sh TREE WHICH: callgrind Ir a solve of one round of the 837 four-foot problems that
# session21-stick/dump_problems.py wrote to /tmp/stick-problems.npz (WHICH: ipm, the
# interior-point method alone; solve, _solve_feet from the carried impulses). TREE: a source tree
# with TREE.pkg/touchdown -> TREE (as docs/issue36/tools/kprof/tree.sh makes them).
here=$(cd "$(dirname "$0")" && pwd); tree=$1; which=$2
source /work/main/docs/issue36/tools/kprof/env.sh >/dev/null
export NUMBA_CACHE_DIR=/tmp/nc-split-$(basename $tree)
PYTHONPATH=$tree.pkg /work/main/.venv/bin/python $here/bench_ipm.py $which 1 > /dev/null
PYTHONPATH=$tree.pkg valgrind --tool=callgrind --instr-atstart=no --callgrind-out-file=/tmp/cg-split.$(basename $tree).$which.out /work/main/.venv/bin/python $here/bench_ipm.py $which 1 2>&1 | grep Collected | awk -v w=$which '{printf "%s Ir a solve: %d\n", w, $4/837}'
