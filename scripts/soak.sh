#!/usr/bin/env bash
# Soak test of the map server (not part of the test suite): one server on a fresh
# atlas, sessions streamed one after another (two overlapping Machine Hall clips
# in turn, as fast as the server answers) for a while, the server's resident
# memory sampled every 10 s. Prints RSS over time, sessions and frames served,
# and the RSS slope over the second half (a server that keeps per-frame or
# per-keyframe records grows; a healthy one stays flat).
#   scripts/soak.sh [SECONDS]          (default 600)
#   LOOK=clean scripts/soak.sh 300     (default look: real)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh"
BUILD_DIR="${ORBATLAS_BUILD_DIR:-$ROOT/build}"
OA="${ORBATLAS_BIN:-$BUILD_DIR/client/orbatlas}"
SERVER="${ORBATLAS_SERVER_BIN:-$BUILD_DIR/server/orbatlas-server}"
DURATION="${1:-600}"
LOOK="${LOOK:-real}"
OUT="$ROOT/out/soak"
mkdir -p "$OUT"
rm -rf "$OUT"/atlas.db* "$OUT"/port "$OUT"/rss.tsv "$OUT"/sessions.tsv
SERVER_PID=""
SAMPLER_PID=""
cleanup() {
  [ -n "$SAMPLER_PID" ] && kill "$SAMPLER_PID" 2>/dev/null || true
  [ -n "$SERVER_PID" ] && kill -TERM "$SERVER_PID" 2>/dev/null && wait "$SERVER_PID" 2>/dev/null || true
}
trap cleanup EXIT

CLIPS=("MH_01:40" "MH_02:30")
for c in "${CLIPS[@]}"; do
  IFS=: read -r seq start <<< "$c"
  dir="$OUT/${seq}_${LOOK}"
  [ -f "$dir/mav0/cam1/data.csv" ] || { rm -rf "$dir"; "$OA" sim --sequence "$seq" --look "$LOOK" --start "$start" --duration 20 --out "$dir" --no-progress >/dev/null; }
done

"$SERVER" --db "$OUT/atlas.db" --listen 127.0.0.1:0 --port-file "$OUT/port" 2>"$OUT/server.log" &
SERVER_PID=$!
for _ in $(seq 1 300); do [ -s "$OUT/port" ] && break; sleep 0.1; done
export ORBATLAS_SERVER="http://127.0.0.1:$(cat "$OUT/port")"

t0=$(date +%s)
( while kill -0 "$SERVER_PID" 2>/dev/null; do
    printf '%s\t%s\n' $(( $(date +%s) - t0 )) "$(awk '/VmRSS/ {print $2}' /proc/"$SERVER_PID"/status)" >> "$OUT/rss.tsv"
    sleep 10
  done ) &
SAMPLER_PID=$!

n=0
while [ $(( $(date +%s) - t0 )) -lt "$DURATION" ]; do
  IFS=: read -r seq _ <<< "${CLIPS[$((n % ${#CLIPS[@]}))]}"
  n=$((n + 1))
  if "$OA" stream --dataset "$OUT/${seq}_${LOOK}" --name "soak-$n" --no-progress --stats "$OUT/session.json" > /dev/null 2>> "$OUT/stream.log"; then
    printf '%s\t%s\t%s\n' "$n" $(( $(date +%s) - t0 )) "$(/usr/bin/python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); print(j["frames"], j["tracked"])' "$OUT/session.json")" >> "$OUT/sessions.tsv"
  else
    printf '%s\t%s\tfailed\n' "$n" $(( $(date +%s) - t0 )) >> "$OUT/sessions.tsv"
  fi
done
"$OA" maps > "$OUT/maps.txt" || true
/usr/bin/python3 -c 'import sys, urllib.request; sys.stdout.write(urllib.request.urlopen(sys.argv[1] + "/metrics").read().decode())' \
    "$ORBATLAS_SERVER" > "$OUT/metrics.txt" || true

/usr/bin/python3 - "$OUT" "$DURATION" <<'PY'
import sys
out, duration = sys.argv[1], int(sys.argv[2])
rss = [tuple(int(x) for x in l.split()) for l in open(f"{out}/rss.tsv") if len(l.split()) == 2]
sessions = [l.split("\t") for l in open(f"{out}/sessions.tsv")]
ok = [s for s in sessions if s[2].strip() != "failed"]
frames = sum(int(s[2].split()[0]) for s in ok)
tracked = sum(int(s[2].split()[1]) for s in ok)
print(f"soak: {len(sessions)} sessions in {duration} s ({len(sessions) - len(ok)} failed), {frames} frames, {tracked} tracked")
print("RSS over time (MB):", ", ".join(f"{t}s {kb / 1024:.0f}" for t, kb in rss[::3]))
half = [(t, kb) for t, kb in rss if t >= duration / 2]
if len(half) >= 2:
    n = len(half); mt = sum(t for t, _ in half) / n; mk = sum(k for _, k in half) / n
    slope = sum((t - mt) * (k - mk) for t, k in half) / max(1e-9, sum((t - mt) ** 2 for t, _ in half))
    print(f"second half: RSS {min(k for _, k in half) / 1024:.0f}..{max(k for _, k in half) / 1024:.0f} MB, "
          f"slope {slope * 60 / 1024:+.2f} MB/min")
for line in open(f"{out}/metrics.txt"):
    if line.startswith(("orbatlas_keyframes ", "orbatlas_map_points ", "orbatlas_maps ", "orbatlas_worker_errors_total")):
        print("  " + line.strip())
PY
