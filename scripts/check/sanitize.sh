#!/usr/bin/env bash
# Sanitizer check of the SLAM engine: builds orbatlas with ASan+UBSan ("address")
# or TSan ("thread") in build-<mode>/, renders a Machine Hall clip once, and
# runs `orbatlas run` on it with the sanitizer set to stop at the first report.
# A clean run ends with "sanitize_run: clean". Also runs the map/mapping/SLAM
# tests under the same sanitizer. SERVER=1 adds the server's tests: three
# concurrent sessions; the hardening tests (the slow-client guard, kept-alive
# connections, idle timeouts); the shared-map tests (eight localisations in one map, two
# mapping sessions in one map, a localisation through a live merge and global
# BA); and the replicas over one PostgreSQL atlas (the registry, the job queue,
# and the three two-replica process tests, whose servers run under the
# sanitizer too). SHARED=1 also runs two recordings at once into one atlas
# (`orbatlas run --dataset A --dataset B`, the clip and the same window of the
# next sequence) and the runner's several-recordings test.
#   scripts/check/sanitize.sh address
#   scripts/check/sanitize.sh thread
#   SEQUENCE=MH_03 DURATION=full LOOK=real SERVER=1 scripts/check/sanitize.sh thread   # a full-length run
# SEQUENCE (MH_01), START (40 s), DURATION (20 s, or "full": the whole sequence
# from its start), LOOK (clean or real) choose the clip; CLIP=DIR runs on an
# existing dataset instead. The clip is rendered with the normal build when there
# is one (rendering under a sanitizer is 5-10 times slower and not what is checked).
set -euo pipefail
MODE="${1:?usage: scripts/check/sanitize.sh address|thread}"
case "$MODE" in address|thread) ;; *) echo "mode must be address or thread" >&2; exit 2 ;; esac
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
"$ROOT/scripts/setup.sh" --deps-only
BUILD="$ROOT/build-$MODE"
SEQUENCE="${SEQUENCE:-MH_01}"
LOOK="${LOOK:-clean}"
DURATION="${DURATION:-20}"
START="${START:-40}"
[ "$DURATION" = "full" ] && START=0
TARGETS=(orbatlas test_map test_mapping test_slam)
[ "${SERVER:-0}" = "1" ] && TARGETS+=(test_server orbatlas-server)
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
export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$ROOT/scripts/check/tsan.supp"
# CHOLMOD's OpenMP workers: fewer of them (see scripts/check/tsan.supp for the rest).
if [ "$MODE" = thread ]; then export OMP_NUM_THREADS=1; fi
start=$(date +%s)
"$BUILD/client/orbatlas" run --config "$ROOT/config/euroc/stereo.yaml" --dataset "$CLIP" \
    --out-trajectory "$BUILD/sanitize_trajectory.txt" --stats "$BUILD/sanitize_stats.json" --compare-culling --no-progress
echo "sanitize_run: orbatlas run on $SEQUENCE ($LOOK, start $START s, duration $DURATION) clean in $(( $(date +%s) - start )) s"
for t in test_map test_mapping test_slam; do "$BUILD/tests/$t" --gtest_brief=1; done
if [ "${SERVER:-0}" = "1" ]; then
  "$BUILD/tests/test_server" --gtest_brief=1 --gtest_filter='ServerEndToEnd.ThreeSessionsStreamConcurrently:ServerHardening.*'
  "$BUILD/tests/test_server" --gtest_brief=1 --gtest_filter='SharedMaps.*'
  # Replicas over one PostgreSQL atlas (skipped without PostgreSQL). The
  # killed-replica test forks a child that starts threads: die_after_fork=0.
  TSAN_OPTIONS="$TSAN_OPTIONS:die_after_fork=0" ASAN_OPTIONS="$ASAN_OPTIONS" "$BUILD/tests/test_server" --gtest_brief=1 \
    --gtest_filter='ReplicaRegistry*:SharedJobQueue*:SharedMergeWork*'
  # The server processes run under the sanitizer too (a report ends one, and its test fails).
  "$BUILD/tests/test_server" --gtest_brief=1 --gtest_filter='ServerProcess.*TwoReplicas*:ServerProcess.*AnUploadWhose*:ServerProcess.*TheMergeWork*'
fi
if [ "${SHARED:-0}" = "1" ]; then
  # The same window of the next Machine Hall sequence: another flight, at once.
  NEXT="MH_0$(( ${SEQUENCE#MH_0} % 5 + 1 ))"
  CLIP2="$BUILD/clip_${NEXT}_${LOOK}_${START}_${DURATION}"
  if [ ! -f "$CLIP2/mav0/cam1/data.csv" ]; then
    rm -rf "$CLIP2"
    RANGE=(--start "$START")
    [ "$DURATION" != "full" ] && RANGE+=(--duration "$DURATION")
    OA_SIM="$ROOT/build/client/orbatlas"
    [ -x "$OA_SIM" ] || OA_SIM="$BUILD/client/orbatlas"
    "$OA_SIM" sim --sequence "$NEXT" --look "$LOOK" "${RANGE[@]}" --out "$CLIP2" --threads 1 --no-progress
  fi
  rm -f "$BUILD/sanitize_shared.db"*
  start=$(date +%s)
  "$BUILD/client/orbatlas" run --config "$ROOT/config/euroc/stereo.yaml" --atlas "$BUILD/sanitize_shared.db" \
      --dataset "$CLIP" --out-trajectory "$BUILD/sanitize_shared_a.txt" \
      --dataset "$CLIP2" --out-trajectory "$BUILD/sanitize_shared_b.txt" --no-progress
  echo "sanitize_run: $SEQUENCE and $NEXT at once into one atlas clean in $(( $(date +%s) - start )) s"
  "$BUILD/tests/test_slam" --gtest_brief=1 --gtest_filter='AtlasSessions.SeveralRecordingsAtOnce*'
fi
echo "sanitize_run: clean ($MODE)"
