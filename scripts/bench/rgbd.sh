#!/usr/bin/env bash
# Long benchmark (issue 20, not part of the test suite): RGB-D against stereo
# SLAM on full-length simulated Machine Hall sequences, on both simulator looks.
# Renders each sequence once with the depth camera (`orbatlas sim --depth`: the
# TUM RGB-D layout beside the ASL one, kept in $ORBATLAS_BENCH_DATA, default
# build/bench_data, as <seq>_depth and <seq>_<look>_depth), runs `orbatlas run`
# with config/euroc/rgbd.yaml and stereo.yaml on the same images, scores with
# `orbatlas eval`, prints one table.
#   scripts/bench/rgbd.sh                     # MH_01..MH_05, both looks
#   scripts/bench/rgbd.sh MH_01 MH_03         # some of them
#   LOOKS=real scripts/bench/rgbd.sh          # one look
#   MODES=rgbd scripts/bench/rgbd.sh          # without the stereo runs
#   ORBATLAS_BIN=/tmp/orbatlas scripts/bench/rgbd.sh   # a frozen binary (no set-up, no build)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BENCH_NAME=bench_rgbd
# shellcheck source=scripts/bench/env.sh
source "$ROOT/scripts/bench/env.sh"
SEQUENCES=("$@")
[ ${#SEQUENCES[@]} -eq 0 ] && SEQUENCES=(MH_01 MH_02 MH_03 MH_04 MH_05)
read -r -a LOOK_LIST <<< "${LOOKS:-clean real}"
read -r -a MODE_LIST <<< "${MODES:-rgbd stereo}"

NAMES=()
for look in "${LOOK_LIST[@]}"; do
  for s in "${SEQUENCES[@]}"; do
    src="$DATA/${s}_depth"
    [ "$look" = clean ] || src="$DATA/${s}_${look}_depth"
    if [ ! -f "$src/depth.txt" ]; then
      echo "== simulating $s ($look look) with the depth camera into $src"
      rm -rf "$src"
      "$OA" sim --sequence "$s" --look "$look" --depth --out "$src"
    fi
    for mode in "${MODE_LIST[@]}"; do
      name="${s}_${look}_${mode}"
      echo "== orbatlas run $mode on $s ($look look)"
      "$OA" run --config "$ROOT/config/euroc/$mode.yaml" --dataset "$src" --no-progress \
          --out-trajectory "$OUT/$name.txt" --stats "$OUT/$name.json" > "$OUT/$name.log" 2>&1
      "$OA" eval --gt "$src" --est "$OUT/$name.txt" --align se3 --json > "$OUT/$name.eval.json"
      NAMES+=("$name")
    done
  done
done

/usr/bin/python3 - "$OUT" "${NAMES[@]}" <<'PY'
import json, sys
out, names = sys.argv[1], sys.argv[2:]
print(f"{'run':24} {'frames':>6} {'tracked':>7} {'cover':>6} {'maps':>4} {'keyframes':>9} {'ATE[m]':>7} "
      f"{'track p50/p95[ms]':>17} {'BA p50[ms]':>10}")
for n in names:
    j = json.load(open(f"{out}/{n}.json")); e = json.load(open(f"{out}/{n}.eval.json"))
    print(f"{n:24} {j['frames']:>6} {j['tracked']:>7} {e['coverage']:>6.3f} {j['maps']:>4} {j['keyframes']:>9} "
          f"{e['ate_rmse_m']:>7.4f} {j['tracking_ms']['p50']:>8.1f}/{j['tracking_ms']['p95']:<8.1f} "
          f"{j['local_ba_ms']['p50']:>10.1f}")
PY
