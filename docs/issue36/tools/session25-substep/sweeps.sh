#!/bin/bash
cd /work/wt-substep
SW=".venv/bin/touchdown sweep scenarios/envelope.toml --vary ships.initial.vertical_speed=-12:-1 --vary ships.initial.horizontal_speed=0:6 --vary ships.initial.tilt_deg=0:15 --samples 10000 --seed 1 --workers 2"
for rep in 1 2; do
for v in 0.005 0.00625 0.005 0.00833334 0.005 0.0125 0.005 0.025; do
  /usr/bin/time -o /tmp/substep/t.txt -f "%e %U %S" $SW --set sim.impact_substep=$v -o /tmp/substep/sub-$v.parquet > /tmp/substep/sw.log 2>&1
  echo "$rep $v $(cat /tmp/substep/t.txt) load $(cut -d' ' -f1 /proc/loadavg)" >> /tmp/substep/sweeps.log
done; done
echo done >> /tmp/substep/sweeps.log
