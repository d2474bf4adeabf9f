#!/usr/bin/env bash
# Benchmark of shared maps (docs/benchmarks.md, "Shared maps"; issue 18), over
# HTTP at the camera rate (orbatlas stream --rate 1, 20 Hz), on this machine:
#  1. fleet: one mapping session plus N = 1, 2, 4, 8 localisation sessions in
#     one map (a stored map of MH_01 40-70 s; the mapping session flies MH_02
#     40-70 s and extends it, the localisers fly MH_02 too, starting 0.5 s apart:
#     their images are the mapping session's, so their accuracy is not claimed
#     here, only the load): frames/s, late frames, tracking p50/p95 per kind of
#     session, the server's CPU (cores busy over the phase);
#  2. two and three mapping sessions in one place at once (MH_01, MH_02, MH_03
#     40-70 s, fresh atlas): keyframes, maps at the end, frames/s, joint ATE
#     under one alignment (orbatlas eval with every session), against the same
#     sessions built apart (--no-join-at-start --no-live-merging, one after
#     another: each its own map, merged by the server when it ends).
#   scripts/bench/fleet.sh [SECONDS]      (default 30 s of each sequence)
#   LOOK=real scripts/bench/fleet.sh      (simulator look; default clean)
#   FLEET="1 2" MAPPERS="2" scripts/bench/fleet.sh 10   (a quick subset)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
"$ROOT/scripts/setup.sh"
BUILD_DIR="${ORBATLAS_BUILD_DIR:-$ROOT/build}"
OA="$BUILD_DIR/client/orbatlas"
SERVER="$BUILD_DIR/server/orbatlas-server"
SECONDS_PER_SESSION="${1:-30}"
LOOK="${LOOK:-clean}"
read -r -a FLEET <<< "${FLEET-1 2 4 8}"  # FLEET="" skips the fleet
read -r -a MAPPERS <<< "${MAPPERS-2 3}"
OUT="$ROOT/out/bench_fleet_$LOOK"
mkdir -p "$OUT"
SERVER_PID=""
stop_server() {
  if [ -n "$SERVER_PID" ]; then
    kill -TERM "$SERVER_PID" 2>/dev/null || true
    wait "$SERVER_PID" 2>/dev/null || true
    SERVER_PID=""
  fi
}
trap stop_server EXIT

clip() {  # rendered once per look: MH_0x, 40 s on, SECONDS_PER_SESSION long
  local seq=$1 dir="$OUT/clips/$1_${SECONDS_PER_SESSION}"
  [ -f "$dir/mav0/cam1/data.csv" ] || "$OA" sim --sequence "$seq" --look "$LOOK" --start 40 \
    --duration "$SECONDS_PER_SESSION" --out "$dir" --no-progress >&2
  echo "$dir"
}

start_server() {  # start_server DB [flags...]
  local db=$1
  shift
  rm -f "$OUT/port"
  "$SERVER" --db "$db" --listen 127.0.0.1:0 --port-file "$OUT/port" --max-sessions 12 "$@" 2>>"$OUT/server.log" &
  SERVER_PID=$!
  for _ in $(seq 1 300); do [ -s "$OUT/port" ] && break; sleep 0.1; done
  export ORBATLAS_SERVER="http://127.0.0.1:$(cat "$OUT/port")"
}

cpu_ticks() { awk '{print $14 + $15}' "/proc/$SERVER_PID/stat"; }
count_maps() { curl -s "$ORBATLAS_SERVER/v1/maps" | /usr/bin/python3 -c 'import json,sys; print(len(json.load(sys.stdin)["maps"]))'; }

: > "$OUT/server.log"
MH01=$(clip MH_01)
MH02=$(clip MH_02)
MH03=$(clip MH_03)

