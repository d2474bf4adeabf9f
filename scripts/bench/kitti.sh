#!/usr/bin/env bash
# Real KITTI odometry (not part of the test suite): `orbatlas run` over each
# sequence folder given (default: the real excerpt in ../shared/data/kitti),
# with no settings (the sequence's calib.txt), scored by `orbatlas eval` (ATE
# and KITTI's relative errors); the live poses (what tracking returned) beside
# the final trajectory. RUNS=k repeats. Prints one table.
#   scripts/bench/kitti.sh                                  # ../shared/data/kitti/excerpt_1
#   scripts/bench/kitti.sh /data/kitti/dataset/sequences/05 # a full sequence
#   ORBATLAS_BIN=/tmp/orbatlas scripts/bench/kitti.sh       # a frozen binary (no set-up, no build)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BENCH_NAME=bench_kitti
# shellcheck source=scripts/bench/env.sh
source "$ROOT/scripts/bench/env.sh"
SEQUENCES=("$@")
[ ${#SEQUENCES[@]} -eq 0 ] && SEQUENCES=("$ROOT/../shared/data/kitti/excerpt_1")
RUN_COUNT="${RUNS:-1}"

NAMES=()
for seq in "${SEQUENCES[@]}"; do
  [ -f "$seq/calib.txt" ] || { echo "$seq is not a KITTI sequence folder (no calib.txt)" >&2; exit 2; }
  for run in $(seq 1 "$RUN_COUNT"); do
    name="$(basename "$seq")_$run"
    echo "== orbatlas run on $seq, run $run"
    "$OA" run --dataset "$seq" --no-progress --out-trajectory "$OUT/$name.txt" \
        --out-live-trajectory "$OUT/$name.live.txt" --stats "$OUT/$name.json" > "$OUT/$name.log" 2>&1
    "$OA" eval --gt "$seq" --est "$OUT/$name.txt" --json > "$OUT/$name.eval.json"
    "$OA" eval --gt "$seq" --est "$OUT/$name.txt" --align sim3 --json > "$OUT/$name.sim3.json"
    "$OA" eval --gt "$seq" --est "$OUT/$name.live.txt" --json > "$OUT/$name.live.eval.json"
    NAMES+=("$name")
  done
done

/usr/bin/python3 - "$OUT" "${NAMES[@]}" <<'PY'
import json, sys
out, names = sys.argv[1], sys.argv[2:]
print(f"{'run':24} {'frames':>6} {'posed':>6} {'maps':>4} {'ATE[m]':>7} {'live ATE[m]':>11} {'scale':>7} "
      f"{'trans[%]':>8} {'rot[deg/m]':>10} {'segments':>8} {'path[m]':>7} {'track p50[ms]':>13}")
for n in names:
    s = json.load(open(f"{out}/{n}.json")); e = json.load(open(f"{out}/{n}.eval.json"))
    sim3 = json.load(open(f"{out}/{n}.sim3.json")); live = json.load(open(f"{out}/{n}.live.eval.json"))
    k = e.get("kitti", {})
    print(f"{n:24} {s['frames']:>6} {s['tracked']:>6} {s['maps']:>4} {e['ate_rmse_m']:>7.4f} {live['ate_rmse_m']:>11.4f} "
          f"{sim3['scale']:>7.4f} {k.get('trans_percent', float('nan')):>8.3f} {k.get('rot_deg_per_m', float('nan')):>10.5f} "
          f"{k.get('segments', 0):>8} {k.get('path_m', 0):>7.1f} {s['tracking_ms']['p50']:>13.1f}")
PY
