#!/usr/bin/env bash
# Reproduces the shipped vocabulary data/vocabulary/orbatlas_k10_l5.vocab:
# renders sparse Machine Hall / V1_01 sessions with scene seeds the tests never
# use (the clean simulator look), adds the real EuRoC frames of ../shared (when
# present) and Debian's opencv-doc sample photographs, and trains k=10, L=5.
# Takes ~10 minutes on 2 cores.
# Usage: scripts/train_vocabulary.sh [OUT_FILE] [WORK_DIR]
#   LOOKS="clean real" HOLD_OUT_V2=1 scripts/train_vocabulary.sh /tmp/both.vocab
#     renders both simulator looks and keeps the two real V2 loop-closure pairs
#     out of the corpus (the candidate compared in docs/vocabulary.md; not shipped).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="${1:-$ROOT/data/vocabulary/orbatlas_k10_l5.vocab}"
WORK="${2:-/tmp/orbatlas_vocab_corpus}"
"$ROOT/scripts/setup.sh"
OA="${ORBATLAS_BIN:-${ORBATLAS_BUILD_DIR:-$ROOT/build}/client/orbatlas}"
read -r -a LOOK_LIST <<< "${LOOKS:-clean}"

if ! dpkg-query -W -f='${Status}' opencv-doc 2>/dev/null | grep -q "install ok installed"; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -q opencv-doc
fi

mkdir -p "$WORK"
render() {  # seed sequence every look
  local dir="$WORK/seed$1_$2_$4"
  [ "$4" = clean ] && dir="$WORK/seed$1_$2"  # the shipped vocabulary's corpus folders
  [ -d "$dir/mav0" ] || "$OA" sim --scene-seed "$1" --sequence "$2" --every "$3" --look "$4" --out "$dir" >&2
  echo "$dir"
}
DIRS=()
for look in "${LOOK_LIST[@]}"; do
  DIRS+=("$(render 101 MH_01 10 "$look")" "$(render 102 MH_03 8 "$look")" "$(render 103 MH_05 7 "$look")"
         "$(render 104 V1_01 10 "$look")")
done
DIRS+=(/usr/share/doc/opencv-doc/examples/data)
SHARED="$ROOT/../shared/data/euroc"
if [ -d "$SHARED" ]; then
  DIRS+=("$SHARED/V1_01_micro")
  [ "${HOLD_OUT_V2:-0}" = "1" ] || DIRS+=("$SHARED/extra_images/loop_closure_V2_room")
  DIRS+=("$SHARED/extra_images/stereo_frame")
else
  echo "note: $SHARED not found; training without the real EuRoC frames" >&2
fi
mkdir -p "$(dirname "$OUT")"
"$OA" vocab train --images "${DIRS[@]}" --k 10 --levels 5 --features 1000 --seed 1 --out "$OUT"
"$OA" vocab info "$OUT"
