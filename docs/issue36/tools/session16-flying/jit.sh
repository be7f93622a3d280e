#!/bin/bash
# jit.sh PKGTREE ROW [SHIPS]: JIT Ir a ship-tick (warm full run first; symbol map), PYTHONHASHSEED=0
tree=$1; row=$2; n=${3:-200}
export NUMBA_CPU_NAME=znver3 NUMBA_CPU_FEATURES="$(cat /tmp/flying-x/feat.txt)" PYTHONPATH=$tree.pkg PYTHONHASHSEED=0
PY=/work/wt-flying/.venv/bin/python
cd $tree
tag=$(basename $tree)
out=/tmp/flying-x/pj.$tag.$row.cg
valgrind --tool=callgrind --instr-atstart=no --dump-instr=yes --callgrind-out-file=$out $PY /tmp/flying-x/prof_states.py $row $n > $out.log 2>&1
pid=$(grep -o "==[0-9]*==" $out.log | head -1 | tr -d =)
python3 /tmp/flying-x/mapcg.py $out /tmp/flying-x/syms-$pid.txt > $out.txt
jit=$(awk 'NR>1 && $3 != "?" {gsub(",","",$1); s+=$1} END {print s}' $out.txt)
all=$(head -1 $out.txt | awk '{print $2}')
echo "row $row $tag ships $n: JIT Ir/ship-tick $(( jit / (n*40) )), all $(( all / (n*40) ))"
