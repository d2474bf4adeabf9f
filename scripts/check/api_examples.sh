#!/usr/bin/env bash
# Runs every curl example of docs/api.md, as a user would paste it, against a
# test server on a fresh atlas, and fails on the first one that gets an error
# reply (curl --fail-with-body). The examples' placeholders (session 3, the
# frame files, /data/MH_01, frame.png) are replaced with a one-second simulated
# clip. Part of the test suite (ctest: api_examples); needs the build and curl.
#   scripts/check/api_examples.sh [BUILD_DIR]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD="${1:-${ORBATLAS_BUILD_DIR:-$ROOT/build}}"
command -v curl >/dev/null || { echo "check_api_examples: curl is missing (scripts/setup.sh installs it)" >&2; exit 1; }
WORK="$(mktemp -d)"
SERVER_PID=""
cleanup() {
  [ -n "$SERVER_PID" ] && kill "$SERVER_PID" 2>/dev/null && wait "$SERVER_PID" 2>/dev/null
  rm -rf "$WORK"
}
trap cleanup EXIT

CLIP="$WORK/MH_01"
"$BUILD/client/orbatlas" sim --sequence MH_01 --start 40 --duration 1 --out "$CLIP" --no-progress >/dev/null
FIRST_T="$(sed -n 2p "$CLIP/mav0/cam0/data.csv" | cut -d, -f1)"
cp "$CLIP/mav0/cam0/data/$FIRST_T.png" "$WORK/frame.png"

"$BUILD/server/orbatlas-server" --db "$WORK/atlas.db" --listen 127.0.0.1:0 --port-file "$WORK/port" \
    --no-merging 2>"$WORK/server.log" &
SERVER_PID=$!
for _ in $(seq 1 200); do [ -s "$WORK/port" ] && break; sleep 0.05; done
[ -s "$WORK/port" ] || { cat "$WORK/server.log" >&2; echo "check_api_examples: the server did not start" >&2; exit 1; }
export S="http://127.0.0.1:$(cat "$WORK/port")"

# The ```sh blocks of docs/api.md, continuation lines joined, curl and tar lines only.
mapfile -t EXAMPLES < <(/usr/bin/python3 - "$ROOT/docs/api.md" <<'PY'
import sys
lines, inside, joined = open(sys.argv[1]).read().split("\n"), False, ""
for line in lines:
    if line.startswith("```"):
        inside = line == "```sh"
        continue
    if not inside:
        continue
    joined += line.rstrip("\\").rstrip() + " " if line.endswith("\\") else line
    if line.endswith("\\"):
        continue
    if joined.startswith(("curl ", "tar ")):
        print(joined)
    joined = ""
PY
)
[ "${#EXAMPLES[@]}" -ge 8 ] || { echo "check_api_examples: found only ${#EXAMPLES[@]} examples in docs/api.md" >&2; exit 1; }

curl() { command curl --fail-with-body --max-time 120 "$@"; }
cd "$CLIP"
SESSION=""
n=0
for example in "${EXAMPLES[@]}"; do
  command="${example//1403636580863555584/$FIRST_T}"
  command="${command//\/data\/MH_01/$CLIP}"
  command="${command//@frame.png/@$WORK/frame.png}"
  command="${command//> map0.ply/> $WORK/map0.ply}"
  [ -n "$SESSION" ] && command="${command//\/v1\/sessions\/3\//\/v1\/sessions\/$SESSION\/}"
  n=$((n + 1))
  echo "[$n] $command"
  if ! reply="$(eval "$command" 2>&1)"; then
    echo "check_api_examples: example $n failed: $reply" >&2
    exit 1
  fi
  echo "    -> ${reply:0:160}"
  if [ -z "$SESSION" ] && [[ "$command" == *"/v1/sessions -H"* ]]; then
    SESSION="$(/usr/bin/python3 -c 'import json,sys; print(json.loads(sys.argv[1])["id"])' "$reply")"
  fi
done
echo "check_api_examples: all $n examples of docs/api.md answered without an error"

# Every metric the Grafana dashboard and docs/monitoring.md name is served.
command curl -s --max-time 30 "$S/metrics" > "$WORK/metrics.txt"
/usr/bin/python3 - "$WORK/metrics.txt" "$ROOT/docs/monitoring/grafana-dashboard.json" "$ROOT/docs/monitoring.md" <<'PY'
import json, re, sys
served = set()
for line in open(sys.argv[1]):
    m = re.match(r"(orbatlas_[a-z_]+)", line)
    if m:
        served.add(m.group(1))
dashboard = json.load(open(sys.argv[2]))
named = set()
for panel in dashboard["panels"]:
    for target in panel["targets"]:
        named.update(re.findall(r"orbatlas_[a-z_]+", target["expr"]))
named.update(re.findall(r"orbatlas_[a-z_]+", open(sys.argv[3]).read()))
# This server runs with --no-merging, which leaves out the merging worker's metrics.
merging_only = {"orbatlas_map_merges_total", "orbatlas_map_merge_pending"}
missing = sorted(n for n in named - merging_only
                 if n not in served and re.sub(r"_(bucket|sum|count)$", "", n) not in served)
if missing:
    sys.exit("check_api_examples: the dashboard or docs/monitoring.md name metrics the server does not serve: " + ", ".join(missing))
print(f"check_api_examples: the dashboard's {len(named)} metric names are all served")
PY
