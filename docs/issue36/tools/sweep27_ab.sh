#!/bin/bash
# Alternating A/B of `touchdown sweep` (the README's envelope command), base then branch, PAIRS
# times: wall and user CPU of the whole command (/usr/bin/time), the load average before each.
#   sweep27_ab.sh BASE_TREE BRANCH_TREE SAMPLES WORKERS PAIRS OUTDIR
base=$1; branch=$2; n=$3; w=$4; pairs=$5; out=$6
mkdir -p "$out"
for p in $(seq 1 "$pairs"); do
  for side in base branch; do
    tree=$base; [ "$side" = branch ] && tree=$branch
    load=$(cut -d' ' -f1 /proc/loadavg)
    /usr/bin/time -f "%e %U %S" -o "$out/time" "$tree/.venv/bin/touchdown" sweep \
      "$branch/scenarios/envelope.toml" --vary ships.initial.vertical_speed=-12:-1 \
      --vary ships.initial.horizontal_speed=0:6 --vary ships.initial.tilt_deg=0:15 \
      --samples "$n" --seed 1 --workers "$w" -o "$out/$side-$p.parquet" > "$out/$side-$p.txt"
    read wall user sys < "$out/time"
    echo "$(date -u +%H:%M:%S) pair $p $side: wall $wall s user $user s sys $sys s load $load"
  done
done
