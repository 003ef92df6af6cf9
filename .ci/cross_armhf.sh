#!/usr/bin/env bash
# CI stage: cross-build for 32-bit ARM (armhf: ARMv7, hard float), run the core suite under
# qemu-arm, run the LK kernels' tests on an ARMv7 without NEON as well (the run-time choice's other
# branch), and check that the 2D tracker's output from a frame directory is bit-identical on x86-64
# and armhf, with NEON and without (.ci/cross_common.sh). Needs the native build of tools/test.sh.
#   EPITRACK_BUILD_DIR   native build directory (default build/test)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
native=${EPITRACK_BUILD_DIR:-$root/build/test}
cross=$root/build/cross-armhf
source "$root/.ci/cross_common.sh"

# What 32-bit changes, under emulation: the image core (algo), the frame sources, codecs and file
# errors with 32-bit size_t and 64-bit off_t/time_t (hal, including its allocation tests and the
# platform ABI checks), and the LK kernels against scalar (simd: qemu-arm's default CPU has NEON,
# so the ARMv7 NEON kernels). The solver (geometry, sfm) is left to the aarch64 stage: it holds no
# file offsets or sizes, and its doubles round the same on both ARM targets (IEEE, no FMA
# contraction), so here it would only add minutes of emulation to the CI budget. Only these
# programs and test binaries are built (the whole build is tools/cross.sh armhf without targets).
# The target's libraries are unpacked from Debian packages (tools/cross_libs.sh) rather than
# installed through multiarch: the aarch64 stage covers multiarch, this one the other way, and it
# does not depend on the mirror serving the target's security updates (it did not, 2026-12-06).
EPITRACK_CROSS_LIBS=download EPITRACK_BUILD_TARGETS="epitrack-track epitrack_algo_tests epitrack_hal_tests
  epitrack_hal_alloc_tests epitrack_lk_kernels_tests" \
  EPITRACK_EXPECT_LK_ISA=neon \
  EPITRACK_CTEST_ARGS="--timeout 600 -L ^(algo|hal|simd)$ -LE slow ${EPITRACK_CTEST_ARGS:-}" \
  bash "$root/tools/cross.sh" armhf "$cross" --test

emulator=$(target_emulator "$cross")
# An ARMv7 without NEON (a Cortex-A9 configured without it, as NVIDIA's Tegra 2): the kernel's
# AT_HWCAP has no NEON there, so the scalar kernels must be chosen, and a NEON instruction would
# stop the program with SIGILL.
no_neon="${emulator%% *} -cpu cortex-a9,neon=off ${emulator#* }"
echo "LK kernel tests on an ARMv7 without NEON:"
# shellcheck disable=SC2086 # the emulator prefix is a word list
EPITRACK_EXPECT_LK_ISA=scalar $no_neon "$cross/tests/tracker/epitrack_lk_kernels_tests"

clip=$root/build/ci-digest-armhf
render_digest_clip "$native" "$clip"
# shellcheck disable=SC2086
check_tracks_bit_exact armhf "$clip" $emulator "$cross/tools/track/epitrack-track"
# shellcheck disable=SC2086
check_tracks_bit_exact armhf-without-neon "$clip" $no_neon "$cross/tools/track/epitrack-track"
