#!/usr/bin/env bash
# Long benchmark (issue 20, not part of the test suite): monocular and
# monocular-inertial SLAM on full-length simulated Machine Hall sequences, on
# both simulator looks (cam0 and imu0 of the renders scripts/bench/slam.sh
# keeps in $ORBATLAS_BENCH_DATA, default build/bench_data). Runs `orbatlas run`
# with config/euroc/mono.yaml and mono_inertial.yaml and scores the camera's
# trajectory with `orbatlas eval --est-frame cam0`: `--align sim3` for mono (a
# single camera has no metric scale), `--align se3` for mono_inertial (the IMU
# makes it metric; the scale error is the Sim3 alignment's scale - 1); prints
# one table with the ATE, the
# share of the path it is, the frames covered and when the map started
# (seconds after the first frame).
#   scripts/bench/mono.sh                     # MH_01..MH_05, both looks
#   scripts/bench/mono.sh MH_01 MH_03         # some of them
#   LOOKS=real scripts/bench/mono.sh          # one look
#   MODES=mono_inertial scripts/bench/mono.sh # one sensor
#   ORBATLAS_BIN=/tmp/orbatlas scripts/bench/mono.sh   # a frozen binary (no set-up, no build)
#   MODES=mono_left scripts/bench/mono.sh     # the left camera of the stereo rig alone
# mono_left: `orbatlas run --config stereo.yaml --sensor mono --atlas` on a copy of
# an atlas holding the stereo map of another sequence (MH_01's; MH_02's for
# MH_01): the single camera starts its own map at its own scale, and merging
# into the stereo map makes it metric, so it is scored with --align se3.
# mono_inertial_left: the same with the IMU (`--config stereo_inertial.yaml
# --sensor mono_inertial`) on a copy of the stereo-inertial map of the other
# sequence: a monocular-inertial map merged into a stereo-inertial one.
#   MODES=mono_inertial_left scripts/bench/mono.sh
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BENCH_NAME=bench_mono
# shellcheck source=scripts/bench/env.sh
source "$ROOT/scripts/bench/env.sh"
SEQUENCES=("$@")
[ ${#SEQUENCES[@]} -eq 0 ] && SEQUENCES=(MH_01 MH_02 MH_03 MH_04 MH_05)
read -r -a LOOK_LIST <<< "${LOOKS:-clean real}"
read -r -a MODE_LIST <<< "${MODES:-mono mono_inertial}"

NAMES=()
for look in "${LOOK_LIST[@]}"; do
  for s in "${SEQUENCES[@]}"; do
    src="$DATA/$s"
    [ "$look" = clean ] || src="$DATA/${s}_$look"
    if [ ! -f "$src/mav0/cam0/data.csv" ]; then
      echo "== simulating $s ($look look) into $src"
      rm -rf "$src"
      "$OA" sim --sequence "$s" --look "$look" --out "$src"
    fi
    for mode in "${MODE_LIST[@]}"; do
      name="${s}_${look}_${mode}"
      echo "== orbatlas run $mode on $s ($look look)"
      if [ "$mode" = mono_left ] || [ "$mode" = mono_inertial_left ]; then
        rig=stereo
        sensor=mono
        [ "$mode" = mono_inertial_left ] && rig=stereo_inertial && sensor=mono_inertial
        ref=MH_01
        [ "$s" = MH_01 ] && ref=MH_02
        ref_src="$DATA/$ref"
        [ "$look" = clean ] || ref_src="$DATA/${ref}_$look"
        base="$OUT/${rig}_${ref}_${look}.db"
        if [ ! -f "$ref_src/mav0/cam0/data.csv" ]; then
          echo "== simulating $ref ($look look) into $ref_src"
          rm -rf "$ref_src"
          "$OA" sim --sequence "$ref" --look "$look" --out "$ref_src"
        fi
        if [ ! -f "$base" ]; then
          echo "== the $rig map of $ref ($look look) into $base"
          "$OA" run --config "$ROOT/config/euroc/$rig.yaml" --dataset "$ref_src" --no-progress --atlas "$base" \
              --out-trajectory "$OUT/${rig}_${ref}_${look}.txt" > "$OUT/${rig}_${ref}_${look}.log" 2>&1
        fi
        rm -f "$OUT/$name.db"
        cp "$base" "$OUT/$name.db"
        "$OA" run --config "$ROOT/config/euroc/$rig.yaml" --sensor "$sensor" --atlas "$OUT/$name.db" --dataset "$src" \
            --no-progress --out-trajectory "$OUT/$name.txt" --stats "$OUT/$name.json" > "$OUT/$name.log" 2>&1
      else
        "$OA" run --config "$ROOT/config/euroc/$mode.yaml" --dataset "$src" --no-progress \
            --out-trajectory "$OUT/$name.txt" --stats "$OUT/$name.json" > "$OUT/$name.log" 2>&1
      fi
      align=sim3
      [ "$mode" = mono ] || align=se3
      "$OA" eval --gt "$src" --est "$OUT/$name.txt" --align "$align" --est-frame cam0 --json > "$OUT/$name.eval.json"
      "$OA" eval --gt "$src" --est "$OUT/$name.txt" --align sim3 --est-frame cam0 --json > "$OUT/$name.sim3.json"
      /usr/bin/python3 - "$src" "$OUT/$name.txt" > "$OUT/$name.path.json" <<'PY'
import json, sys
import numpy as np
gt = np.loadtxt(f"{sys.argv[1]}/mav0/state_groundtruth_estimate0/data.csv", delimiter=",", comments="#")
est = np.loadtxt(sys.argv[2], comments="#", ndmin=2)
t0, t1 = est[0, 0], est[-1, 0]
t0, t1 = (t0, t1) if t0 > 1e12 else (t0 * 1e9, t1 * 1e9)  # seconds or nanoseconds
inside = gt[(gt[:, 0] >= t0) & (gt[:, 0] <= t1)]
first_frame = np.loadtxt(f"{sys.argv[1]}/mav0/cam0/data.csv", delimiter=",", comments="#", dtype=str, ndmin=2)[0, 0]
print(json.dumps({"path_m": float(np.linalg.norm(np.diff(inside[:, 1:4], axis=0), axis=1).sum()),
                  "first_pose_s": float((t0 - float(first_frame)) * 1e-9)}))
PY
      NAMES+=("$name")
    done
  done
done

/usr/bin/python3 - "$OUT" "${NAMES[@]}" <<'PY'
import json, sys
out, names = sys.argv[1], sys.argv[2:]
print(f"{'run':28} {'frames':>6} {'tracked':>7} {'cover':>6} {'maps':>4} {'keyframes':>9} {'align':>5} {'ATE[m]':>7} "
      f"{'path[m]':>7} {'ATE/path':>8} {'scale-1':>8} {'start[s]':>8} {'IMU init[s]':>11} {'track p50/p95[ms]':>17} "
      f"{'BA p50[ms]':>10} {'loops':>5} {'merges':>6}")
for n in names:
    j = json.load(open(f"{out}/{n}.json")); e = json.load(open(f"{out}/{n}.eval.json"))
    p = json.load(open(f"{out}/{n}.path.json"))
    sim3 = json.load(open(f"{out}/{n}.sim3.json"))
    init = j.get("imu_initialized_at_s")
    init = f"{init:>11.2f}" if init is not None else f"{'-':>11}"
    print(f"{n:28} {j['frames']:>6} {j['tracked']:>7} {e['coverage']:>6.3f} {j['maps']:>4} {j['keyframes']:>9} "
          f"{e['align']:>5} {e['ate_rmse_m']:>7.4f} {p['path_m']:>7.1f} "
          f"{100 * e['ate_rmse_m'] / max(p['path_m'], 1e-9):>7.3f}% {sim3['scale'] - 1:>8.4f} "
          f"{p['first_pose_s']:>8.1f} {init} {j['tracking_ms']['p50']:>8.1f}/{j['tracking_ms']['p95']:<8.1f} "
          f"{j['local_ba_ms']['p50']:>10.1f} {j.get('loops', 0):>5} {j.get('live_merges', 0):>6}")
PY
