#!/usr/bin/env bash
# Long benchmark (not part of the test suite): stereo SLAM on full-length simulated
# Machine Hall sequences. Renders each sequence once (about 80 s and 1.7 GB each,
# kept in $ORBATLAS_BENCH_DATA, default build/bench_data), runs `orbatlas run` with
# --stats and --final-ba (one global BA after the last frame), scores it with
# `orbatlas eval`, and prints one line per sequence.
#   scripts/bench/slam.sh                    # MH_01..MH_05
#   scripts/bench/slam.sh MH_01 MH_03        # some of them
#   REALTIME=1 scripts/bench/slam.sh MH_01   # frames fed at 20 Hz, late frames counted
#   LOOKS=real scripts/bench/slam.sh          # one simulator look (default: both, clean and real)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
"$ROOT/scripts/setup.sh"
BUILD_DIR="${ORBATLAS_BUILD_DIR:-$ROOT/build}"
OA="$BUILD_DIR/client/orbatlas"
DATA="${ORBATLAS_BENCH_DATA:-$BUILD_DIR/bench_data}"
OUT="$ROOT/out/bench_slam"
mkdir -p "$DATA" "$OUT"
SEQUENCES=("$@")
[ ${#SEQUENCES[@]} -eq 0 ] && SEQUENCES=(MH_01 MH_02 MH_03 MH_04 MH_05)
EXTRA=(--compare-culling --final-ba)
[ "${REALTIME:-0}" = "1" ] && EXTRA+=(--realtime)
read -r -a LOOK_LIST <<< "${LOOKS:-clean real}"

RUNS=()
for look in "${LOOK_LIST[@]}"; do
  for s in "${SEQUENCES[@]}"; do
    src="$DATA/$s"
    [ "$look" = clean ] || src="$DATA/${s}_$look"
    if [ ! -f "$src/mav0/cam1/data.csv" ]; then
      echo "== simulating $s ($look look) into $src"
      rm -rf "$src"
      "$OA" sim --sequence "$s" --look "$look" --out "$src"
    fi
    name="${s}_$look"
    echo "== orbatlas run on $s ($look look)"
    "$OA" run --config "$ROOT/config/euroc/stereo.yaml" --dataset "$src" \
        --out-trajectory "$OUT/$name.txt" --stats "$OUT/$name.json" "${EXTRA[@]}"
    "$OA" eval --gt "$src" --est "$OUT/$name.txt" --align se3 --json > "$OUT/$name.eval.json"
    RUNS+=("$name")
  done
done

/usr/bin/python3 - "$OUT" "${RUNS[@]}" <<'PY'
import json, sys
out, seqs = sys.argv[1], sys.argv[2:]
print(f"{'run':12} {'frames':>6} {'tracked':>7} {'cover':>6} {'maps':>4} {'ATE[m]':>7} {'track p50/p95 [ms]':>18} "
      f"{'map/KF p50 [ms]':>15} {'BA p50 [ms]':>11} {'cull scan/incr [ms/KF]':>22} {'KFs':>5} {'MPs':>6} {'RSS[MB]':>7} {'late':>5} {'wkerr':>5}")
for s in seqs:
    j = json.load(open(f"{out}/{s}.json")); e = json.load(open(f"{out}/{s}.eval.json"))
    by = j["culling_ms_per_kf_by_scheme"]
    cull = "/".join("-" if by[k] is None else f"{by[k]:.4f}" for k in ("scan", "incremental"))
    print(f"{s:12} {j['frames']:>6} {j['tracked']:>7} {e['coverage']:>6.3f} {j['maps']:>4} {e['ate_rmse_m']:>7.4f} "
          f"{j['tracking_ms']['p50']:>8.1f}/{j['tracking_ms']['p95']:<9.1f} {j['local_mapping_ms_per_kf']['p50']:>15.1f} "
          f"{j['local_ba_ms']['p50']:>11.1f} {cull:>22} {j['keyframes']:>5} {j['mappoints']:>6} {j['peak_rss_mb']:>7.0f} {j['late_frames']:>5} {j.get('worker_errors', 0):>5}")
    o = j["objects"]
    print(f"       objects: keyframes {o['keyframes']}, mappoints {o['mappoints']}")
    lc = j.get("loop_closing")
    if lc:
        pr = lc["place_recognition_ms_per_kf"]
        gba = ", ".join(f"{g['keyframes']} KFs {g['seconds']:.2f} s" + (" (interrupted)" if g["interrupted"] else "")
                        for g in lc["global_ba"]) or "none"
        corr = ", ".join(f"{l['correction_ms']:.0f} ms ({l['correction_m']:.3f} m, error {l.get('error_m', float('nan')):.3f} m)"
                         for l in lc["loops"]) or "none"
        print(f"       loops {j['loops']} (false {lc.get('false_loops', '?')}); place recognition ms/KF p50 "
              f"{pr['p50']:.2f} p95 {pr['p95']:.2f}; hypotheses {lc['hypotheses']}; corrections: {corr}; global BA: {gba}")
PY
