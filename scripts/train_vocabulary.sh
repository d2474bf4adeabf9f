#!/usr/bin/env bash
# Reproduces the shipped vocabulary data/vocabulary/orbatlas_k10_l5.vocab:
# renders sparse Machine Hall / V1_01 sessions with scene seeds the tests never
# use, adds the real EuRoC frames of ../shared (when present) and Debian's
# opencv-doc sample photographs, and trains k=10, L=5. Takes ~10 minutes on 2 cores.
# Usage: scripts/train_vocabulary.sh [OUT_FILE] [WORK_DIR]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="${1:-$ROOT/data/vocabulary/orbatlas_k10_l5.vocab}"
WORK="${2:-/tmp/orbatlas_vocab_corpus}"
"$ROOT/scripts/setup.sh"
OA="${ORBATLAS_BUILD_DIR:-$ROOT/build}/client/orbatlas"

if ! dpkg-query -W -f='${Status}' opencv-doc 2>/dev/null | grep -q "install ok installed"; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -q opencv-doc
fi

mkdir -p "$WORK"
render() {  # seed sequence every
  local dir="$WORK/seed$1_$2"
  [ -d "$dir/mav0" ] || "$OA" sim --scene-seed "$1" --sequence "$2" --every "$3" --out "$dir"
  echo "$dir"
}
DIRS=("$(render 101 MH_01 10)" "$(render 102 MH_03 8)" "$(render 103 MH_05 7)" "$(render 104 V1_01 10)")
DIRS+=(/usr/share/doc/opencv-doc/examples/data)
SHARED="$ROOT/../shared/data/euroc"
if [ -d "$SHARED" ]; then
  DIRS+=("$SHARED/V1_01_micro" "$SHARED/extra_images/loop_closure_V2_room" "$SHARED/extra_images/stereo_frame")
else
  echo "note: $SHARED not found; training without the real EuRoC frames" >&2
fi
mkdir -p "$(dirname "$OUT")"
"$OA" vocab train --images "${DIRS[@]}" --k 10 --levels 5 --features 1000 --seed 1 --out "$OUT"
"$OA" vocab info "$OUT"
