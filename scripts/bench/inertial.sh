#!/usr/bin/env bash
# Long benchmark (issue 19, issue 65; not part of the test suite): stereo against
# stereo-inertial and monocular-inertial on full-length simulated Machine Hall
# sequences, on both simulator looks (the real look's IMU is the realistic one:
# vibration, biases, noise of the real EuRoC IMU), optionally the 1-s blackout
# (every image black for one second in the middle of the sequence). Renders each
# sequence once (kept in $ORBATLAS_BENCH_DATA, default build/bench_data, as
# scripts/bench/slam.sh does; IMU variants reuse the rendering's images,
# `sim --images-from`), runs `orbatlas run`, scores its final and its live
# trajectory (the poses tracking returned) with `orbatlas eval`, prints one table.
#   scripts/bench/inertial.sh                  # MH_01..MH_05, both looks
#   scripts/bench/inertial.sh MH_01 MH_03      # some of them
#   LOOKS=real scripts/bench/inertial.sh       # one look
#   IMU=real scripts/bench/inertial.sh MH_05   # the real IMU recording (MH_05; MH_01's lossy one)
#   IMU=offset5 scripts/bench/inertial.sh MH_03   # the look's IMU 5 ms late against the camera
#   RUNS=3 scripts/bench/inertial.sh MH_01     # several runs of each (the spread)
#   MODES="stereo stereo_inertial" scripts/bench/inertial.sh   # default: stereo stereo_inertial mono_inertial
#   MODES=blackout scripts/bench/inertial.sh   # stereo-inertial with the 1-s blackout
#   ORBATLAS_BIN=/tmp/orbatlas scripts/bench/inertial.sh   # a frozen binary (no set-up, no build)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BENCH_NAME=bench_inertial
# shellcheck source=scripts/bench/env.sh
source "$ROOT/scripts/bench/env.sh"
SEQUENCES=("$@")
[ ${#SEQUENCES[@]} -eq 0 ] && SEQUENCES=(MH_01 MH_02 MH_03 MH_04 MH_05)
read -r -a LOOK_LIST <<< "${LOOKS:-clean real}"
IMU_SOURCE="${IMU:-synthetic}"
RUN_COUNT="${RUNS:-1}"
read -r -a MODE_LIST <<< "${MODES:-stereo stereo_inertial mono_inertial}"

NAMES=()
for look in "${LOOK_LIST[@]}"; do
  for s in "${SEQUENCES[@]}"; do
    src=$(bench_dataset "$s" "$look")
    case "$IMU_SOURCE" in
      synthetic) ;;
      real | offset5)
        base="$src"
        src="${base}_imu$IMU_SOURCE"
        sim_extra=(--imu real)
        [ "$IMU_SOURCE" = offset5 ] && sim_extra=(--imu-time-offset-ms 5)
        if [ ! -f "$src/mav0/imu0/data.csv" ]; then
          echo "== $s ($look look) with the $IMU_SOURCE IMU into $src"
          rm -rf "$src"
          "$OA" sim --sequence "$s" --look "$look" "${sim_extra[@]}" --images-from "$base" --out "$src" --no-progress
        fi
        ;;
      *) echo "IMU must be synthetic, real or offset5, not $IMU_SOURCE" >&2; exit 2 ;;
    esac
    # The blackout: one second from the middle of the recording.
    frames=$(($(wc -l < "$src/mav0/cam0/data.csv") - 1))
    mid=$(/usr/bin/python3 -c "print(round($frames / 20.0 / 2.0, 1))")
    for run in $(seq 1 "$RUN_COUNT"); do
      for mode in "${MODE_LIST[@]}"; do
        name="${s}_${look}_${IMU_SOURCE}_${mode}_$run"
        config=$mode extra=()
        if [ "$mode" = blackout ]; then
          config=stereo_inertial
          extra=(--black-out "$mid:$(/usr/bin/python3 -c "print($mid + 1.0)")")
        fi
        echo "== orbatlas run $config on $s ($look look${extra[*]:+, ${extra[*]}}), run $run"
        "$OA" run --config "$ROOT/config/euroc/$config.yaml" --dataset "$src" --no-progress \
            --out-trajectory "$OUT/$name.txt" --out-live-trajectory "$OUT/$name.live.txt" \
            --stats "$OUT/$name.json" "${extra[@]}" > "$OUT/$name.log" 2>&1
        # A monocular session's trajectory is the camera's (cam0), a stereo one's the body's.
        frame=body
        [ "$mode" = mono_inertial ] && frame=cam0
        "$OA" eval --gt "$src" --est "$OUT/$name.txt" --align se3 --est-frame "$frame" --json > "$OUT/$name.eval.json"
        "$OA" eval --gt "$src" --est "$OUT/$name.live.txt" --align se3 --est-frame "$frame" --json \
            > "$OUT/$name.live.eval.json"
        NAMES+=("$name")
      done
    done
  done
done

/usr/bin/python3 - "$OUT" "${NAMES[@]}" <<'PY'
import json, sys
out, names = sys.argv[1], sys.argv[2:]
print(f"{'run':40} {'frames':>6} {'visual':>6} {'imu':>4} {'cover':>6} {'maps':>4} {'ATE[m]':>7} {'live[m]':>7} {'init[s]':>7} "
      f"{'offset[ms]':>10} {'track p50/p95[ms]':>17} {'BA p50[ms]':>10} {'VI BAs':>6} {'chi2 p50':>8} "
      f"{'gap end[m]':>10} {'to visual':>9}")
for n in names:
    j = json.load(open(f"{out}/{n}.json")); e = json.load(open(f"{out}/{n}.eval.json"))
    live = json.load(open(f"{out}/{n}.live.eval.json"))
    init = j.get("imu_initialized_at_s")
    b = j.get("black_out") or {}
    gap = b.get("error_at_end_m")
    off = j.get("imu_time_offset_ms")
    chi2 = j.get("imu", {}).get("local_ba_chi2_median", {}).get("p50")
    print(f"{n:40} {j['frames']:>6} {j['tracked']:>6} {j.get('frames_tracked_by_imu', 0):>4} {e['coverage']:>6.3f} "
          f"{j['maps']:>4} {e['ate_rmse_m']:>7.4f} {live['ate_rmse_m']:>7.4f} {'-' if init is None else f'{init:.1f}':>7} "
          f"{'-' if off is None else f'{off:.2f}':>10} "
          f"{j['tracking_ms']['p50']:>8.1f}/{j['tracking_ms']['p95']:<8.1f} {j['local_ba_ms']['p50']:>10.1f} "
          f"{j.get('imu', {}).get('local_bas', 0):>6} {'-' if chi2 is None else f'{chi2:.1f}':>8} "
          f"{'-' if gap is None else f'{gap:.3f}':>10} {b.get('frames_to_visual', '-'):>9}")
PY
