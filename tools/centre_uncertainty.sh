#!/usr/bin/env bash
# The camera path check's calibration table (docs/solver.md, "Camera path check"): renders
# synthetic clips of several classes, solves each (focal given, then self-calibrated; the
# rolling-shutter clips also with --readout auto) and prints one line per solve: status, exit
# code, the centres' standard deviation in percent of the path (summary.json
# centre_uncertainty), and epitrack-eval's ATE and relative RPE against the ground truth.
#   tools/centre_uncertainty.sh [CLIP...]     (default: every clip below)
#   EPITRACK_BUILD_DIR   build with the commands (default build/test, as tools/test.sh)
#   EPITRACK_OUT         where clips and solves go (default a temporary directory, removed)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${EPITRACK_BUILD_DIR:-$root/build/test}
synth=$build/tools/synth/epitrack-synth
solve=$build/tools/solve/epitrack-solve
eval_cmd=$build/tools/eval/epitrack-eval
for b in "$synth" "$solve" "$eval_cmd"; do
  [ -x "$b" ] || { echo "centre_uncertainty: no $b (build first)" >&2; exit 2; }
done
if [ -n "${EPITRACK_OUT:-}" ]; then out=$EPITRACK_OUT; mkdir -p "$out"; else
  out=$(mktemp -d); trap 'rm -rf "$out"' EXIT
fi

common="--frames 120 --size 480x360 --focal 420 --noise 1"
declare -A clips=(
  [fastpan-s5]="--scene fastpan $common --seed 5"
  [fastpan-s6]="--scene fastpan $common --seed 6"
  [fastpan-s7]="--scene fastpan $common --seed 7"
  [fastpan-s9]="--scene fastpan $common --seed 9"
  [fastpan-s5-walk4mm]="--scene fastpan $common --seed 5 --walk 0.004"
  [fastpan-s5-rs30]="--scene fastpan $common --seed 5 --rolling-shutter 30ms"
  [fastpan-s9-rs30]="--scene fastpan $common --seed 9 --rolling-shutter 30ms"
  [orbit]="--scene orbit $common"
  [handheld]="--scene handheld $common"
  [dolly]="--scene dolly $common"
  [occlusion]="--scene occlusion $common"
  [planar]="--scene planar $common"
  [pan-tripod]="--scene pan $common"
  [shake-s1]="--scene shake $common --seed 1"
  [shake-s2]="--scene shake $common --seed 2"
  [shake-s3]="--scene shake $common --seed 3"
  [shake-s4-noise2]="--scene shake --frames 120 --size 480x360 --focal 420 --noise 2 --seed 4"
  [shake-640-200]="--scene shake --frames 200 --size 640x480 --focal 544 --noise 1 --seed 1"
)
order=(fastpan-s5 fastpan-s6 fastpan-s7 fastpan-s9 fastpan-s5-walk4mm fastpan-s5-rs30
  fastpan-s9-rs30 orbit handheld dolly occlusion planar pan-tripod shake-s1 shake-s2 shake-s3
  shake-s4-noise2 shake-640-200)
[ $# -gt 0 ] && order=("$@")

one() { # clip mode solve-args...
  local clip=$1 mode=$2
  shift 2
  local dir=$out/$clip-$mode rc=0 t0=$SECONDS
  "$solve" "$out/$clip/frames" --out "$dir" --force --quiet "$@" || rc=$?
  if [ ! -f "$dir/summary.json" ]; then
    echo "$clip $mode: exit $rc, no summary.json"
    return 0
  fi
  local ev
  ev=$("$eval_cmd" --gt "$out/$clip/groundtruth.txt" --est "$dir/cameras.tum" \
    --gt-intrinsics "$out/$clip/intrinsics.txt" --est-intrinsics "$dir/intrinsics.txt" 2>/dev/null) || true
  python3 - "$clip" "$mode" "$rc" "$((SECONDS - t0))" "$ev" "$dir/summary.json" <<'PY'
import json, sys
clip, mode, rc, secs, ev, path = sys.argv[1:]
s = json.load(open(path))
cu = s.get("centre_uncertainty", {})
sd = cu.get("sd_percent_of_path")
sd_text = f"{cu['sd_steps']:.3f} step, {sd:.3f} %" if sd is not None else "-"
try:
    e = json.loads(ev)
    ev_text = (f"ATE {100 * e['ate_rmse_rel']:.3f} %, rpe_rel {e['rpe_trans_rel']:.3f}, "
               f"rot {e['rot_err_deg_mean']:.3f} deg, focal {e['focal_err_pct']:.2f} %")
except (ValueError, KeyError, TypeError):
    ev_text = ev.strip().replace("\n", " ")
print(f"{clip} {mode}: {s.get('status')} (exit {rc}), {s.get('solved_frames')}/{s.get('frames')} "
      f"frames, centre sd {sd_text} of path; {ev_text}; {secs} s")
PY
}

for clip in "${order[@]}"; do
  [ -n "${clips[$clip]:-}" ] || { echo "centre_uncertainty: unknown clip $clip" >&2; exit 2; }
  [ -d "$out/$clip/frames" ] || "$synth" ${clips[$clip]} --quiet --out "$out/$clip" >/dev/null
  one "$clip" given --intrinsics "$out/$clip/intrinsics.txt"
  one "$clip" self
  case "$clip" in *-rs*) one "$clip" self-readout-auto --readout auto ;; esac
done
