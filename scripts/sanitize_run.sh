#!/usr/bin/env bash
# Sanitizer check of the SLAM engine: builds orbatlas with ASan+UBSan ("address")
# or TSan ("thread") in build-<mode>/, renders a Machine Hall clip once, and
# runs `orbatlas run` on it with the sanitizer set to stop at the first report.
# A clean run ends with "sanitize_run: clean". Also runs the map/mapping/SLAM
# tests (and, with SERVER=1, the server's three-concurrent-sessions test) under
# the same sanitizer.
#   scripts/sanitize_run.sh address
#   scripts/sanitize_run.sh thread
#   SEQUENCE=MH_03 DURATION=full LOOK=real SERVER=1 scripts/sanitize_run.sh thread   # a full-length run
# SEQUENCE (MH_01), START (40 s), DURATION (20 s, or "full": the whole sequence
# from its start), LOOK (clean or real) choose the clip; CLIP=DIR runs on an
# existing dataset instead. The clip is rendered with the normal build when there
# is one (rendering under a sanitizer is 5-10 times slower and not what is checked).
set -euo pipefail
MODE="${1:?usage: scripts/sanitize_run.sh address|thread}"
case "$MODE" in address|thread) ;; *) echo "mode must be address or thread" >&2; exit 2 ;; esac
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh" --deps-only
BUILD="$ROOT/build-$MODE"
SEQUENCE="${SEQUENCE:-MH_01}"
LOOK="${LOOK:-clean}"
DURATION="${DURATION:-20}"
START="${START:-40}"
[ "$DURATION" = "full" ] && START=0
TARGETS=(orbatlas test_map test_mapping test_slam)
[ "${SERVER:-0}" = "1" ] && TARGETS+=(test_server)
cmake -S "$ROOT" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DORBATLAS_SANITIZE="$MODE" >/dev/null
ninja -C "$BUILD" -j"$(nproc)" "${TARGETS[@]}"
CLIP="${CLIP:-$BUILD/clip_${SEQUENCE}_${LOOK}_${START}_${DURATION}}"
if [ ! -f "$CLIP/mav0/cam1/data.csv" ]; then
  rm -rf "$CLIP"
  RANGE=(--start "$START")
  [ "$DURATION" != "full" ] && RANGE+=(--duration "$DURATION")
  if [ -x "$ROOT/build/client/orbatlas" ]; then
    "$ROOT/build/client/orbatlas" sim --sequence "$SEQUENCE" --look "$LOOK" "${RANGE[@]}" --out "$CLIP" --no-progress
  else
    # One render thread: concurrent PNG writes trip a lock-order report inside GDAL
    # (loaded by OpenCV's imgcodecs), which is not ours.
    "$BUILD/client/orbatlas" sim --sequence "$SEQUENCE" --look "$LOOK" "${RANGE[@]}" --out "$CLIP" --threads 1 --no-progress
  fi
fi
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:halt_on_error=1"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$ROOT/scripts/tsan.supp"
# CHOLMOD's OpenMP workers: fewer of them (see scripts/tsan.supp for the rest).
if [ "$MODE" = thread ]; then export OMP_NUM_THREADS=1; fi
start=$(date +%s)
"$BUILD/client/orbatlas" run --config "$ROOT/config/euroc/stereo.yaml" --dataset "$CLIP" \
    --out-trajectory "$BUILD/sanitize_trajectory.txt" --stats "$BUILD/sanitize_stats.json" --compare-culling --no-progress
echo "sanitize_run: orbatlas run on $SEQUENCE ($LOOK, start $START s, duration $DURATION) clean in $(( $(date +%s) - start )) s"
for t in test_map test_mapping test_slam; do "$BUILD/tests/$t" --gtest_brief=1; done
if [ "${SERVER:-0}" = "1" ]; then
  "$BUILD/tests/test_server" --gtest_brief=1 --gtest_filter='ServerEndToEnd.ThreeSessionsStreamConcurrently'
fi
echo "sanitize_run: clean ($MODE)"
