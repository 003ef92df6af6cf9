# shellcheck shell=bash
# Sourced by the cross stages (.ci/cross_aarch64.sh, .ci/cross_armhf.sh): the bit-exact tracks.csv
# check. A fixed synthetic clip is rendered and tracked natively, then tracked from the same frame
# directory (PGM frames: the directory replay path) by the target build under emulation; the two
# tracks.csv must be byte-identical, so a recording debugged on a desktop behaves the same on the
# board.

# target_emulator CROSS_BUILD: the toolchain's command prefix that runs a target program here
# (qemu with the cross loader and its own libc, see toolchains/linux-cross-common.cmake), as ctest
# uses it.
target_emulator() {
  local emulator
  emulator=$(sed -n 's/^EPITRACK_TARGET_EMULATOR:INTERNAL=//p' "$1/CMakeCache.txt" | tr ';' ' ')
  [ -n "$emulator" ] || { echo "ci: no emulator in $1/CMakeCache.txt" >&2; return 1; }
  echo "$emulator"
}

# render_digest_clip NATIVE_BUILD CLIP_DIR: renders the clip into CLIP_DIR/frames and writes the
# native tracker's output to CLIP_DIR/tracks-x86_64.csv.
render_digest_clip() {
  local native=$1 clip=$2
  rm -rf "$clip"
  "$native/tools/synth/epitrack-synth" --scene handheld --frames 60 --size 704x576 --noise 2 \
    --seed 11 --out "$clip" >/dev/null
  "$native/tools/track/epitrack-track" "$clip/frames" --out "$clip/tracks-x86_64.csv" --quiet
}

# check_tracks_bit_exact LABEL CLIP_DIR COMMAND...: runs COMMAND (the target's epitrack-track
# through the emulator) on CLIP_DIR/frames and fails unless its tracks.csv is byte-identical to the
# native one, with more than 1000 rows.
check_tracks_bit_exact() {
  local label=$1 clip=$2
  shift 2
  local out="$clip/tracks-$label.csv"
  "$@" "$clip/frames" --out "$out" --quiet
  local a b rows
  a=$(sha256sum <"$clip/tracks-x86_64.csv" | cut -d' ' -f1)
  b=$(sha256sum <"$out" | cut -d' ' -f1)
  rows=$(($(wc -l <"$clip/tracks-x86_64.csv") - 1))
  echo "tracks.csv digest: x86-64 $a, $label $b ($rows rows)"
  if [ "$a" != "$b" ]; then
    echo "ci: the tracker's output differs between x86-64 and $label" >&2
    diff "$clip/tracks-x86_64.csv" "$out" | head -20 >&2
    return 1
  fi
  [ "$rows" -gt 1000 ] || { echo "ci: too few tracked rows ($rows)" >&2; return 1; }
  echo "ci: $label bit-exact"
}
