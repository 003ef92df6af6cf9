#!/bin/bash
# The issue-20/27 table for one synthetic clip: renders it (640x480, 200 frames, focal 600), runs
# epitrack-track (default and --no-kalman, --frame-stats), scores the tracks against the truth
# (track_accuracy.py), solves with the focal given and self-calibrated (own tracks and the
# --no-kalman tracks), scores each solve with epitrack-eval, and runs epitrack-device (intrinsics
# given and self-calibrated); --whole-window (the device's option set) is tracked and scored too.
# tools/synth/motion_table.py OUT/NAME prints the figures.
#
# usage: tools/synth/motion_baseline.sh BUILD_DIR OUT_DIR NAME [epitrack-synth options...]
#   e.g. tools/synth/motion_baseline.sh build/test /tmp/baseline shake --scene shake
set -u
if [ $# -lt 3 ]; then
  sed -n 2,10p "$0" >&2
  exit 2
fi
B=$1
C=$2/$3
shift 3
HERE=$(cd "$(dirname "$0")" && pwd)
rm -rf "$C"
mkdir -p "$C"
"$B/tools/synth/epitrack-synth" "$@" --frames 200 --size 640x480 --focal 600 --quiet --out "$C" || exit 1
for v in default nokalman wholewindow; do
  extra=""
  [ $v = nokalman ] && extra="--no-kalman"
  [ $v = wholewindow ] && extra="--whole-window"
  "$B/tools/track/epitrack-track" "$C/frames" --out "$C/tracks_$v.csv" --frame-stats --quiet $extra \
    2> "$C/track_$v.log"
  python3 "$HERE/track_accuracy.py" "$C/landmarks.txt" "$C/tracks_$v.csv" > "$C/acc_$v.json"
done
for f in given self; do
  extra=""
  [ $f = given ] && extra="--focal 600"
  for t in own nokalman; do
    tracks=""
    [ $t = nokalman ] && tracks="--tracks $C/tracks_nokalman.csv"
    "$B/tools/solve/epitrack-solve" "$C/frames" --out "$C/solve_${t}_$f" $extra $tracks --render none \
      --quiet > "$C/solve_${t}_$f.log" 2>&1
    echo "exit $?" >> "$C/solve_${t}_$f.log"
    "$B/tools/eval/epitrack-eval" --gt "$C/groundtruth.txt" --est "$C/solve_${t}_$f/cameras.tum" \
      --gt-intrinsics "$C/intrinsics.txt" --est-intrinsics "$C/solve_${t}_$f/intrinsics.txt" \
      > "$C/eval_${t}_$f.json" 2>&1
  done
done
"$B/firmware_like/epitrack-device" --source "$C/frames" --intrinsics "$C/intrinsics.txt" \
  > "$C/device_given.jsonl" 2>&1
"$B/firmware_like/epitrack-device" --source "$C/frames" > "$C/device_self.jsonl" 2>&1
echo "$C done"
