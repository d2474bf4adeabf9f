#!/usr/bin/env bash
# Memory benchmark (issue 21, not part of the test suite): the server's memory
# over a long run. N live stereo sessions at the camera's rate, each streaming
# SECONDS_PER_PASS of its own Machine Hall sequence REPEAT times in one session
# (`orbatlas stream --repeat`: each pass's timestamps after the last's, so a
# session revisits its map every pass), while the server's resident size
# (VmRSS) and heap in use (orbatlas_heap_in_use_bytes on /metrics) are sampled
# every SAMPLE_S seconds. Prints the samples per minute and the growth from the
# end of the first pass to the end.
#   scripts/bench/memory.sh                                  # N=2, 60 s x 10: ten minutes
#   N=1 REPEAT=5 scripts/bench/memory.sh
#   ORBATLAS_BIN=... ORBATLAS_SERVER_BIN=... scripts/bench/memory.sh   # frozen binaries
# Results in $ORBATLAS_BENCH_OUT (default out/bench_memory).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BENCH_NAME=bench_memory
# shellcheck source=scripts/bench/env.sh
source "$ROOT/scripts/bench/env.sh"
SERVER_BIN="${ORBATLAS_SERVER_BIN:-$BUILD_DIR/server/orbatlas-server}"
N="${N:-2}"
REPEAT="${REPEAT:-10}"
SECONDS_PER_PASS="${SECONDS_PER_PASS:-60}"
START_S="${START_S:-20}"
LOOK="${LOOK:-real}"
SAMPLE_S="${SAMPLE_S:-10}"
SEQUENCES=(MH_01 MH_02 MH_03 MH_04 MH_05)

dataset() { bench_dataset "$1" "$LOOK"; }  # the rendered full sequence

rm -rf "$OUT/run"
mkdir -p "$OUT/run"
for ((i = 0; i < N; ++i)); do dataset "${SEQUENCES[$i]}" > /dev/null; done
"$SERVER_BIN" --db "$OUT/run/atlas.db" --listen 127.0.0.1:0 --port-file "$OUT/run/port" 2> "$OUT/run/server.log" &
SERVER_PID=$!
trap 'kill -TERM "$SERVER_PID" 2>/dev/null || true; wait "$SERVER_PID" 2>/dev/null || true' EXIT
for _ in $(seq 1 300); do [ -s "$OUT/run/port" ] && break; sleep 0.1; done
[ -s "$OUT/run/port" ] || { cat "$OUT/run/server.log" >&2; exit 1; }
URL="http://127.0.0.1:$(cat "$OUT/run/port")"
pids=()
for ((i = 0; i < N; ++i)); do
  seq=${SEQUENCES[$i]}
  "$OA" stream --server "$URL" --dataset "$(dataset "$seq")" --start "$START_S" --duration "$SECONDS_PER_PASS" \
      --repeat "$REPEAT" --rate 1 --max-lag 0.1 --name "memory-$seq" --no-progress --stats "$OUT/run/$seq.json" \
      > "$OUT/run/$seq.txt" 2>&1 &
  pids+=($!)
done
echo "t_s,rss_kb,heap_bytes" > "$OUT/run/memory.csv"
t0=$(date +%s)
running() { for p in "${pids[@]}"; do kill -0 "$p" 2>/dev/null && return 0; done; return 1; }
while running; do
  rss=$(awk '/VmRSS/ {print $2}' "/proc/$SERVER_PID/status")
  heap=$(curl -s --max-time 5 "$URL/metrics" | awk '/^orbatlas_heap_in_use_bytes / {print $2}')
  echo "$(( $(date +%s) - t0 )),$rss,${heap:-0}" >> "$OUT/run/memory.csv"
  sleep "$SAMPLE_S"
done
for p in "${pids[@]}"; do wait "$p"; done

/usr/bin/python3 - "$OUT/run" "$N" "$SECONDS_PER_PASS" "${SEQUENCES[*]}" <<'PY'
import csv, json, os, sys
run, n, per_pass, seqs = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), sys.argv[4].split()
rows = [(int(r["t_s"]), int(r["rss_kb"]) / 1024.0, float(r["heap_bytes"]) / 2**20)
        for r in csv.DictReader(open(os.path.join(run, "memory.csv")))]
print(f"{n} session(s), {len(rows)} samples over {rows[-1][0]} s")
print(f"{'t [s]':>6} {'RSS [MB]':>9} {'heap [MB]':>9}")
for t, rss, heap in rows:
    if t % 60 < 10 or (t, rss, heap) == rows[-1]:
        print(f"{t:>6} {rss:>9.1f} {heap:>9.1f}")
after_first = [r for r in rows if r[0] >= per_pass]
if after_first:
    a, b = after_first[0], rows[-1]
    minutes = max((b[0] - a[0]) / 60.0, 1e-9)
    print(f"from the end of the first pass ({a[0]} s) to the end ({b[0]} s): RSS {a[1]:.1f} -> {b[1]:.1f} MB "
          f"({(b[1] - a[1]) / minutes:+.2f} MB/min), heap {a[2]:.1f} -> {b[2]:.1f} MB ({(b[2] - a[2]) / minutes:+.2f} MB/min)")
print(f"peak RSS {max(r[1] for r in rows):.1f} MB")
for s in seqs[:n]:
    j = json.load(open(os.path.join(run, f"{s}.json")))
    print(f"{s}: {j['frames']} frames, {j['tracked']} tracked, late {j['late_frames']}, skipped {j['skipped_frames']}, "
          f"keyframes {j['keyframes']}, tracking p50 {j['tracking_ms']['p50']:.1f} ms")
PY
