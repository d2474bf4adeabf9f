#!/usr/bin/env bash
# The main job on its embedded default: build, render a Machine Hall clip along
# the real MH_01 trajectory, run stereo SLAM on it and score it against the ground
# truth, and score the reference system's (ORB-SLAM3) real MH_01 output the same way.
# Everything is written to out/demo/.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh"
BUILD_DIR="${ORBATLAS_BUILD_DIR:-$ROOT/build}"
OA="$BUILD_DIR/client/orbatlas"
OUT="$ROOT/out/demo"
rm -rf "$OUT" && mkdir -p "$OUT"
GT="$ROOT/data/euroc/groundtruth/MH_01_easy.txt.gz"

echo "== 1. Simulate 20 s of MH_01 (from 40 s in) (stereo + IMU + ground truth, EuRoC ASL layout)"
"$OA" sim --sequence MH_01 --start 40 --duration 20 --out "$OUT/MH_01_clip"

echo "== 2. Stereo SLAM on the clip (tracking + local mapping)"
"$OA" run --config "$ROOT/config/euroc/stereo.yaml" --dataset "$OUT/MH_01_clip" \
     --out-trajectory "$OUT/slam_trajectory.txt" --stats "$OUT/slam_stats.json"

echo "== 3. The SLAM trajectory against the clip's ground truth"
"$OA" eval --gt "$OUT/MH_01_clip" --est "$OUT/slam_trajectory.txt" --align se3 --plot "$OUT/slam_top_view.png"

echo "== 4. ORB-SLAM3 v1.0 monocular-inertial on real MH_01, scored by orbatlas eval"
"$OA" eval --gt "$GT" --est "$ROOT/data/euroc/peer_trajectories/orbslam3_MH01_monoi_frames.txt.gz" \
     --align se3 --plot "$OUT/orbslam3_MH01_top_view.png"

echo "Done: outputs in $OUT"
