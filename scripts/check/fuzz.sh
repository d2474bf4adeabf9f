#!/usr/bin/env bash
# Fuzzes the parsers a client's bytes reach (docs/fuzzing.md) with libFuzzer
# (Debian's clang), under ASan and UBSan: builds the targets in build-fuzz/ with
# clang, then runs each for SECONDS (default 600) from its seed corpus in
# fuzz/corpus/<target>/ (new inputs go to build-fuzz/corpus/<target>/, not into
# the repository). Stops at the first crash, leak or sanitizer report, keeping
# the input as build-fuzz/crash-<target>-*; prints one line of figures per target.
#   scripts/check/fuzz.sh                     # every target, 10 minutes each
#   SECONDS_EACH=30 scripts/check/fuzz.sh fuzz_tar fuzz_imu_batch
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
"$ROOT/scripts/setup.sh" --deps-only
command -v clang++ >/dev/null || { echo "fuzz: needs clang (Debian's clang package)" >&2; exit 1; }
BUILD="$ROOT/build-fuzz"
EACH="${SECONDS_EACH:-600}"
ALL=(fuzz_tar fuzz_settings fuzz_image_decode fuzz_raw_frame fuzz_imu_batch fuzz_session_request)
TARGETS=("$@")
[ ${#TARGETS[@]} -eq 0 ] && TARGETS=("${ALL[@]}")
if [ ! -f "$BUILD/build.ninja" ]; then
  CXX=clang++ cmake -S "$ROOT" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DORBATLAS_FUZZ=ON \
    -DORBATLAS_SANITIZE=address -DORBATLAS_BUILD_TESTS=OFF >/dev/null
fi
cmake --build "$BUILD" -j "${ORBATLAS_JOBS:-$(nproc)}" --target "${TARGETS[@]}"
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
status=0
printf '%-18s %10s %12s %8s %8s %s\n' target seconds executions cov ft result
for t in "${TARGETS[@]}"; do
  corpus="$BUILD/corpus/$t"
  mkdir -p "$corpus"
  log="$BUILD/$t.log"
  set +e
  (cd "$BUILD" && "./fuzz/$t" -max_total_time="$EACH" -print_final_stats=1 -artifact_prefix="$BUILD/crash-$t-" \
    -rss_limit_mb=4096 -timeout=10 "$corpus" "$ROOT/fuzz/corpus/$t") >"$log" 2>&1
  rc=$?
  set -e
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | awk '{print $2}')
  ft=$(grep -o 'ft: [0-9]*' "$log" | tail -1 | awk '{print $2}')
  result=clean
  if [ $rc -ne 0 ]; then result="FOUND (exit $rc; see $log)"; status=1; fi
  printf '%-18s %10s %12s %8s %8s %s\n' "$t" "$EACH" "${runs:-?}" "${cov:-?}" "${ft:-?}" "$result"
done
exit $status
