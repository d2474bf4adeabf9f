#!/usr/bin/env bash
# Sanitizer check of the SLAM engine: builds orbatlas with ASan+UBSan ("address")
# or TSan ("thread") in build-<mode>/, renders a 20 s Machine Hall clip once, and
# runs `orbatlas run` on it with the sanitizer set to stop at the first report.
# A clean run ends with "sanitize_run: clean". Also runs the map/mapping/SLAM
# tests under the same sanitizer.
#   scripts/sanitize_run.sh address
#   scripts/sanitize_run.sh thread
set -euo pipefail
MODE="${1:?usage: scripts/sanitize_run.sh address|thread}"
case "$MODE" in address|thread) ;; *) echo "mode must be address or thread" >&2; exit 2 ;; esac
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh" --deps-only
BUILD="$ROOT/build-$MODE"
cmake -S "$ROOT" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DORBATLAS_SANITIZE="$MODE" >/dev/null
ninja -C "$BUILD" -j"$(nproc)" orbatlas test_map test_mapping test_slam
CLIP="$BUILD/clip_MH_01_20s"
if [ ! -f "$CLIP/mav0/cam1/data.csv" ]; then
  rm -rf "$CLIP"
  # One render thread: concurrent PNG writes trip a lock-order report inside GDAL
  # (loaded by OpenCV's imgcodecs), which is not ours.
  "$BUILD/client/orbatlas" sim --sequence MH_01 --start 40 --duration 20 --out "$CLIP" --threads 1 --no-progress
fi
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:halt_on_error=1"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$ROOT/scripts/tsan.supp"
"$BUILD/client/orbatlas" run --config "$ROOT/config/euroc/stereo.yaml" --dataset "$CLIP" \
    --out-trajectory "$BUILD/sanitize_trajectory.txt" --stats "$BUILD/sanitize_stats.json" --compare-culling --no-progress
for t in test_map test_mapping test_slam; do "$BUILD/tests/$t" --gtest_brief=1; done
echo "sanitize_run: clean ($MODE)"
