#!/usr/bin/env bash
# The main job on its embedded default: build, render two Machine Hall sessions
# along the real MH_01 and MH_02 trajectories, start the map server on a fresh
# atlas, stream both sessions to it over HTTP, list the maps, print each session's
# ATE against the ground truth, restart the server to show the atlas persisted,
# localise a single image against it, and score the reference system's
# (ORB-SLAM3) real MH_01 output with the same evaluator. Outputs go to out/demo/.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh"
BUILD_DIR="${ORBATLAS_BUILD_DIR:-$ROOT/build}"
OA="$BUILD_DIR/client/orbatlas"
SERVER="$BUILD_DIR/server/orbatlas-server"
OUT="$ROOT/out/demo"
rm -rf "$OUT" && mkdir -p "$OUT"
GT="$ROOT/data/euroc/groundtruth/MH_01_easy.txt.gz"
SERVER_PID=""
stop_server() {
  if [ -n "$SERVER_PID" ] && kill -0 "$SERVER_PID" 2>/dev/null; then
    kill -TERM "$SERVER_PID" && wait "$SERVER_PID" || true
  fi
  SERVER_PID=""
}
trap stop_server EXIT
start_server() {
  rm -f "$OUT/port"
  "$SERVER" --db "$OUT/atlas.db" --listen 127.0.0.1:0 --port-file "$OUT/port" 2>>"$OUT/server.log" &
  SERVER_PID=$!
  for _ in $(seq 1 300); do [ -s "$OUT/port" ] && break; sleep 0.1; done
  [ -s "$OUT/port" ] || { echo "the server did not start; see $OUT/server.log"; exit 1; }
  export ORBATLAS_SERVER="http://127.0.0.1:$(cat "$OUT/port")"
  echo "   server $ORBATLAS_SERVER (pid $SERVER_PID, log $OUT/server.log)"
}

echo "== 1. Simulate two sessions: 20 s of MH_01 and 20 s of MH_02 (stereo + IMU + ground truth, EuRoC ASL)"
"$OA" sim --sequence MH_01 --start 40 --duration 20 --out "$OUT/MH_01_clip"
"$OA" sim --sequence MH_02 --start 30 --duration 20 --out "$OUT/MH_02_clip"

echo "== 2. Start the map server on a fresh atlas ($OUT/atlas.db)"
start_server

echo "== 3. Stream both sessions over HTTP (tracking, local mapping and loop closing in the server)"
"$OA" stream --dataset "$OUT/MH_01_clip" --name MH_01 --stats "$OUT/session_MH_01.json" \
     --out-trajectory "$OUT/session_MH_01.txt"
"$OA" stream --dataset "$OUT/MH_02_clip" --name MH_02 --stats "$OUT/session_MH_02.json" \
     --out-trajectory "$OUT/session_MH_02.txt"

echo "== 4. One map for both sessions: they cross the same part of the hall. A new session's first frame is"
echo "      looked up in the stored maps (recognised: it tracks in that map from the start); otherwise its"
echo "      own map is merged into the other live, once a keyframe recognises the shared place, or by the"
echo "      server-wide merging worker when it finishes (then global BA)"
"$OA" merges --wait 600
"$OA" sessions
"$OA" maps

echo "== 5. Restart the server: the atlas is still there; localise one image of MH_01 against it"
stop_server
start_server
"$OA" maps
FRAME="$(ls "$OUT/MH_01_clip/mav0/cam0/data" | sed -n 150p)"
"$OA" localize --config euroc/stereo --server "$ORBATLAS_SERVER" --image "$OUT/MH_01_clip/mav0/cam0/data/$FRAME"
for S in MH_01 MH_02; do
  ID="$(sed -n 's/^  "session": \([0-9]*\),*$/\1/p' "$OUT/session_$S.json")"
  "$OA" trajectory --session "$ID" --out "$OUT/session_${S}_merged.txt"
done
stop_server

echo "== 6. Each session's ATE (orbatlas eval against the clip's ground truth)"
for S in MH_01 MH_02; do
  echo "-- $S"
  "$OA" eval --gt "$OUT/${S}_clip" --est "$OUT/session_${S}_merged.txt" --align se3 --plot "$OUT/session_${S}_top_view.png"
done
echo "-- both sessions together, under ONE alignment (the ground truths share a world frame: this"
echo "   measures how well the merge put the two sessions into one map)"
"$OA" eval --gt "$OUT/MH_01_clip" --gt "$OUT/MH_02_clip" --est "$OUT/session_MH_01_merged.txt" \
     --est "$OUT/session_MH_02_merged.txt" --align se3 --plot "$OUT/sessions_joint_top_view.png"

echo "== 7. ORB-SLAM3 v1.0 monocular-inertial on real MH_01, scored by the same evaluator"
"$OA" eval --gt "$GT" --est "$ROOT/data/euroc/peer_trajectories/orbslam3_MH01_monoi_frames.txt.gz" \
     --align se3 --plot "$OUT/orbslam3_MH01_top_view.png"

echo "Done: outputs in $OUT"
