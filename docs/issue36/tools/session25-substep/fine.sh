#!/bin/bash
cd /work/wt-substep
SW=".venv/bin/touchdown sweep scenarios/envelope.toml --vary ships.initial.vertical_speed=-12:-1 --vary ships.initial.horizontal_speed=0:6 --vary ships.initial.tilt_deg=0:15 --samples 10000 --seed 1"
/usr/bin/time -f "%e wall %U user" $SW --workers 1 --set sim.impact_substep=0.001 --set sim.stiff_substep=0.0001 -o /tmp/substep/sub-fine1.parquet > /tmp/substep/fine1.log 2>&1
/usr/bin/time -f "%e wall %U user" $SW --workers 1 --set sim.max_substep=0.005 --set sim.impact_substep=0.001 --set sim.coarse_substep=0 --set sim.stiff_substep=0.0001 -o /tmp/substep/sub-fine.parquet > /tmp/substep/fine.log 2>&1
