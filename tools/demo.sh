#!/usr/bin/env bash
# The README's demo, the product's showcase: installs missing Debian packages, builds Release,
# renders a synthetic handheld clip (or takes INPUT when given one), solves it with a
# self-calibrated focal, renders two virtual towers on the ground into every frame, and prints where
# the report (report.html) and the augmented video (augmented.avi) are.
#   tools/demo.sh [INPUT]
#     INPUT    a frame directory, .y4m (- for stdin), .mjpeg or v4l2:/dev/videoN (default: synthetic)
#   environment:
#     EPITRACK_DEMO_OUT      output folder (default build/demo)
#     EPITRACK_DEMO_RENDER   towers | cube | axes (default towers)
#     EPITRACK_DEMO_FRAMES   frames of the synthetic clip (default 150)
#     EPITRACK_DEMO_SEED     scene layout of the synthetic clip (default 1)
#     EPITRACK_DEMO_JOBS     parallel build jobs (default: every core)
#     EPITRACK_DEMO_ARGS     extra epitrack-solve options, e.g. "--object-at 0.2,0,0 --object-scale 2"
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=$root/build/release
out=${EPITRACK_DEMO_OUT:-$root/build/demo}
render=${EPITRACK_DEMO_RENDER:-towers}
frames=${EPITRACK_DEMO_FRAMES:-150}
seed=${EPITRACK_DEMO_SEED:-1}
jobs=${EPITRACK_DEMO_JOBS:-$(nproc)}
input=${1:-}

echo "demo: checking packages ..."
"$root/tools/deps.sh" base
echo "demo: building Release in $build ..."
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release -DEPITRACK_BUILD_TESTS=OFF >/dev/null
cmake --build "$build" -j "$jobs" >/dev/null
bin=$build/tools

mkdir -p "$out"
synthetic=0
if [ -z "$input" ]; then
  synthetic=1
  echo "demo: rendering a synthetic handheld clip (704x576, $frames frames, true focal 600 px) ..."
  rm -rf "$out/clip"
  "$bin/synth/epitrack-synth" --scene handheld --frames "$frames" --size 704x576 --focal 600 \
    --seed "$seed" --out "$out/clip" 2>/dev/null
  input=$out/clip/frames
fi

echo "demo: solving $input (focal self-calibrated) and rendering '$render' ..."
rm -rf "$out/solve"
solve_rc=0
# shellcheck disable=SC2086  # EPITRACK_DEMO_ARGS is a list of options
"$bin/solve/epitrack-solve" "$input" --out "$out/solve" --render "$render" \
  ${EPITRACK_DEMO_ARGS:-} || solve_rc=$?

if [ "$synthetic" = 1 ] && [ "$solve_rc" -eq 0 ]; then
  echo "demo: accuracy against the synthetic ground truth (epitrack-eval):"
  "$bin/eval/epitrack-eval" --gt "$out/clip/groundtruth.txt" --est "$out/solve/cameras.tum" \
    --gt-intrinsics "$out/clip/intrinsics.txt" --est-intrinsics "$out/solve/intrinsics.txt" |
    tee "$out/eval.json" || true
fi

# A frame from the middle of the clip, for the README (docs/demo_frame.jpg is one of these).
if [ -d "$out/solve/augmented" ]; then
  count=$(find "$out/solve/augmented" -name '*.jpg' | wc -l)
  if [ "$count" -gt 0 ]; then
    middle=$(printf '%06d.jpg' $((count / 2)))
    cp "$out/solve/augmented/$middle" "$out/demo_frame.jpg"
  fi
fi
if [ -f "$out/solve/augmented.avi" ] && command -v ffprobe >/dev/null 2>&1; then
  ffprobe -v error -select_streams v:0 -count_frames \
    -show_entries stream=codec_name,width,height,nb_read_frames -of csv=p=0 \
    "$out/solve/augmented.avi" | sed 's/^/demo: ffprobe augmented.avi: /' || true
fi

echo
echo "demo: output in $out"
[ "$synthetic" = 1 ] && echo "  synthetic clip:  $out/clip (frames/, groundtruth.txt, intrinsics.txt, points3d.txt, landmarks.txt)"
[ -f "$out/solve/summary.json" ] && echo "  summary:         $out/solve/summary.json"
[ -f "$out/solve/report.html" ] && echo "  report:          $out/solve/report.html"
[ -f "$out/solve/augmented.avi" ] && echo "  augmented video: $out/solve/augmented.avi  (play: ffplay, mpv or vlc)"
[ -f "$out/demo_frame.jpg" ] && echo "  one frame:       $out/demo_frame.jpg"
if [ "$solve_rc" -ne 0 ]; then
  echo "demo: epitrack-solve failed (exit $solve_rc); summary.json and report.html say why" >&2
  exit "$solve_rc"
fi
exit 0
