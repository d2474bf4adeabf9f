#!/usr/bin/env bash
# Installs the Debian packages orbatlas needs (when missing), then configures and
# builds it in build/ (Release). Sourced by demo.sh and test.sh; safe to re-run.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${ORBATLAS_BUILD_DIR:-$ROOT/build}"

PACKAGES=(build-essential cmake ninja-build pkg-config zlib1g-dev
          libeigen3-dev libopencv-dev libceres-dev libsqlite3-dev libcereal-dev
          libcpp-httplib-dev libgtest-dev libcli11-dev nlohmann-json3-dev libopengv-dev curl
          libarchive-dev prometheus-cpp-dev clang-format librosbag-dev libsensor-msgs-dev
          libjs-three chromium postgresql libpq-dev libssl-dev openssl)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "[setup] installing Debian packages: ${missing[*]}"
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { echo "[setup] need root (or sudo) to install: ${missing[*]}" >&2; exit 1; }
    SUDO="sudo"
  fi
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get update -q
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

# --deps-only: stop after the packages (scripts that configure their own build).
[ "${1:-}" = "--deps-only" ] && exit 0

JOBS="${ORBATLAS_JOBS:-$(nproc)}"
# ORBATLAS_WERROR=ON|OFF (the test command sets ON): the project's own compiler
# warnings are errors. Unset, a configured build keeps what it has.
werror=()
[ -n "${ORBATLAS_WERROR:-}" ] && werror=(-DORBATLAS_WERROR="$ORBATLAS_WERROR")
if [ ! -f "$BUILD_DIR/build.ninja" ]; then
  cmake -S "$ROOT" -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release "${werror[@]}"
elif ((${#werror[@]})) && ! grep -qx "ORBATLAS_WERROR:BOOL=$ORBATLAS_WERROR" "$BUILD_DIR/CMakeCache.txt"; then
  cmake -S "$ROOT" -B "$BUILD_DIR" "${werror[@]}"
fi
cmake --build "$BUILD_DIR" -j "$JOBS"
