#!/usr/bin/env bash
# CI stage: cross-build for aarch64, run the test suite under qemu-aarch64, and check that the 2D
# tracker's output on a fixed synthetic clip, read from a frame directory, is bit-identical on
# x86-64 and aarch64 (.ci/cross_common.sh). Needs the native build of tools/test.sh.
#   EPITRACK_BUILD_DIR   native build directory (default build/test)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
native=${EPITRACK_BUILD_DIR:-$root/build/test}
cross=$root/build/cross-aarch64

# The core suite under emulation: image core (algo), frame sources and codecs (hal), geometry
# solvers, the allocation tests (zero allocation per frame, including the 500-frame device loop),
# the solver (sfm) and the LK kernels' bit-exactness against scalar (simd, NEON expected). Test
# scenes are bit-identical on both machines (one random draw per statement,
# tests/support/seeded_random.hpp), so the same tolerances hold. Measured under
# qemu-aarch64 (CPU seconds): algo 2, alloc 84, geometry+sfm about 290.
# Left out: the tracker, device, tools, render and export labels, whose tests run the commands
# (rendering clips with epitrack-synth under emulation takes about 0.5 s a frame, far too slow for
# CI; in-process rendering, as in the allocation tests, is fine); the tracker's bit-exactness is
# checked below on a clip rendered natively.
# Also left out, for the CI budget: the slow tier (tests tagged [slow], e.g. the solver's
# whole-clip accuracy sweeps, 50-110 s each under qemu); they run natively in the test stage. Only the programs and the test binaries of these labels are built (the other test
# binaries would be a third of the build); ctest ignores the unbuilt ones under -L.
# --timeout: a test that hangs under emulation fails the stage instead of stalling it.
source "$root/.ci/cross_common.sh"
EPITRACK_BUILD_TARGETS="epitrack-device epitrack-solve epitrack-synth epitrack-track epitrack-record
  epitrack-eval epitrack_algo_tests epitrack_alloc_tests epitrack_geometry_tests epitrack_hal_tests
  epitrack_hal_alloc_tests epitrack_sfm_tests epitrack_lk_kernels_tests" \
  EPITRACK_EXPECT_LK_ISA=neon \
  EPITRACK_CTEST_ARGS="--timeout 900 -L ^(algo|hal|geometry|alloc|sfm|simd)$ -LE slow ${EPITRACK_CTEST_ARGS:-}" \
  bash "$root/tools/cross.sh" aarch64 "$cross" --test

clip=$root/build/ci-digest-aarch64
render_digest_clip "$native" "$clip"
emulator=$(target_emulator "$cross")
# shellcheck disable=SC2086 # the emulator prefix is a word list
check_tracks_bit_exact aarch64 "$clip" $emulator "$cross/tools/track/epitrack-track"
