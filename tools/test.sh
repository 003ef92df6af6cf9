#!/usr/bin/env bash
# The README's test command: installs missing packages, builds (warnings are errors) and runs the
# whole native test suite with ctest. Tests that need ../shared/data skip visibly without it.
#   EPITRACK_BUILD_DIR   build directory (default build/test)
#   EPITRACK_JOBS        parallel build and test jobs (default: number of cores)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${EPITRACK_BUILD_DIR:-$root/build/test}
jobs=${EPITRACK_JOBS:-$(nproc)}

"$root/tools/deps.sh" base

cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release -DEPITRACK_WERROR=ON -DEPITRACK_BUILD_TESTS=ON \
  ${EPITRACK_CMAKE_ARGS:-} >/dev/null
cmake --build "$build" -j "$jobs"

if [ ! -d "$root/../shared/data" ] && [ -z "${EPITRACK_SHARED_DATA:-}" ]; then
  echo "test.sh: ../shared/data not found: tests on the real sequences will be reported as skipped"
fi
ctest --test-dir "$build" -j "$jobs" --output-on-failure ${EPITRACK_CTEST_ARGS:-}
