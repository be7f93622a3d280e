#!/bin/bash
# bench.sh ROUNDS TREE...: bench/states.py rows 0,3,4 (1000 ships, 40 ticks, repeat 2) per tree, alternating, znver3 target
. /tmp/flying-x/benchenv.sh
rounds=$1; shift
for r in $(seq $rounds); do for t in "$@"; do
  echo "round $r $t $(date -u +%T) load $(cut -d' ' -f1 /proc/loadavg)"
  (cd /tmp && /tmp/flying-x/$t.py /tmp/flying-x/states.py --only 0,3,4 --ships 1000 --ticks 40 --repeat 2)
done; done
