#!/usr/bin/env bash
# Upload throughput with one and two orbatlas-server replicas over one
# PostgreSQL atlas (issue 23, docs/scaling.md "Replicas"; not part of the test
# suite). A throwaway PostgreSQL cluster (Debian's initdb / pg_ctl, on a Unix
# socket in a temporary folder) holds a fresh database per phase; each phase
# uploads the same recordings (Machine Hall clips, SECONDS long from 40 s,
# MH_01..MH_04 in turn) to the first replica at once (`orbatlas upload
# --no-wait`) and times them until every job is done:
#   1 replica, 1 worker | 1 replica, 2 workers | 2 replicas, 1 worker each
# (the two replicas share the work folder and the job queue: the uploads all go
# to the first one, and the second one's worker takes what the first's is not
# running). Per phase: wall time, frames per second over all jobs, and which
# replica ran each job (its session id's replica range).
#   scripts/bench/replicas.sh                    # 4 uploads of 20 s
#   UPLOADS=8 SECONDS_PER_UPLOAD=10 scripts/bench/replicas.sh
#   LOOK=real scripts/bench/replicas.sh
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BENCH_NAME=bench_replicas
# shellcheck source=scripts/bench/env.sh
source "$ROOT/scripts/bench/env.sh"
SERVER_BIN="${ORBATLAS_SERVER_BIN:-$BUILD_DIR/server/orbatlas-server}"
UPLOADS="${UPLOADS:-4}"
SECONDS_PER_UPLOAD="${SECONDS_PER_UPLOAD:-20}"
LOOK="${LOOK:-clean}"
PG_BIN="$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -1)"
[ -x "$PG_BIN/initdb" ] || { echo "bench_replicas: PostgreSQL's initdb is missing (scripts/setup.sh installs postgresql)" >&2; exit 1; }

WORK="$(mktemp -d /tmp/orbatlas-bench-replicas-XXXXXX)"
AS_PG=()
if [ "$(id -u)" -eq 0 ]; then
  chown postgres "$WORK"
  AS_PG=(runuser -u postgres --)
fi
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  for p in "${PIDS[@]}"; do wait "$p" 2>/dev/null || true; done
  "${AS_PG[@]}" "$PG_BIN/pg_ctl" -D "$WORK/data" -m immediate -w stop >/dev/null 2>&1 || true
  rm -rf "$WORK"
}
trap cleanup EXIT
"${AS_PG[@]}" "$PG_BIN/initdb" -D "$WORK/data" -U orbatlas -A trust -E UTF8 --no-sync > "$WORK/initdb.log"
"${AS_PG[@]}" "$PG_BIN/pg_ctl" -D "$WORK/data" -l "$WORK/server.log" -w -t 60 \
    -o "-k $WORK -c listen_addresses=''" start > /dev/null
psql_db() { "${AS_PG[@]}" "$PG_BIN/psql" -h "$WORK" -U orbatlas -d postgres -q -c "$1" > /dev/null; }

# The recordings: SECONDS_PER_UPLOAD of MH_01.. from 40 s, rendered once per look.
CLIPS=()
for i in $(seq 0 $((UPLOADS - 1))); do
  seq="MH_0$(( i % 4 + 1 ))"
  dir="$DATA/replicas_${seq}_${LOOK}_40_${SECONDS_PER_UPLOAD}"
  if [ ! -f "$dir/mav0/cam1/data.csv" ]; then
    rm -rf "$dir"
    "$OA" sim --sequence "$seq" --look "$LOOK" --start 40 --duration "$SECONDS_PER_UPLOAD" --out "$dir" --no-progress >&2
  fi
  CLIPS+=("$dir")
done
FRAMES=0
for c in "${CLIPS[@]}"; do FRAMES=$((FRAMES + $(($(wc -l < "$c/mav0/cam0/data.csv") - 1)))); done

REPLICA_URL=""
start_replica() {  # DB NAME WORKERS: starts a replica; its URL in REPLICA_URL (not in a subshell: PIDS)
  local db=$1 name=$2 workers=$3
  rm -f "$WORK/$name.port"
  "$SERVER_BIN" --db "$db" --work-dir "$WORK/uploads" --listen 127.0.0.1:0 --port-file "$WORK/$name.port" \
      --workers "$workers" --lease-s 2 --no-merging 2> "$WORK/$name.log" &
  PIDS+=($!)
  for _ in $(seq 1 600); do [ -s "$WORK/$name.port" ] && break; sleep 0.05; done
  [ -s "$WORK/$name.port" ] || { cat "$WORK/$name.log" >&2; echo "bench_replicas: $name did not start" >&2; exit 1; }
  REPLICA_URL="http://127.0.0.1:$(cat "$WORK/$name.port")"
}

phase() {  # LABEL REPLICAS WORKERS
  local label=$1 replicas=$2 workers=$3 db url
  db="phase_$(echo "$label" | tr -c 'a-z0-9' '_')"
  psql_db "CREATE DATABASE $db"
  rm -rf "$WORK/uploads"
  mkdir -p "$WORK/uploads"
  local uri="postgresql://orbatlas@/$db?host=$WORK"
  start_replica "$uri" "${db}_a" "$workers"
  url="$REPLICA_URL"
  if [ "$replicas" -ge 2 ]; then start_replica "$uri" "${db}_b" "$workers"; fi
  local t0 t1
  t0=$(date +%s.%N)
  for c in "${CLIPS[@]}"; do
    "$OA" upload --server "$url" --dataset "$c" --config euroc/stereo --name "$(basename "$c")" --no-wait --no-progress > /dev/null
  done
  while :; do
    "$OA" jobs --server "$url" --json > "$OUT/$db.jobs.json" 2>/dev/null || true
    if /usr/bin/python3 - "$OUT/$db.jobs.json" "$UPLOADS" <<'PY'
import json, sys
try:
    jobs = json.load(open(sys.argv[1]))["jobs"]
except Exception:
    sys.exit(1)
if any(j["state"] == "failed" for j in jobs):
    print("bench_replicas: a job failed: " + json.dumps(jobs), file=sys.stderr)
    sys.exit(2)
sys.exit(0 if len(jobs) == int(sys.argv[2]) and all(j["state"] == "done" for j in jobs) else 1)
PY
    then break; fi
    sleep 0.5
  done
  t1=$(date +%s.%N)
  /usr/bin/python3 - "$OUT/$db.jobs.json" "$label" "$t0" "$t1" "$FRAMES" <<'PY'
import json, sys
jobs = json.load(open(sys.argv[1]))["jobs"]
label, t0, t1, frames = sys.argv[2], float(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5])
runners = {}
for j in jobs:
    r = j["session"] >> 24
    runners[r] = runners.get(r, 0) + 1
wall = t1 - t0
print(json.dumps({"phase": label, "uploads": len(jobs), "frames": frames, "wall_s": round(wall, 1),
                  "frames_per_s": round(frames / wall, 1),
                  "jobs_per_replica": {str(k): v for k, v in sorted(runners.items())}}))
PY
  for p in "${PIDS[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  for p in "${PIDS[@]}"; do wait "$p" 2>/dev/null || true; done
  PIDS=()
}

echo "== $UPLOADS uploads of $SECONDS_PER_UPLOAD s ($FRAMES stereo frames), $LOOK look, $(nproc) cores" >&2
{
  phase "1 replica, 1 worker" 1 1
  phase "1 replica, 2 workers" 1 2
  phase "2 replicas, 1 worker each" 2 1
} | tee "$OUT/summary.jsonl"
