#!/usr/bin/env bash
# CI stage: cross-build for aarch64, run the test suite under qemu-aarch64, and check that the 2D
# tracker's output on a fixed synthetic clip is bit-identical on x86-64 and aarch64 (a recording
# debugged on a desktop behaves the same on the board). Needs the native build of tools/test.sh.
#   EPITRACK_BUILD_DIR   native build directory (default build/test)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
native=${EPITRACK_BUILD_DIR:-$root/build/test}
cross=$root/build/cross-aarch64

# The core suite under emulation: image core (algo), frame sources and codecs (hal), geometry
# solvers, the allocation tests (zero allocation per frame, including the 500-frame device loop)
# and the solver (sfm). Test scenes are bit-identical on both machines (one random draw per
# statement, tests/support/seeded_random.hpp), so the same tolerances hold. Measured under
# qemu-aarch64 (CPU seconds): algo 2, alloc 84, geometry+sfm about 290.
# Left out: the tracker, device, tools, render and export labels, whose tests run the commands
# (rendering clips with epitrack-synth under emulation takes about 0.5 s a frame, far too slow for
# CI; in-process rendering, as in the allocation tests, is fine); the tracker's bit-exactness is
# checked below on a clip rendered natively.
# Also left out, for the CI budget: the slow tier (tests tagged [slow], e.g. the solver's
# whole-clip accuracy sweeps, 50-110 s each under qemu); they run natively in the test stage. Only the programs and the test binaries of these labels are built (the other test
# binaries would be a third of the build); ctest ignores the unbuilt ones under -L.
# --timeout: a test that hangs under emulation fails the stage instead of stalling it.
EPITRACK_BUILD_TARGETS="epitrack-device epitrack-solve epitrack-synth epitrack-track epitrack-record
  epitrack-eval epitrack_algo_tests epitrack_alloc_tests epitrack_geometry_tests epitrack_hal_tests
  epitrack_hal_alloc_tests epitrack_sfm_tests" \
  EPITRACK_CTEST_ARGS="--timeout 900 -L ^(algo|hal|geometry|alloc|sfm)$ -LE slow ${EPITRACK_CTEST_ARGS:-}" \
  bash "$root/tools/cross.sh" aarch64 "$cross" --test

clip=$root/build/ci-digest
rm -rf "$clip"
"$native/tools/synth/epitrack-synth" --scene handheld --frames 60 --size 704x576 --noise 2 --seed 11 \
  --out "$clip" >/dev/null
"$native/tools/track/epitrack-track" "$clip/frames" --out "$clip/tracks-x86_64.csv" --quiet
# The toolchain's emulator command (qemu with the cross loader and its own libc, see
# toolchains/linux-cross-common.cmake), as ctest uses it.
emulator=$(sed -n 's/^EPITRACK_TARGET_EMULATOR:INTERNAL=//p' "$cross/CMakeCache.txt" | tr ';' ' ')
[ -n "$emulator" ] || { echo "cross_aarch64: no emulator in $cross/CMakeCache.txt" >&2; exit 1; }
$emulator "$cross/tools/track/epitrack-track" "$clip/frames" \
  --out "$clip/tracks-aarch64.csv" --quiet
a=$(sha256sum <"$clip/tracks-x86_64.csv" | cut -d' ' -f1)
b=$(sha256sum <"$clip/tracks-aarch64.csv" | cut -d' ' -f1)
rows=$(($(wc -l <"$clip/tracks-x86_64.csv") - 1))
echo "tracks.csv digest: x86-64 $a, aarch64 $b ($rows rows)"
if [ "$a" != "$b" ]; then
  echo "cross_aarch64: the tracker's output differs between x86-64 and aarch64" >&2
  diff "$clip/tracks-x86_64.csv" "$clip/tracks-aarch64.csv" | head -20 >&2
  exit 1
fi
[ "$rows" -gt 1000 ] || { echo "cross_aarch64: too few tracked rows ($rows)" >&2; exit 1; }
echo "cross_aarch64: bit-exact"
