#!/bin/bash
# comp.sh TAG: TAG's kernels compiled for valgrind's CPU (env.sh) into $KPROF/nc-TAG
set -eu
here=$(cd "$(dirname "$0")" && pwd); tag=$1
export PYTHONPATH=$KPROF/$tag.pkg NUMBA_CACHE_DIR=$KPROF/nc-$tag
cd "$KPROF/$tag"
"$KPROF_PY" "$here/workload.py" 5 2 >/dev/null 2>&1
"$KPROF_PY" "$here/workload.py" env 1 >/dev/null 2>&1
echo "compiled $tag $(date +%T)"
