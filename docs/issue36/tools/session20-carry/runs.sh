#!/bin/bash
cd /work/wt-carry/docs/issue36/tools/kprof
export KPROF=/tmp/carry-kprof KPROF_PY=/work/wt-carry/.venv/bin/python
source ./env.sh
tag=$1
(cd /tmp && PYTHONPATH=$KPROF/$tag.pkg NUMBA_CACHE_DIR=$KPROF/nc-$tag $KPROF_PY /work/wt-carry/docs/issue36/tools/envelope_columns.py /tmp/carry-env-$tag.npz; echo "env columns $tag rc $? $(date +%T)")
for r in 5 6; do ./jit.sh $tag $r 100; done
./jit.sh $tag env 30
echo "done $tag $(date +%T)"
