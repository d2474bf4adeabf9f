#!/usr/bin/env bash
# The test command: installs what is missing, builds, runs the whole GTest suite.
# Tests that need the real EuRoC data in ../shared/data/euroc skip (with a
# message) when it is absent.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# The project's own compiler warnings are errors here (and so in CI).
ORBATLAS_WERROR=ON "$ROOT/scripts/setup.sh"
BUILD_DIR="${ORBATLAS_BUILD_DIR:-$ROOT/build}"
cd "$BUILD_DIR"
ctest --output-on-failure -j "${ORBATLAS_JOBS:-$(nproc)}" "$@"
