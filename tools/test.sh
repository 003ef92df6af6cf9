#!/usr/bin/env bash
# The README's test command: installs missing packages, builds (warnings are errors) and runs the
# native test suite with ctest. Tests that need ../shared/data skip visibly without it.
#   tools/test.sh          the default tier: unit and short tests (everything not labelled slow)
#   tools/test.sh --all    every test, the slow tier too (whole-clip solves, sweeps, real
#                          programs); CI runs this
#   EPITRACK_BUILD_DIR   build directory (default build/test)
#   EPITRACK_JOBS        parallel build and test jobs (default: number of cores)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${EPITRACK_BUILD_DIR:-$root/build/test}
jobs=${EPITRACK_JOBS:-$(nproc)}
tier=(-LE slow)
case "${1:-}" in
  "") ;;
  --all) tier=() ;;
  *)
    echo "test.sh: unknown argument '$1' (usage: tools/test.sh [--all])" >&2
    exit 2
    ;;
esac

"$root/tools/deps.sh" base

cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release -DEPITRACK_WERROR=ON -DEPITRACK_BUILD_TESTS=ON \
  ${EPITRACK_CMAKE_ARGS:-} >/dev/null
cmake --build "$build" -j "$jobs"

if [ ! -d "$root/../shared/data" ] && [ -z "${EPITRACK_SHARED_DATA:-}" ]; then
  echo "test.sh: ../shared/data not found: tests on the real sequences will be reported as skipped"
fi
if [ ${#tier[@]} -gt 0 ]; then
  echo "test.sh: the default tier (tests labelled slow left out; tools/test.sh --all runs them)"
fi
ctest --test-dir "$build" -j "$jobs" --output-on-failure "${tier[@]}" ${EPITRACK_CTEST_ARGS:-}
