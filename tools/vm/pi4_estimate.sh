#!/usr/bin/env bash
# Instructions per frame of the aarch64 (NEON) build of epitrack-device, counted under
# qemu-aarch64 with tools/vm/insn_count_plugin.c, for the Raspberry Pi 4 estimate in
# docs/device.md. The device runs a rendered 704x576 orbit (300 features, intrinsics given) for
# FIRST and for LAST frames; (count(LAST) - count(FIRST)) / (LAST - FIRST) is the steady per-frame
# cost (start-up, reservation and the map's initialisation cancel out; reading each PGM frame
# stays in, about 0.4 MB of copying), with the default profile and with firmware_like/pi4.conf.
#   tools/vm/pi4_estimate.sh [--build-dir DIR] [--first N] [--last N]
# Needs the aarch64 cross-build (tools/cross.sh aarch64; EPITRACK_CROSS_BUILD_DIR) and the native
# build's epitrack-synth (EPITRACK_BUILD_DIR). Prints one line per profile.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
build=$root/build/vm
first=10
last=160
while [ $# -gt 0 ]; do
  case "$1" in
    --build-dir) build=$(realpath -m "$2"); shift 2 ;;
    --first) first=$2; shift 2 ;;
    --last) last=$2; shift 2 ;;
    -h | --help) sed -n '2,11p' "${BASH_SOURCE[0]}"; exit 0 ;;
    *) echo "pi4_estimate.sh: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
[ "$last" -gt "$first" ] || { echo "pi4_estimate.sh: --last must exceed --first" >&2; exit 2; }
cross=${EPITRACK_CROSS_BUILD_DIR:-$root/build/cross-aarch64}
native=${EPITRACK_BUILD_DIR:-$root/build/test}
device=$cross/firmware_like/epitrack-device
synth=$native/tools/synth/epitrack-synth
for f in "$device" "$synth"; do
  [ -x "$f" ] || { echo "pi4_estimate.sh: $f is missing (tools/cross.sh aarch64; the native build)" >&2; exit 2; }
done
command -v qemu-aarch64 >/dev/null || { echo "pi4_estimate.sh: qemu-aarch64 is missing (qemu-user)" >&2; exit 2; }
mkdir -p "$build"
plugin=$build/insn_count_plugin.so
gcc -O2 -Wall -Wextra -Werror -shared -fPIC -o "$plugin" "$root/tools/vm/insn_count_plugin.c"
clip=$build/pi4-clip-$last
if [ ! -f "$clip/intrinsics.txt" ]; then
  "$synth" --size 704x576 --frames "$last" --seed 1 --quiet --out "$clip.tmp" && mv "$clip.tmp" "$clip"
fi
# count N [ARGS...]: guest instructions of the device processing N frames.
count() {
  local n=$1
  shift
  qemu-aarch64 -L /usr/aarch64-linux-gnu -plugin "$plugin" -d plugin "$device" \
    --source "$clip/frames" --intrinsics "$clip/intrinsics.txt" --max-frames "$n" \
    --poses /dev/null "$@" 2>&1 | sed -n 's/^insns: //p'
}
for profile in default pi4; do
  args=()
  [ "$profile" = pi4 ] && args=(--config "$root/firmware_like/pi4.conf")
  a=$(count "$first" "${args[@]}")
  b=$(count "$last" "${args[@]}")
  [ -n "$a" ] && [ -n "$b" ] || { echo "pi4_estimate.sh: no instruction count from qemu" >&2; exit 1; }
  awk -v p="$profile" -v a="$a" -v b="$b" -v n=$((last - first)) 'BEGIN {
    i = (b - a) / n
    printf "%s: %.1f M instructions per frame (frames %d..%d); Pi 4 at 1.5 GHz: %.0f ms at CPI 1.0, %.0f-%.0f ms at CPI 0.75-1.5\n",
      p, i / 1e6, '"$first"', '"$last"', i / 1.5e6, 0.75 * i / 1.5e6, 1.5 * i / 1.5e6 }'
done
