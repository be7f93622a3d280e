#!/bin/bash
tree=$1; n=${2:-60}
export NUMBA_CPU_NAME=znver3 NUMBA_CPU_FEATURES="$(cat /tmp/bounce/feat.txt)" PYTHONPATH=$tree.pkg PYTHONHASHSEED=0
PY=/work/wt-bounce/.venv/bin/python
cd $tree; tag=$(basename $tree)
out=/tmp/bounce/pc.$tag.cg
valgrind --tool=callgrind --instr-atstart=no --callgrind-out-file=$out $PY /tmp/bounce/prof_cases.py $n > $out.log 2>&1
pid=$(grep -o "==[0-9]*==" $out.log | head -1 | tr -d =)
python3 /tmp/bounce/mapcg.py $out /tmp/bounce/syms-$pid.txt > $out.txt
jit=$(awk 'NR>1 && $3 != "?" {gsub(",","",$1); s+=$1} END {print s}' $out.txt)
echo "$tag $n cases: JIT Ir $jit, all $(head -1 $out.txt | awk '{print $2}')"
