#!/bin/bash
# cols.sh TREEDIR TAG: the 300 envelope touchdowns' outcome columns (ir_cases.py) with TAG's znver3 cache
tree=$1; tag=$2
export NUMBA_CPU_NAME=znver3 NUMBA_CPU_FEATURES="$(cat /tmp/contact-x/feat.txt)" PYTHONPATH=$tree.pkg PYTHONHASHSEED=0 NUMBA_CACHE_DIR=/tmp/contact-x/nc-$tag
cd $tree && /work/main/.venv/bin/python /work/main/docs/issue36/tools/ir_cases.py 300 /tmp/contact-x/cols-$tag.npz
