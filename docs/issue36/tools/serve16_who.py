# session 16 (serve): usage: python3 serve16_who.py LOOP_TID OWN_TIDS(comma) perf-script.txt (serve16_nicerun.sh)
# from `perf script` of sched:sched_switch on CPU 0: while the loop thread (pid given) was
# preempted (prev_state R), who ran: ms by (own thread name | other), per second of trace
import sys, re, collections
loop = int(sys.argv[1]); own = set(int(x) for x in sys.argv[2].split(','))
t_out = None; acc = collections.Counter(); cur = None; last = None
rx = re.compile(r'\s(\d+\.\d+):\s+sched:sched_switch:\s+prev_comm=(.*?) prev_pid=(\d+) .*?prev_state=(\S+) ==> next_comm=(.*?) next_pid=(\d+)')
first = lastt = None
for line in open(sys.argv[3]):
    m = rx.search(line)
    if not m: continue
    t = float(m.group(1)); pp = int(m.group(3)); st = m.group(4); np_ = int(m.group(6)); nc = m.group(5)
    first = first or t; lastt = t
    if cur is not None and t_out is not None:  # time of the task that ran, while loop was runnable-out
        acc['own' if cur[0] in own else 'other'] += t - cur[1]
    if pp == loop:
        t_out = t if st.startswith('R') else None
    if np_ == loop:
        t_out = None
    cur = (np_, t)
span = lastt - first
print(f"span {span:.1f} s: loop preempted, the CPU went to own threads {acc['own']/span*1e3:.1f} ms/s, others {acc['other']/span*1e3:.1f} ms/s")
