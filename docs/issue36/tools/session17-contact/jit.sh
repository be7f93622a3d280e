#!/bin/bash
# jit.sh TREEDIR TAG ROW [N]: callgrind Ir by kernel; ROW=env: N envelope cases (Ir per case), else states row (Ir per ship-tick)
tree=$1; tag=$2; row=$3; n=${4:-200}
export NUMBA_CPU_NAME=znver3 NUMBA_CPU_FEATURES="$(cat /tmp/contact-x/feat.txt)" PYTHONPATH=$tree.pkg PYTHONHASHSEED=0 NUMBA_CACHE_DIR=/tmp/contact-x/nc-$tag
PY=/work/main/.venv/bin/python
cd $tree
out=/tmp/contact-x/pj.$tag.$row.cg
if [ $row = env ]; then script="prof_cases.py $n"; div=$n; else script="prof_states.py $row $n"; div=$((n*40)); fi
valgrind --tool=callgrind --instr-atstart=no --dump-instr=yes --callgrind-out-file=$out $PY /tmp/contact-x/$script > $out.log 2>&1
pid=$(grep -o "==[0-9]*==" $out.log | head -1 | tr -d =)
python3 /tmp/contact-x/mapcg.py $out /tmp/contact-x/syms-$pid.txt > $out.txt
cp /tmp/contact-x/syms-$pid.txt /tmp/contact-x/syms.$tag.$row.txt
jit=$(awk 'NR>1 && $3 != "?" {gsub(",","",$1); s+=$1} END {print s}' $out.txt)
all=$(head -1 $out.txt | awk '{print $2}')
echo "row $row $tag n $n: JIT Ir/unit $(( jit / div )), all $(( all / div ))"
