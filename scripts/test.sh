#!/usr/bin/env bash
# The test command: installs what is missing, builds, runs the whole GTest suite.
# Tests that need the real EuRoC data in ../shared/data/euroc skip (with a
# message) when it is absent.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh"
BUILD_DIR="${ORBATLAS_BUILD_DIR:-$ROOT/build}"
cd "$BUILD_DIR"
ctest --output-on-failure -j "${ORBATLAS_JOBS:-$(nproc)}" "$@"
