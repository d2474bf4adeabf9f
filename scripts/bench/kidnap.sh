#!/usr/bin/env bash
# Long benchmark (not part of the test suite): relocalisation after a kidnapping on
# full-length simulated sequences. For each sequence: a run with 3 s of frames
# removed (from 60 s), and one with 2 s of frames from another part of the hall
# spliced in (from 60 s, the frames of 30 s on). Prints how many frames after the
# window tracking needed to relocalise (goal: within 10) and the ATE without the
# window's frames (goal: <= 0.03 m). A run that cannot relocalise for 5 frames
# starts a new map and merges it back live: the maps/merges line says when. Also
# prints the frames tracked outside the window and the coverage.
#   scripts/bench/kidnap.sh [MH_01 ...]      (data: $ORBATLAS_BENCH_DATA, as scripts/bench/slam.sh)
#   LOOKS=real scripts/bench/kidnap.sh        (default: both simulator looks, clean and real)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
"$ROOT/scripts/setup.sh"
BUILD_DIR="${ORBATLAS_BUILD_DIR:-$ROOT/build}"
OA="$BUILD_DIR/client/orbatlas"
DATA="${ORBATLAS_BENCH_DATA:-$BUILD_DIR/bench_data}"
OUT="$ROOT/out/bench_kidnap"
mkdir -p "$DATA" "$OUT"
SEQUENCES=("$@")
[ ${#SEQUENCES[@]} -eq 0 ] && SEQUENCES=(MH_01 MH_02 MH_03 MH_04 MH_05)
read -r -a LOOK_LIST <<< "${LOOKS:-clean real}"

for look in "${LOOK_LIST[@]}"; do
for s in "${SEQUENCES[@]}"; do
  src="$DATA/$s"
  [ "$look" = clean ] || src="$DATA/${s}_$look"
  if [ ! -f "$src/mav0/cam1/data.csv" ]; then
    rm -rf "$src"
    "$OA" sim --sequence "$s" --look "$look" --out "$src"
  fi
  for mode in remove splice; do
    d="$OUT/${s}_${look}_$mode"
    rm -rf "$d"
    if [ $mode = remove ]; then
      /usr/bin/python3 "$ROOT/scripts/analysis/kidnap_dataset.py" "$src" "$d" remove 60 3
    else
      /usr/bin/python3 "$ROOT/scripts/analysis/kidnap_dataset.py" "$src" "$d" splice 60 2 30
    fi
    echo "== $s ($look look), $mode"
    "$OA" run --config "$ROOT/config/euroc/stereo.yaml" --dataset "$d" --out-trajectory "$d.txt" \
        --stats "$d.json" --no-progress | tail -n 4
    /usr/bin/python3 - "$d" <<'PY'
import bisect, json, sys
d = sys.argv[1]
k = json.load(open(f"{d}/kidnap.json"))
w0, w1 = k["window_start_ns"], k["window_end_ns"]
frames = [int(l.split(',')[0]) for l in open(f"{d}/mav0/cam0/data.csv") if l[0] != '#']
poses = sorted(int(round(float(l.split()[0]) * 1e9)) for l in open(f"{d}.txt") if l[0] != '#')
def is_tracked(t):  # TUM seconds lose a few hundred ns: match within 1 ms
    i = bisect.bisect_left(poses, t - 1_000_000)
    return i < len(poses) and abs(poses[i] - t) <= 1_000_000
after = [t for t in frames if t >= w1]
n = next((i for i, t in enumerate(after) if is_tracked(t)), None)
outside = [t for t in frames if not (w0 <= t < w1)]
print(f"tracked {sum(1 for t in outside if is_tracked(t))} of {len(outside)} frames outside the window")
with open(f"{d}.outside.txt", "w") as f:
    for l in open(f"{d}.txt"):
        if l[0] == '#' or not (w0 <= int(round(float(l.split()[0]) * 1e9)) < w1):
            f.write(l)
print(f"frames after the window before the first tracked one: {n} (goal <= 10)")
st = json.load(open(f"{d}.json"))
line = f"maps at the end {st['maps']}, started {st.get('maps_started', 1)}, relocalisations {st['relocalizations']}"
for m in st.get("loop_closing", {}).get("live_merges", []):
    t = int(round(m["keyframe_t_s"] * 1e9))
    line += (f"; map {m['source_map']} merged live into {m['target_map']} "
             f"{sum(1 for x in after if x <= t)} frames after the window ({m['matches']} matches)")
print(line)
PY
    "$OA" eval --gt "$src" --est "$d.outside.txt" --align se3 | grep -iE "ate|coverage" | head -n 3
  done
done
done
