#!/usr/bin/env bash
# Soak test of the map server (not part of the test suite): one server on a fresh
# atlas, sessions streamed one after another (two overlapping Machine Hall clips
# in turn, as fast as the server answers) for a while, the server's resident
# memory sampled every 10 s. Prints RSS over time, sessions and frames served,
# and the RSS slope over the second half (a server that keeps per-frame or
# per-keyframe records grows; a healthy one stays flat).
#   scripts/check/soak.sh [SECONDS]          (default 600)
#   LOOK=clean scripts/check/soak.sh 300     (default look: real)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
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

# ORBATLAS_SERVER_WRAP: a command to run the server under, e.g. "heaptrack -o out/soak/heap".
${ORBATLAS_SERVER_WRAP:-} "$SERVER" --db "$OUT/atlas.db" --listen 127.0.0.1:0 --port-file "$OUT/port" 2>"$OUT/server.log" &
SERVER_PID=$!
for _ in $(seq 1 300); do [ -s "$OUT/port" ] && break; sleep 0.1; done
export ORBATLAS_SERVER="http://127.0.0.1:$(cat "$OUT/port")"

t0=$(date +%s)
# Every 10 s: seconds, resident KB, C heap in use KB, keyframes, map points (from /metrics).
( while kill -0 "$SERVER_PID" 2>/dev/null; do
    /usr/bin/python3 - "$ORBATLAS_SERVER" $(( $(date +%s) - t0 )) >> "$OUT/rss.tsv" <<'PY' || true
import sys, urllib.request
m = {}
for line in urllib.request.urlopen(sys.argv[1] + "/metrics", timeout=5).read().decode().splitlines():
    if line and not line.startswith("#"):
        k, _, v = line.rpartition(" ")
        m[k] = float(v)
print(sys.argv[2], int(m["orbatlas_resident_bytes"] / 1024), int(m["orbatlas_heap_in_use_bytes"] / 1024),
      int(m["orbatlas_keyframes"]), int(m["orbatlas_map_points"]), sep="\t")
PY
    sleep 10
  done ) &
SAMPLER_PID=$!

n=0
while [ $(( $(date +%s) - t0 )) -lt "$DURATION" ]; do
  IFS=: read -r seq _ <<< "${CLIPS[$((n % ${#CLIPS[@]}))]}"
  n=$((n + 1))
  if "$OA" stream --dataset "$OUT/${seq}_${LOOK}" --name "soak-$n" --no-progress --stats "$OUT/session.json" > /dev/null 2>> "$OUT/stream.log"; then
    # Between sessions (the last one finished, the next not started): the
    # memory the server keeps, without a session's working set in it.
    /usr/bin/python3 - "$ORBATLAS_SERVER" "$OUT/session.json" "$n" $(( $(date +%s) - t0 )) >> "$OUT/sessions.tsv" <<'PY'
import json, sys, urllib.request
j = json.load(open(sys.argv[2]))
m = {}
for line in urllib.request.urlopen(sys.argv[1] + "/metrics", timeout=5).read().decode().splitlines():
    if line and not line.startswith("#"):
        k, _, v = line.rpartition(" ")
        m[k] = float(v)
print(sys.argv[3], sys.argv[4], j["frames"], j["tracked"], int(m["orbatlas_resident_bytes"] / 1024),
      int(m["orbatlas_heap_in_use_bytes"] / 1024), sep="\t")
PY
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
samples = [tuple(int(x) for x in l.split()) for l in open(f"{out}/rss.tsv") if len(l.split()) == 5]
rss = [(t, kb) for t, kb, _, _, _ in samples]
heap = [(t, kb) for t, _, kb, _, _ in samples]
sessions = [l.rstrip("\n").split("\t") for l in open(f"{out}/sessions.tsv")]
ok = [s for s in sessions if s[2].strip() != "failed"]
frames = sum(int(s[2]) for s in ok)
tracked = sum(int(s[3]) for s in ok)
print(f"soak: {len(sessions)} sessions in {duration} s ({len(sessions) - len(ok)} failed), {frames} frames, {tracked} tracked")
print("RSS over time (MB):", ", ".join(f"{t}s {kb / 1024:.0f}" for t, kb in rss[::3]))
print("heap in use (MB):  ", ", ".join(f"{t}s {kb / 1024:.0f}" for t, kb in heap[::3]))
print("keyframes / points:", ", ".join(f"{s[0]}s {s[3]}/{s[4]}" for s in samples[::6]))
def second_half(series, what):
    half = [(t, kb) for t, kb in series if t >= duration / 2]
    if len(half) < 2:
        return
    n = len(half); mt = sum(t for t, _ in half) / n; mk = sum(k for _, k in half) / n
    slope = sum((t - mt) * (k - mk) for t, k in half) / max(1e-9, sum((t - mt) ** 2 for t, _ in half))
    print(f"second half: {what} {min(k for _, k in half) / 1024:.0f}..{max(k for _, k in half) / 1024:.0f} MB, "
          f"slope {slope * 60 / 1024:+.2f} MB/min")
second_half(rss, "RSS")
second_half(heap, "heap in use")
# Between sessions: the server's own memory, sampled right after each session ended.
between = [(int(s[0]), int(s[4]), int(s[5])) for s in ok]
if len(between) >= 4:
    print("between sessions, RSS / heap in use (MB):",
          ", ".join(f"#{n} {r / 1024:.0f}/{h / 1024:.1f}" for n, r, h in between[:: max(1, len(between) // 10)]))
    half = between[len(between) // 2:]
    k = len(half); mn = sum(n for n, _, _ in half) / k
    for idx, what in ((1, "RSS"), (2, "heap in use")):
        mv = sum(x[idx] for x in half) / k
        slope = sum((x[0] - mn) * (x[idx] - mv) for x in half) / max(1e-9, sum((x[0] - mn) ** 2 for x in half))
        print(f"second half of the sessions: {what} {slope:+.1f} KB per session")
for line in open(f"{out}/metrics.txt"):
    if line.startswith(("orbatlas_keyframes ", "orbatlas_map_points ", "orbatlas_maps ", "orbatlas_worker_errors_total")):
        print("  " + line.strip())
PY
