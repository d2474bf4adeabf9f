#!/usr/bin/env python3
"""Which threads ran while frames were late: a capacity run's frame logs
against a scheduler trace of the machine taken during it.

  perf record -e sched:sched_switch -a -k mono -o sched.data -- sleep 30   # during the run
  python3 -c 'import time; print(time.time() - time.clock_gettime(time.CLOCK_MONOTONIC))' > clockoff.txt
  perf script -i sched.data -F comm,tid,cpu,time,event,trace > sched.txt
  scripts/late_bursts.py OUT/n4 sched.txt clockoff.txt

OUT/n4 is a scripts/bench_capacity.sh output folder (its *.frames.csv). Each
frame instant's 50-ms window (from the first of the sessions' sends) is split
by the CPU time each class of thread ran in it; windows with a late reply are
compared with the others (docs/benchmarks.md, stop 56).
"""
import bisect
import collections
import csv
import glob
import os
import re
import sys

SWITCH = re.compile(r"^\s*(.+?)\s+(\d+)\s+\[(\d+)\]\s+([\d.]+):\s+sched:sched_switch:\s+prev_comm=(.+?) prev_pid=(\d+) "
                    r".*? prev_state=(\S+) ==> next_comm=(.+?) next_pid=(\d+)")
CLASSES = ["tracking and HTTP", "right image", "local mapping", "global BA", "checkpoints", "loop closing",
           "clients", "kdamond.0", "idle"]


def thread_class(comm):
    comm = comm.strip()
    if comm.startswith("swapper"):
        return "idle"
    if comm == "orbatlas-server":
        return "tracking and HTTP"  # the HTTP threads keep the process's name
    if comm == "orbatlas":
        return "clients"
    return comm if comm in CLASSES else "other"


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    frames_dir, trace, clock_file = sys.argv[1:]
    offset = float(open(clock_file).read())  # unix time minus monotonic time
    runs = collections.defaultdict(list)  # class -> [(start, end)] on any CPU
    on_cpu = {}
    for line in open(trace):
        m = SWITCH.match(line)
        if not m:
            continue
        cpu, t = int(m.group(3)), float(m.group(4))
        if cpu in on_cpu:
            comm, start = on_cpu[cpu]
            runs[thread_class(comm)].append((start, t))
        on_cpu[cpu] = (m.group(8), t)
    if not runs:
        sys.exit(f"late_bursts: no sched_switch events in {trace}")
    for intervals in runs.values():
        intervals.sort()
    t_min = min(s for v in runs.values() for s, _ in v)
    t_max = max(e for v in runs.values() for _, e in v)

    logs = sorted(glob.glob(os.path.join(frames_dir, "*.frames.csv")))
    if not logs:
        sys.exit(f"late_bursts: no *.frames.csv in {frames_dir}")
    sessions = [list(csv.DictReader(open(f))) for f in logs]
    n = min(len(s) for s in sessions)

    longest = {c: max(e - s for s, e in v) for c, v in runs.items()}  # no interval starting earlier reaches a

    def ms_in(intervals, a, b, reach):
        total = 0.0
        for s, e in intervals[bisect.bisect_left(intervals, (a - reach, 0.0)):]:
            if s > b:
                break
            if e > a:
                total += min(e, b) - max(s, a)
        return 1000.0 * total

    windows = []
    for i in range(n):
        t0 = min(int(s[i]["sent_unix_us"]) for s in sessions) * 1e-6 - offset
        if t0 < t_min or t0 + 0.05 > t_max:
            continue
        late = sum(s[i]["late"] == "1" for s in sessions)
        windows.append((late, {c: ms_in(v, t0, t0 + 0.05, longest[c]) for c, v in runs.items()}))
    print(f"{len(windows)} frame instants in the trace; CPU time per 50-ms window [ms]")
    print("| windows | count | " + " | ".join(CLASSES + ["other"]) + " |")
    print("|---" * (len(CLASSES) + 3) + "|")
    for name, chosen in (("no late reply", [w for w in windows if w[0] == 0]),
                         ("a late reply", [w for w in windows if w[0] > 0])):
        if not chosen:
            continue
        cells = [sum(w[1].get(c, 0.0) for w in chosen) / len(chosen) for c in CLASSES + ["other"]]
        print(f"| {name} | {len(chosen)} | " + " | ".join(f"{x:.1f}" for x in cells) + " |")
    busy = [w for w in windows if w[1].get("kdamond.0", 0.0) > 2.0]
    late = [w for w in windows if w[0] > 0]
    print(f"windows with kdamond.0 over 2 ms: {len(busy)}, of them with a late reply: {sum(w[0] > 0 for w in busy)}; "
          f"windows with a late reply: {len(late)}, of them with kdamond.0 over 2 ms: "
          f"{sum(w[1].get('kdamond.0', 0.0) > 2.0 for w in late)}")


if __name__ == "__main__":
    main()
