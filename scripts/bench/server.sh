#!/usr/bin/env bash
# Benchmark of the map server (docs/benchmarks.md, "Map server"): frames per second
# through the API for one session and for three at once, the latency the server and
# HTTP add to tracking, and POST /v1/localize latency p50/p95 against the stored maps.
#   scripts/bench/server.sh [SECONDS]      (default 60 s of each sequence)
#   LOOK=real scripts/bench/server.sh      (simulator look; default clean)
# Simulated clips are rendered into out/bench_server/ (or taken from
# $ORBATLAS_BENCH_DATA/MH_0x when it holds full simulated clean sequences).
# The localisation queries are images of another flight (MH_04, 20-80 s), none
# of which built the stored maps.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
"$ROOT/scripts/setup.sh"
BUILD_DIR="${ORBATLAS_BUILD_DIR:-$ROOT/build}"
OA="$BUILD_DIR/client/orbatlas"
SERVER="$BUILD_DIR/server/orbatlas-server"
SECONDS_PER_SESSION="${1:-60}"
LOOK="${LOOK:-clean}"
OUT="$ROOT/out/bench_server_$LOOK"
mkdir -p "$OUT"
rm -rf "$OUT"/atlas.db* "$OUT"/*.json "$OUT"/port
SERVER_PID=""
trap '[ -n "$SERVER_PID" ] && kill -TERM "$SERVER_PID" 2>/dev/null && wait "$SERVER_PID" || true' EXIT

declare -A START=([MH_01]=40 [MH_02]=30 [MH_03]=30)
clip() {  # the dataset folder of a sequence, and the --start/--duration to stream
  local seq=$1
  if [ "$LOOK" = clean ] && [ -n "${ORBATLAS_BENCH_DATA:-}" ] && [ -d "$ORBATLAS_BENCH_DATA/$seq/mav0" ]; then
    echo "$ORBATLAS_BENCH_DATA/$seq --start ${START[$seq]} --duration $SECONDS_PER_SESSION"
  else
    [ -d "$OUT/$seq/mav0" ] || "$OA" sim --sequence "$seq" --look "$LOOK" --start "${START[$seq]}" --duration "$SECONDS_PER_SESSION" --out "$OUT/$seq" >&2
    echo "$OUT/$seq"
  fi
}

"$SERVER" --db "$OUT/atlas.db" --listen 127.0.0.1:0 --port-file "$OUT/port" 2>"$OUT/server.log" &
SERVER_PID=$!
for _ in $(seq 1 300); do [ -s "$OUT/port" ] && break; sleep 0.1; done
export ORBATLAS_SERVER="http://127.0.0.1:$(cat "$OUT/port")"

echo "== one session (MH_01, ${SECONDS_PER_SESSION} s, as fast as the server answers)"
# shellcheck disable=SC2046
"$OA" stream --dataset $(clip MH_01) --name one --no-progress --stats "$OUT/one.json"

echo "== three sessions at once (MH_01, MH_02, MH_03)"
# Every clip rendered first: rendered inside the loop, a clip already there
# streamed while the others were still rendering, and the three did not overlap.
declare -A CLIP
for SEQ in MH_01 MH_02 MH_03; do CLIP[$SEQ]="$(clip $SEQ)"; done
PIDS=()
for SEQ in MH_01 MH_02 MH_03; do
  # shellcheck disable=SC2086
  "$OA" stream --dataset ${CLIP[$SEQ]} --name "three-$SEQ" --no-progress --stats "$OUT/three_$SEQ.json" > "$OUT/three_$SEQ.txt" &
  PIDS+=($!)
done
for P in "${PIDS[@]}"; do wait "$P"; done
cat "$OUT"/three_MH_0?.txt
/usr/bin/python3 - "$OUT" <<'PY'
import json, sys, glob
out = sys.argv[1]
three = [json.load(open(f)) for f in sorted(glob.glob(out + "/three_MH_0?.json"))]
one = json.load(open(out + "/one.json"))
each = ", ".join("%.1f" % t["fps"] for t in three)
print(f"one session: {one['fps']:.1f} frames/s; three sessions: {sum(t['fps'] for t in three):.1f} frames/s in total ({each})")
print(f"added by the server p50 {one['server_overhead_ms']['p50']:.2f} ms, by HTTP + client p50 {one['client_overhead_ms']['p50']:.2f} ms (one session)")
PY

echo "== POST /v1/localize: single left images of another flight (MH_04 20-80 s, every 10th frame; none built the maps)"
[ -d "$OUT/MH_04_queries/mav0" ] || "$OA" sim --sequence MH_04 --look "$LOOK" --start 20 --duration 60 --out "$OUT/MH_04_queries" >&2
"$OA" localize --server "$ORBATLAS_SERVER" --config euroc/stereo --dataset "$OUT/MH_04_queries" --every 10 --stats "$OUT/localize.json"
"$OA" maps
