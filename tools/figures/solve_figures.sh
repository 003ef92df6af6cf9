#!/usr/bin/env bash
# Reproduces the solver figures of the README: epitrack-synth clip -> epitrack-solve -> epitrack-eval,
# one line per scenario. Usage: tools/figures/solve_figures.sh [BUILD_DIR] (default build/dev).
# Scratch output goes to $EPITRACK_FIG_DIR (default /tmp/epitrack-figures); EPITRACK_FIG_SOLVE_ARGS
# is appended to every epitrack-solve call (e.g. "--features 300" to compare a setting).
set -u
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
B=${1:-$root/build/dev}
out=${EPITRACK_FIG_DIR:-/tmp/epitrack-figures}
mkdir -p "$out"
run() {
  local name=$1 synth=$2 solve=$3 dir="$out/$1"
  rm -rf "$dir"
  # shellcheck disable=SC2086
  "$B/tools/synth/epitrack-synth" $synth --out "$dir" >/dev/null 2>&1
  # shellcheck disable=SC2086
  "$B/tools/solve/epitrack-solve" "$dir/frames" --out "$dir/solve" --quiet $solve ${EPITRACK_FIG_SOLVE_ARGS:-} 2>/dev/null
  local rc=$?
  local ev
  ev=$("$B/tools/eval/epitrack-eval" --gt "$dir/groundtruth.txt" --est "$dir/solve/cameras.tum" \
    --gt-intrinsics "$dir/intrinsics.txt" --est-intrinsics "$dir/solve/intrinsics.txt" 2>/dev/null)
  python3 - "$name" "$rc" "$ev" "$dir/solve/summary.json" <<'PY'
import json, sys
name, rc, ev, sp = sys.argv[1:5]
try:
    m = json.loads(ev)
except ValueError:
    m = {}
try:
    s = json.load(open(sp))
except (OSError, ValueError):
    print(f"{name:14s} exit {rc} no summary.json")
    sys.exit(0)
nan = float("nan")
ate = m.get("ate_rmse_rel")
ate = nan if ate is None else ate * 100
rot = m.get("rot_err_deg_mean")
rot = nan if rot is None else rot
print(f"{name:14s} exit {rc} status {s['status']:10s} solved {s['solved_frames']}/{s['frames']} "
      f"focal {s['focal_px'] or nan:.2f} ({s['focal_source']}, observable {s['focal_observable']}) "
      f"ATE {ate:.4f}% rot {rot:.3f} deg reproj {s['mean_reproj_px'] or nan:.3f} px "
      f"total {s['seconds']['total']:.1f} s")
PY
}
run orbit340_K "--scene orbit --frames 340 --target-wander 0.5" "--focal 600"
run orbit200_self "--scene orbit --frames 200 --target-wander 0.5" ""
run handheld_self "--scene handheld --frames 200" ""
run noisy_K "--scene orbit --frames 200 --target-wander 0.5 --noise 2 --blur 0.5" "--focal 600"
run dolly_K "--scene dolly --frames 200" "--focal 600"
run orbit_exact "--scene orbit --frames 200" ""
run pan_self "--scene pan --frames 120" ""
run distort_k1k2 "--scene orbit --frames 200 --target-wander 0.5 --distortion -0.12,0.03" "--focal 600 --distortion k1k2"
