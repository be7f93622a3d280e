#!/bin/bash
# abba.sh ROUNDS ONLY A B: bench/states.py --only ONLY, order A B B A each round (CPU time, us)
rounds=$1; only=$2; A=$3; B=$4
run() { v=$(cd /tmp && $1 /work/wt-contact/bench/states.py --only $only --ships 1000 --ticks 40 --cases 300 --repeat 2 | grep -o "[0-9.]* us" | tr -d 'us' | tr '\n' ' '); echo "$r $(basename $1) $v"; }
for r in $(seq $rounds); do run $A; run $B; run $B; run $A; done
