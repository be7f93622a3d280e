#!/bin/bash
# jit.sh TAG ROW [N]: callgrind Ir of the compiled kernels, by kernel; ROW=env: N envelope
# touchdowns (Ir a touchdown), else bench/states.py's row ROW, N ships, 40 ticks (Ir a ship-tick)
set -eu
here=$(cd "$(dirname "$0")" && pwd); tag=$1; row=$2; n=${3:-200}
export PYTHONPATH=$KPROF/$tag.pkg NUMBA_CACHE_DIR=$KPROF/nc-$tag
cd "$KPROF/$tag"
out=$KPROF/pj.$tag${KPROF_SIM:+.$KPROF_SIM}.$row.cg
if [ "$row" = env ]; then div=$n; elif [ "$row" = quiet ]; then
    div=$((n * $(python3 -c "import json,os; p=os.environ.get('QUIET_PATHS','all'); print(sum(1 for x in json.load(open(os.environ['QUIET_LIST'])) if p == 'all' or x[2] in p.split(',')))")))
    out=$KPROF/pj.$tag.$row-${QUIET_PATHS:-all}.cg; else div=$((n * 40)); fi
KPROF_OUT=$KPROF valgrind --tool=callgrind --instr-atstart=no --dump-instr=yes \
    --callgrind-out-file="$out" "$KPROF_PY" "$here/workload.py" "$row" "$n" > "$out.log" 2>&1
pid=$(grep -o "==[0-9]*==" "$out.log" | head -1 | tr -d =)
cp "$KPROF/syms-$pid.txt" "$KPROF/syms.$tag.$row.txt"
"$KPROF_PY" "$here/mapcg.py" "$out" "$KPROF/syms.$tag.$row.txt" > "$out.txt"
jit=$(awk 'NR>1 && $3 != "?" {gsub(",","",$1); s+=$1} END {print s}' "$out.txt")
all=$(head -1 "$out.txt" | awk '{print $2}')
echo "row $row $tag n $n: JIT Ir/unit $(( jit / div )), all $(( all / div ))"
