#!/usr/bin/python3
"""The table scripts/check/stress.sh prints: one line per run from out/stress/runs.tsv and
each run's stats and eval JSON, then runs, aborts, worker errors and slot races.
Usage: scripts/analysis/stress_summary.py OUT_DIR"""
import json, os, sys
out = sys.argv[1]
rows = [l.rstrip("\n").split("\t") for l in open(f"{out}/runs.tsv") if l.strip()]
print(f"{'run':20} {'status':8} {'wkerr':>5} {'races':>5} {'maps':>4} {'tracked':>11} {'KFs':>5} {'ATE[m]':>8} {'cover':>6} {'s':>5}")
aborts = errors = races = 0
for r in rows:
    name, status = r[0], r[4]
    secs = r[5] if len(r) > 5 else "-"
    if status in ("ABORTED", "sim_failed"):
        aborts += status == "ABORTED"
        print(f"{name:20} {status:8}")
        continue
    j = json.load(open(f"{out}/{name}.json"))
    e = json.load(open(f"{out}/{name}.eval.json")) if os.path.exists(f"{out}/{name}.eval.json") else {}
    errors += j.get("worker_errors", 0)
    races += j.get("slot_races", 0)
    ate = f"{e['ate_rmse_m']:.4f}" if "ate_rmse_m" in e else "-"
    cov = f"{e['coverage']:.3f}" if "coverage" in e else "-"
    print(f"{name:20} {status:8} {j.get('worker_errors', 0):>5} {j.get('slot_races', 0):>5} {j['maps']:>4} "
          f"{j['tracked']:>5}/{j['frames']:<5} {j['keyframes']:>5} {ate:>8} {cov:>6} {secs:>5}")
print(f"runs {len(rows)}, aborts {aborts}, worker errors {errors}, slot races handled {races}")
