#!/usr/bin/env bash
# The README's demo: installs missing packages, builds Release, renders a synthetic clip (or uses
# INPUT when given), runs the pipeline that exists on it, and prints where the output is.
#   tools/demo.sh [INPUT]        EPITRACK_DEMO_OUT overrides the output folder (default build/demo)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=$root/build/release
out=${EPITRACK_DEMO_OUT:-$root/build/demo}
input=${1:-}

"$root/tools/deps.sh" base
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release -DEPITRACK_BUILD_TESTS=OFF >/dev/null
cmake --build "$build" -j "$(nproc)"
bin=$build/tools

mkdir -p "$out"
if [ -z "$input" ]; then
  echo "demo: rendering a synthetic handheld clip (704x576, 120 frames, focal 600) ..."
  "$bin/synth/epitrack-synth" --scene handheld --frames 120 --size 704x576 --focal 600 --seed 7 --out "$out/clip"
  input=$out/clip/frames
fi

if [ -x "$bin/track/epitrack-track" ]; then
  echo "demo: tracking features ..."
  "$bin/track/epitrack-track" "$input" --out "$out/tracks.csv"
fi
if [ -x "$bin/solve/epitrack-solve" ]; then
  echo "demo: solving the camera ..."
  "$bin/solve/epitrack-solve" "$input" --out "$out/solve" --render towers
fi
if [ -x "$bin/bench/epitrack-bench" ]; then
  echo "demo: pyramid benchmark on the clip ..."
  "$bin/bench/epitrack-bench" pyramid "$input" --repeat 3 | tee "$out/bench_pyramid.json"
fi

echo
echo "demo: output in $out"
[ -d "$out/clip" ] && echo "  synthetic clip:  $out/clip (frames/, groundtruth.txt, intrinsics.txt, points3d.txt, landmarks.txt)"
[ -f "$out/tracks.csv" ] && echo "  2D tracks:       $out/tracks.csv"
[ -f "$out/solve/report.html" ] && echo "  report:          $out/solve/report.html"
[ -f "$out/solve/augmented.avi" ] && echo "  augmented video: $out/solve/augmented.avi"
exit 0
