#!/bin/bash
# alt9.sh ROUNDS ONLY PY... : bench/states.py --only ONLY per interpreter, alternating; the rows' us on one line per run
rounds=$1; only=$2; shift 2
for r in $(seq $rounds); do for py in "$@"; do
  v=$(cd /tmp && $py /work/wt-contact/bench/states.py --only $only --ships 1000 --ticks 40 --cases 300 --repeat 2 | grep -o "[0-9.]* us" | tr -d 'us' | tr '\n' ' ')
  echo "$r $(basename $py) $v"
done; done
