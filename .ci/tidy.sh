#!/usr/bin/env bash
# CI stage: the code's form. Fails on the first of:
#   1. clang-format: every C++ file of algo/ hal/ firmware_like/ tools/ tests/ (the layering
#      fixtures aside) must be formatted as .clang-format says (clang-format --dry-run --Werror);
#   2. clang-tidy: every translation unit of algo/ hal/ firmware_like/ tools/ (and the project
#      headers they include) with the check set of .clang-tidy, every warning an error. It reads
#      the compile commands of a configure-only build with clang (nothing is compiled), so it needs
#      no other stage.
#   EPITRACK_TIDY_BUILD_DIR  where the compile commands are configured (default build/tidy)
#   EPITRACK_JOBS            parallel clang-tidy processes (default: number of cores)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${EPITRACK_TIDY_BUILD_DIR:-$root/build/tidy}
jobs=${EPITRACK_JOBS:-$(nproc)}
cd "$root"

"$root/tools/deps.sh" base tidy

t0=$SECONDS
mapfile -t sources < <(git ls-files -- 'algo/*' 'hal/*' 'firmware_like/*' 'tools/*' 'tests/*' |
  grep -E '\.(c|cpp|h|hpp)$' | grep -v '^tests/layering/violating_tree/')
echo "tidy: clang-format --dry-run --Werror over ${#sources[@]} files"
if ! clang-format --dry-run --Werror "${sources[@]}"; then
  echo "tidy: files above are not formatted: run clang-format -i on them" >&2
  exit 1
fi
echo "tidy: clang-format passed in $((SECONDS - t0)) s"

t1=$SECONDS
# Compile commands from clang (clang-tidy is clang: GCC's own warning flags would be unknown to it);
# the tests are left out of the configure (they are not checked).
CC=clang CXX=clang++ cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release \
  -DEPITRACK_BUILD_TESTS=OFF -DEPITRACK_BUILD_BENCH=ON -DEPITRACK_CCACHE=OFF -DEPITRACK_PCH=OFF \
  -DCMAKE_EXPORT_COMPILE_COMMANDS=ON >/dev/null
units=$(python3 -c '
import json, sys
for c in json.load(open(sys.argv[1])):
    print(c["file"])' "$build/compile_commands.json" |
  grep -E "^$root/(algo|hal|firmware_like|tools)/" | sort -u)
echo "tidy: clang-tidy over $(echo "$units" | wc -l) translation units, $jobs at a time"
# run-clang-tidy: one clang-tidy per unit, in parallel; the checks and options are .clang-tidy's.
# shellcheck disable=SC2086 # one file name per word
if ! run-clang-tidy -quiet -p "$build" -j "$jobs" $units \
  >"$build/clang-tidy.log" 2>&1; then
  grep -E 'warning:|error:' "$build/clang-tidy.log" | sort -u >&2 || cat "$build/clang-tidy.log" >&2
  echo "tidy: clang-tidy found the problems above (full log: $build/clang-tidy.log)" >&2
  exit 1
fi
echo "tidy: clang-tidy passed in $((SECONDS - t1)) s"
