#!/usr/bin/env bash
# Cross-builds epitrack for an ARM Linux board with Debian's cross compilers and multiarch target
# libraries (installed here when missing), and optionally runs the core test suite under qemu-user.
#   tools/cross.sh aarch64|armhf [BUILD_DIR] [--test]
#   EPITRACK_JOBS        parallel jobs (default: number of cores)
#   EPITRACK_CMAKE_ARGS  extra configure arguments (e.g. -DEPITRACK_CPU_FLAGS_FILE=toolchains/cpu/cortex-a72.cmake)
#   EPITRACK_CTEST_ARGS  extra ctest arguments for --test (e.g. -L algo)
#   EPITRACK_BUILD_TARGETS  targets to build, space-separated (default: all)
#   EPITRACK_CROSS_LIBS  where the target's libjpeg-turbo and libpng come from: multiarch (installed
#                        with apt), download (unpacked into BUILD_DIR/target-libs by
#                        tools/cross_libs.sh, no version coupling to the build machine), or auto
#                        (default: multiarch, download when the multiarch install fails)
# The build is Release with warnings as errors, tests on, the benchmark off (no OpenCV on the target).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

usage() { echo "usage: tools/cross.sh aarch64|armhf [BUILD_DIR] [--test]" >&2; exit 2; }
[ $# -ge 1 ] || usage
arch=$1; shift
case "$arch" in
  aarch64) triple=aarch64-linux-gnu; group=cross-aarch64 ;;
  armhf) triple=arm-linux-gnueabihf; group=cross-armhf ;;
  -h|--help) sed -n '2,13p' "${BASH_SOURCE[0]}"; exit 0 ;;
  *) echo "cross.sh: unknown architecture '$arch' (aarch64 or armhf)" >&2; exit 2 ;;
esac
build=""
run_tests=0
for a in "$@"; do
  case "$a" in
    --test) run_tests=1 ;;
    -*) echo "cross.sh: unknown option '$a'" >&2; exit 2 ;;
    *) [ -z "$build" ] || usage; build=$a ;;
  esac
done
build=${build:-$root/build/cross-$arch}
jobs=${EPITRACK_JOBS:-$(nproc)}

"$root/tools/deps.sh" base "$group-tools"
libs=${EPITRACK_CROSS_LIBS:-auto}
target_libs=""
case "$libs" in
  multiarch) "$root/tools/deps.sh" "$group" ;;
  download) target_libs=$build/target-libs ;;
  auto)
    if ! "$root/tools/deps.sh" "$group"; then
      echo "cross.sh: the multiarch install failed; unpacking the target's libraries instead" >&2
      target_libs=$build/target-libs
    fi
    ;;
  *) echo "cross.sh: EPITRACK_CROSS_LIBS must be multiarch, download or auto, not '$libs'" >&2; exit 2 ;;
esac
if [ -n "$target_libs" ]; then "$root/tools/cross_libs.sh" "$arch" "$target_libs"; fi

cmake -S "$root" -B "$build" -DCMAKE_TOOLCHAIN_FILE="$root/toolchains/$triple.cmake" \
  -DCMAKE_BUILD_TYPE=Release -DEPITRACK_WERROR=ON -DEPITRACK_BUILD_TESTS=ON -DEPITRACK_BUILD_BENCH=OFF \
  -DEPITRACK_TARGET_LIBS="$target_libs" ${EPITRACK_CMAKE_ARGS:-} >/dev/null
targets=()
for t in ${EPITRACK_BUILD_TARGETS:-}; do targets+=(--target "$t"); done
cmake --build "$build" -j "$jobs" "${targets[@]}"
echo "cross.sh: built $triple in $build"

if [ "$run_tests" = 1 ]; then
  # Target binaries (and the commands the tests spawn) run through qemu-user with the multiarch
  # loader prefix; the toolchain file sets CMAKE_CROSSCOMPILING_EMULATOR for ctest.
  ctest --test-dir "$build" -j "$jobs" --output-on-failure ${EPITRACK_CTEST_ARGS:-}
fi
