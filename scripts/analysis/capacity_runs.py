#!/usr/bin/python3
"""Several runs of scripts/bench/capacity.sh (RUNS=k) taken together.

    scripts/analysis/capacity_runs.py OUT "1 2 3 4" "MH_01 MH_02 ..."

OUT holds run_1 ... run_k, each with alone_SEQ/ (each clip alone) and nN/ (N
sessions at once). One run of a live session is one sample: its threads and
timing differ from run to run, and so does its ATE, alone as much as with
others. So each clip's ATE with N sessions is compared as a mean over the runs
with the same clip's mean alone, at finish (what the client read when its
session ended) and once the atlas settled (the server's end-of-session merge
search and global BA done), with each side's range. Late and skipped frames
are summed over every run.
"""
import glob
import json
import math
import os
import sys


def load(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def ate(run_dir, d, i, seq, settled):
    """The ATE of session i (1-based) of SEQ in run_dir/d, or None."""
    j = load(os.path.join(run_dir, d, f"{i}_{seq}{'.settled' if settled else ''}.json"))
    return j.get("ate_rmse_m") if j else None


def spread(values):
    """'mean (min-max, n)' in mm of the values that exist."""
    v = [x for x in values if x is not None and not math.isnan(x)]
    if not v:
        return None, "-"
    mean = sum(v) / len(v)
    return mean, f"{1000 * mean:.2f} ({1000 * min(v):.2f}-{1000 * max(v):.2f}, {len(v)})"


def main():
    out, ns, seqs = sys.argv[1], [int(n) for n in sys.argv[2].split()], sys.argv[3].split()
    runs = sorted(glob.glob(os.path.join(out, "run_*")), key=lambda p: int(p.rsplit("_", 1)[1]))
    if not runs:
        sys.exit(f"capacity_runs: no run_* in {out}")
    print(f"== {len(runs)} runs taken together ({out})")
    for n in [n for n in ns if n > 1]:
        sent = late = skipped = 0
        per_run = []
        for r in runs:
            stats = [load(os.path.join(r, f"n{n}", f"{i + 1}_{s}.json")) for i, s in enumerate(seqs[:n])]
            if any(x is None for x in stats):
                continue
            rs = sum(x["frames"] + x["skipped_frames"] for x in stats)
            rl = sum(x["late_frames"] for x in stats)
            sent, late, skipped = sent + rs, late + rl, skipped + sum(x["skipped_frames"] for x in stats)
            per_run.append(f"{100.0 * rl / max(rs, 1):.2f}")
        if not sent:
            continue
        print(f"{n} sessions: {100.0 * late / sent:.2f} % late and {100.0 * skipped / sent:.2f} % skipped "
              f"over {len(per_run)} runs ({', '.join(per_run)} % late per run)")
        print(f"  {'clip':<6} {'when':<8} {'alone: mean (min-max, runs) [mm]':<34} "
              f"{f'{n} at once: mean (min-max, runs) [mm]':<38} against alone")
        for i, s in enumerate(seqs[:n]):
            for settled in (False, True):
                alone_mean, alone_text = spread([ate(r, f"alone_{s}", 1, s, settled) for r in runs])
                with_mean, with_text = spread([ate(r, f"n{n}", i + 1, s, settled) for r in runs])
                ratio = (f"{100.0 * (with_mean / alone_mean - 1.0):+.0f} %"
                         if alone_mean and with_mean is not None else "-")
                print(f"  {s:<6} {'settled' if settled else 'finish':<8} {alone_text:<34} {with_text:<38} {ratio}")


if __name__ == "__main__":
    main()
