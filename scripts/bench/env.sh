# Sourced by the long benchmarks (scripts/bench/: inertial.sh, rgbd.sh,
# mono.sh, ...) after they set ROOT and BENCH_NAME: the orbatlas binary
# (OA: $ORBATLAS_BIN, a frozen binary with no set-up and no build; else the
# README's set-up and build), the rendered sequences (DATA:
# $ORBATLAS_BENCH_DATA, default build/bench_data, shared by every benchmark)
# and the results folder (OUT: $ORBATLAS_BENCH_OUT, default out/$BENCH_NAME).
BUILD_DIR="${ORBATLAS_BUILD_DIR:-$ROOT/build}"
if [ -n "${ORBATLAS_BIN:-}" ]; then
  OA="$ORBATLAS_BIN"
else
  "$ROOT/scripts/setup.sh"
  OA="$BUILD_DIR/client/orbatlas"
fi
# The benchmarks' figures are computed with Debian's numpy (python3-numpy).
if ! /usr/bin/python3 -c "import numpy" 2> /dev/null; then
  echo "== installing python3-numpy (the benchmarks' figures)" >&2
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -q python3-numpy >&2
fi
DATA="${ORBATLAS_BENCH_DATA:-$BUILD_DIR/bench_data}"
OUT="${ORBATLAS_BENCH_OUT:-$ROOT/out/$BENCH_NAME}"
mkdir -p "$DATA" "$OUT"

# bench_dataset SEQ LOOK: the folder of the full rendered SEQ in LOOK (clean,
# real), rendered first when it is missing.
bench_dataset() {
  local seq=$1 look=$2 dir
  dir="$DATA/$seq"
  [ "$look" = clean ] || dir="$DATA/${seq}_$look"
  if [ ! -d "$dir/mav0" ]; then
    echo "== rendering $seq ($look look) into $dir" >&2
    "$OA" sim --sequence "$seq" --look "$look" --out "$dir" --no-progress >&2
  fi
  echo "$dir"
}
