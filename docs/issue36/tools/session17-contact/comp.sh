#!/bin/bash
# comp.sh TREEDIR TAG: compile a tree's kernels (znver3, no avx512) into /tmp/contact-x/nc-TAG
tree=$1; tag=$2
export NUMBA_CPU_NAME=znver3 NUMBA_CPU_FEATURES="$(cat /tmp/contact-x/feat.txt)" PYTHONPATH=$tree.pkg PYTHONHASHSEED=0 NUMBA_CACHE_DIR=/tmp/contact-x/nc-$tag
cd $tree && /work/main/.venv/bin/python /tmp/contact-x/prof_states.py 5 2 > /dev/null 2>&1; /work/main/.venv/bin/python /tmp/contact-x/prof_cases.py 1 > /dev/null 2>&1; echo "compiled $tag $(date +%T)"
