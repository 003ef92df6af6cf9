#!/usr/bin/env bash
# Fuzzing: builds the libFuzzer targets of tests/fuzz (clang, ASan + UBSan, coverage of the code
# under test) into build/fuzz and runs each one for a bounded time on a fresh copy of its seed
# corpus (tests/fuzz/corpus/TARGET), with its dictionary when there is one. Fails when any target
# crashes, leaks, times out, runs out of memory or prints a sanitizer report. Prints, per target,
# the executions, libFuzzer's coverage (cov: edges, ft: features) and the corpus it grew.
#   EPITRACK_FUZZ_SECONDS    seconds per target (default 30)
#   EPITRACK_FUZZ_TARGETS    targets to run, space-separated (default: all of tests/fuzz/corpus)
#   EPITRACK_FUZZ_BUILD_DIR  build directory (default build/fuzz)
#   EPITRACK_FUZZ_RUN_DIR    where grown corpora, logs and crash files go (default BUILD/runs)
#   EPITRACK_JOBS            parallel build jobs and targets fuzzed at once (default 2)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${EPITRACK_FUZZ_BUILD_DIR:-$root/build/fuzz}
runs=${EPITRACK_FUZZ_RUN_DIR:-$build/runs}
seconds=${EPITRACK_FUZZ_SECONDS:-30}
jobs=${EPITRACK_JOBS:-2}
targets=${EPITRACK_FUZZ_TARGETS:-$(ls "$root/tests/fuzz/corpus")}

"$root/tools/deps.sh" base fuzz

CC=clang CXX=clang++ cmake -S "$root" -B "$build" -DEPITRACK_FUZZ=ON \
  -DEPITRACK_SANITIZERS="address;undefined" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" -DEPITRACK_BUILD_BENCH=OFF >/dev/null
build_targets=()
for t in $targets; do build_targets+=(--target "fuzz_$t"); done
cmake --build "$build" -j "$jobs" "${build_targets[@]}"

export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:strict_string_checks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}

# One target: fuzz for the bounded time, then write its table row, ending in "ok" or "FAILED ...",
# to its run directory (the targets run two at a time, one per core; rows are printed in order).
fuzz_one() {
  local t=$1 bin="$build/tests/fuzz/fuzz_$1" work="$runs/$1"
  rm -rf "$work"
  mkdir -p "$work/corpus" "$work/artifacts"
  cp "$root/tests/fuzz/corpus/$t/"* "$work/corpus/"
  local dict=()
  if [ -f "$root/tests/fuzz/dict/$t.dict" ]; then dict=(-dict="$root/tests/fuzz/dict/$t.dict"); fi
  local rc=0
  "$bin" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
    -artifact_prefix="$work/artifacts/" "${dict[@]}" "$work/corpus" >"$work/log" 2>&1 || rc=$?
  # The last status line: "#N DONE cov: C ft: F corp: U/Sb ..." (or INITED/NEW/REDUCE/pulse).
  local last execs cov ft corp result=ok
  last=$(grep -E '^#[0-9]+' "$work/log" | tail -n 1 || true)
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$work/log" | tail -n 1)
  cov=$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<<"$last")
  ft=$(sed -n 's/.* ft: \([0-9]*\).*/\1/p' <<<"$last")
  corp=$(sed -n 's/.* corp: \([0-9]*\/[0-9]*[a-zA-Z]*\).*/\1/p' <<<"$last")
  if [ "$rc" -ne 0 ] || [ -n "$(ls -A "$work/artifacts")" ] ||
     grep -qE 'runtime error:|ERROR: (Address|Leak|Undefined)Sanitizer|FUZZ_CHECK failed' "$work/log"; then
    result="FAILED (exit $rc)"
  fi
  printf '%-14s %10s %8s %8s %14s  %s\n' "$t" "${execs:-?}" "${cov:-?}" "${ft:-?}" "${corp:-?}" \
    "$result" >"$work/row"
}

running=0
for t in $targets; do
  fuzz_one "$t" &
  running=$((running + 1))
  if [ "$running" -ge "$jobs" ]; then
    wait -n || true
    running=$((running - 1))
  fi
done
wait

failed=()
printf '%-14s %10s %8s %8s %14s  %s\n' target executions cov ft corpus result
for t in $targets; do
  row=$(cat "$runs/$t/row" 2>/dev/null || echo "$t: no result")
  echo "$row"
  [[ "$row" == *"  ok" ]] || failed+=("$t")
done

for t in "${failed[@]}"; do
  echo "---- fuzz_$t: $runs/$t/log (crash inputs in $runs/$t/artifacts) ----" >&2
  grep -E -A40 'ERROR:|runtime error:|FUZZ_CHECK failed|deadly signal|timeout' "$runs/$t/log" | head -n 60 >&2 || true
  echo "reproduce: $build/tests/fuzz/fuzz_$t $runs/$t/artifacts/*" >&2
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz.sh: ${#failed[@]} target(s) failed: ${failed[*]}" >&2
  exit 1
fi
echo "fuzz.sh: all ${seconds}s runs clean"
