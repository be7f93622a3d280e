#!/bin/bash
tree=$1
export NUMBA_CPU_NAME=znver3 NUMBA_CPU_FEATURES="$(cat /tmp/flying-x/feat.txt)" PYTHONPATH=$tree.pkg PYTHONHASHSEED=0
cd $tree && /work/wt-flying/.venv/bin/python /tmp/flying-x/ir_states.py 3 2 2 > /dev/null 2>&1; echo "compiled $tree $(date +%T)"
