#!/usr/bin/python3
"""CPU seconds of one process's threads by thread name (Linux /proc), for the
capacity benchmark (scripts/bench/capacity.sh): the map server names its
background threads (core/common/thread_name.h: "local mapping", "loop
closing", "global BA", "map merging", "checkpoints", "uploads", "right image");
tracking runs on the HTTP threads, which keep the process's name.

  thread_cpu.py PID OUT.json   # samples every 0.5 s until PID exits or SIGTERM

Per thread, the CPU time it used since the first sample; a thread that ends
between two samples loses at most its last half second."""
import json
import os
import signal
import sys
import time

pid, out = int(sys.argv[1]), sys.argv[2]
hz = os.sysconf("SC_CLK_TCK")
first, last, names = {}, {}, {}
stopping = False


def stop(*_):
    global stopping
    stopping = True


signal.signal(signal.SIGTERM, stop)


def sample(initial):
    try:
        tids = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return False
    for tid in tids:
        try:
            with open(f"/proc/{pid}/task/{tid}/stat") as f:
                stat = f.read()
            with open(f"/proc/{pid}/task/{tid}/comm") as f:
                names[tid] = f.read().strip()
        except OSError:
            continue  # ended meanwhile
        fields = stat[stat.rfind(")") + 2:].split()
        ticks = int(fields[11]) + int(fields[12])  # utime + stime
        first.setdefault(tid, ticks if initial else 0)  # threads born after the first sample count from 0
        last[tid] = ticks
    return True


initial = True
while not stopping and sample(initial):
    initial = False
    time.sleep(0.5)
by_name = {}
for tid, ticks in last.items():
    name = names.get(tid, "?")
    by_name[name] = by_name.get(name, 0.0) + (ticks - first[tid]) / hz
with open(out, "w") as f:
    json.dump({k: round(v, 2) for k, v in sorted(by_name.items(), key=lambda kv: -kv[1])}, f)
    f.write("\n")
