#!/usr/bin/env bash
# The main job on its embedded default: build, render a Machine Hall clip along
# the real MH_01 trajectory, check it against the real ground truth, score the
# reference system's (ORB-SLAM3) real MH_01 output, and benchmark the renderer.
# Everything is written to out/demo/.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh"
BUILD_DIR="${ORBATLAS_BUILD_DIR:-$ROOT/build}"
OA="$BUILD_DIR/client/orbatlas"
OUT="$ROOT/out/demo"
rm -rf "$OUT" && mkdir -p "$OUT"
GT="$ROOT/data/euroc/groundtruth/MH_01_easy.txt.gz"

echo "== 1. Simulate 20 s of MH_01 (stereo + IMU + ground truth, EuRoC ASL layout)"
"$OA" sim --sequence MH_01 --start 10 --duration 20 --out "$OUT/MH_01_clip"

echo "== 2. The simulated trajectory against the real MH_01 ground truth (smoothing only)"
"$OA" eval --gt "$GT" --est "$OUT/MH_01_clip" --align none

echo "== 3. ORB-SLAM3 v1.0 monocular-inertial on real MH_01, scored by orbatlas eval"
"$OA" eval --gt "$GT" --est "$ROOT/data/euroc/peer_trajectories/orbslam3_MH01_monoi_frames.txt.gz" \
     --align se3 --plot "$OUT/orbslam3_MH01_top_view.png"

echo "== 4. Renderer speed"
"$OA" bench render --frames 100

echo "Done: outputs in $OUT"