if [ ${#FLEET[@]} -gt 0 ]; then
echo "== fleet: one mapping session + N localisation sessions in one map (${SECONDS_PER_SESSION} s, 20 Hz)"
rm -rf "$OUT"/fleet_base.db*
start_server "$OUT/fleet_base.db"
"$OA" stream --dataset "$MH01" --name stored --no-progress > /dev/null
stop_server
for N in "${FLEET[@]}"; do
  rm -rf "$OUT"/fleet.db* "$OUT"/fleet_"$N"_*.json
  for f in "$OUT"/fleet_base.db "$OUT"/fleet_base.db-wal; do
    [ -f "$f" ] && cp "$f" "$OUT/fleet.db${f#"$OUT"/fleet_base.db}"
  done
  start_server "$OUT/fleet.db"
  ticks0=$(cpu_ticks)
  t0=$(date +%s.%N)
  PIDS=()
  "$OA" stream --dataset "$MH02" --name mapper --mode map --rate 1 --no-progress \
    --stats "$OUT/fleet_${N}_map.json" > /dev/null &
  PIDS+=($!)
  for i in $(seq 1 "$N"); do
    "$OA" stream --dataset "$MH02" --name "localizer $i" --mode localize --rate 1 --start "$(awk "BEGIN { print 0.5 * $i }")" \
      --no-progress --stats "$OUT/fleet_${N}_loc$i.json" > /dev/null &
    PIDS+=($!)
  done
  for P in "${PIDS[@]}"; do wait "$P"; done
  t1=$(date +%s.%N)
  ticks1=$(cpu_ticks)
  echo "$N $ticks0 $ticks1 $t0 $t1 $(getconf CLK_TCK)" > "$OUT/fleet_${N}_cpu.txt"
  stop_server
done
/usr/bin/python3 - "$OUT" "${FLEET[@]}" <<'PY'
import json, sys, glob
out, fleet = sys.argv[1], sys.argv[2:]
print("| N localisers | mapping fps | mapping late | mapping tracking p50/p95 ms | localiser fps (mean) | localiser late (total / frames) | localiser tracked | localiser tracking p50/p95 ms | server CPU (cores) |")
print("|---|---|---|---|---|---|---|---|---|")
for n in fleet:
    m = json.load(open(f"{out}/fleet_{n}_map.json"))
    locs = [json.load(open(f)) for f in sorted(glob.glob(f"{out}/fleet_{n}_loc*.json"))]
    _, t0, t1, w0, w1, hz = open(f"{out}/fleet_{n}_cpu.txt").read().split()
    cores = (float(t1) - float(t0)) / float(hz) / (float(w1) - float(w0))
    frames = sum(l["frames"] for l in locs)
    late = sum(l["late_frames"] for l in locs)
    tracked = sum(l["tracked"] for l in locs)
    p50 = max(l["tracking_ms"]["p50"] for l in locs)
    p95 = max(l["tracking_ms"]["p95"] for l in locs)
    fps = sum(l["fps"] for l in locs) / len(locs)
    print(f"| {n} | {m['fps']:.1f} | {m['late_frames']} / {m['frames']} | {m['tracking_ms']['p50']:.1f} / {m['tracking_ms']['p95']:.1f} "
          f"| {fps:.1f} | {late} / {frames} | {tracked / max(frames, 1):.3f} | {p50:.1f} / {p95:.1f} (worst) | {cores:.2f} |")
PY
fi

joint_ate() {  # joint_ate PREFIX SEQ...: per map the sessions end in, one alignment for all of them
  local prefix=$1
  shift
  /usr/bin/python3 - "$OA" "$prefix" "$OUT" "$SECONDS_PER_SESSION" "$@" <<'PY'
import json, subprocess, sys
oa, prefix, out, secs, seqs = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4], sys.argv[5:]
groups = {}
for s in seqs:
    maps = sorted({l.split()[2] for l in open(f"{prefix}_{s}.txt") if l.startswith("# map")})
    groups.setdefault(",".join(maps), []).append(s)
parts = []
for maps, members in sorted(groups.items()):
    args = [oa, "eval", "--align", "se3", "--json"]
    for s in members:
        args += ["--gt", f"{out}/clips/{s}_{secs}", "--est", f"{prefix}_{s}.txt"]
    ate = json.loads(subprocess.run(args, check=True, capture_output=True, text=True).stdout)["ate_rmse_m"]
    parts.append(f"{'+'.join(members)} (map {maps}) {ate:.4f} m")
print("; ".join(parts))
PY
}

for K in "${MAPPERS[@]}"; do
  SEQS=(MH_01 MH_02 MH_03)
  SEQS=("${SEQS[@]:0:$K}")
  echo "== $K mapping sessions in one place at once (${SEQS[*]}, ${SECONDS_PER_SESSION} s, 20 Hz)"
  rm -rf "$OUT"/together.db* "$OUT"/together_*
  start_server "$OUT/together.db"
  PIDS=()
  for s in "${SEQS[@]}"; do
    "$OA" stream --dataset "$(clip "$s")" --name "$s" --mode map --rate 1 --no-progress \
      --stats "$OUT/together_$s.json" --out-trajectory "$OUT/together_$s.txt" > /dev/null &
    PIDS+=($!)
  done
  for P in "${PIDS[@]}"; do wait "$P"; done
  together_maps=$(count_maps)
  stop_server
  echo "== the same $K sessions built apart (one after another, each its own map) and merged"
  rm -rf "$OUT"/apart.db* "$OUT"/apart_*
  start_server "$OUT/apart.db" --no-join-at-start --no-live-merging
  for s in "${SEQS[@]}"; do
    "$OA" stream --dataset "$(clip "$s")" --name "$s" --mode map --rate 1 --no-progress \
      --stats "$OUT/apart_$s.json" > /dev/null
  done
  # The last session's map goes to the merging worker when the session ends: wait for it.
  for _ in $(seq 1 600); do
    [ "$(curl -s "$ORBATLAS_SERVER/v1/merges" | /usr/bin/python3 -c 'import json,sys; print(json.load(sys.stdin)["pending"])')" = 0 ] && break
    sleep 0.2
  done
  for s in "${SEQS[@]}"; do
    id=$(/usr/bin/python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["session"])' "$OUT/apart_$s.json")
    "$OA" trajectory --session "$id" --out "$OUT/apart_$s.txt" > /dev/null
  done
  apart_maps=$(count_maps)
  stop_server
  /usr/bin/python3 - "$OUT" "${SEQS[@]}" <<'PY'
import json, sys
out, seqs = sys.argv[1], sys.argv[2:]
for kind in ("together", "apart"):
    rows = [json.load(open(f"{out}/{kind}_{s}.json")) for s in seqs]
    print(f"{kind}: " + "; ".join(
        f"{s} {r['keyframes']} keyframes, {r['fps']:.1f} frames/s, late {r['late_frames']}/{r['frames']}, ATE alone {r.get('ate_rmse_m', float('nan')):.4f} m"
        for s, r in zip(seqs, rows)))
PY
  echo "together: maps at the end $together_maps; joint ATE per map: $(joint_ate "$OUT/together" "${SEQS[@]}")"
  echo "apart:    maps at the end $apart_maps; joint ATE per map: $(joint_ate "$OUT/apart" "${SEQS[@]}")"
done
