#!/bin/bash
# usage: nicerun.sh WNICE SHIPS
cd /tmp
WNICE=$1 taskset -c 0 /work/wt-serve/.venv/bin/python /tmp/serve-x/h/split.py redis://127.0.0.1:16391/0 $2 200 30 > /tmp/serve-x/h/out-$1.txt 2>&1 &
while [ ! -s /tmp/serve-x/h/pid ]; do sleep 0.5; done; PID=$(cat /tmp/serve-x/h/pid)
sleep 8
OWN=$(ls /proc/$PID/task | tr '\n' ',' | sed 's/,$//')
perf record -q -e sched:sched_switch -C 0 -o /tmp/serve-x/h/p-$1.data -- sleep 5 >/dev/null 2>&1
while kill -0 $PID 2>/dev/null; do sleep 1; done
perf script -i /tmp/serve-x/h/p-$1.data 2>/dev/null > /tmp/serve-x/h/p-$1.txt
echo "WNICE=$1"; head -4 /tmp/serve-x/h/out-$1.txt | tail -3; grep -E '^  (telemetry|step|log) ' /tmp/serve-x/h/out-$1.txt; tail -1 /tmp/serve-x/h/out-$1.txt
python3 /tmp/serve-x/h/who.py $(cat /tmp/serve-x/h/pid) $OWN /tmp/serve-x/h/p-$1.txt
