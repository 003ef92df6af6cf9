#!/usr/bin/env bash
# Solves the real sequences of ../shared/data with default settings (given intrinsics, then
# self-calibrated) and prints one line of epitrack-eval figures per solve (issue 6's table).
#   tools/real_sequences.sh [kitti|temple|tum|all] [extra epitrack-solve options...]
#   EPITRACK_BUILD_DIR   build with the commands (default build/test, as tools/test.sh)
#   EPITRACK_SHARED_DATA data directory (default ../shared/data beside the project)
#   EPITRACK_OUT         where the solves go (default a temporary directory, removed)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${EPITRACK_BUILD_DIR:-$root/build/test}
data=${EPITRACK_SHARED_DATA:-$root/../shared/data}
which=${1:-all}
shift || true
[ -d "$data" ] || { echo "real_sequences: no data directory $data" >&2; exit 2; }
solve=$build/tools/solve/epitrack-solve
eval_cmd=$build/tools/eval/epitrack-eval
[ -x "$solve" ] && [ -x "$eval_cmd" ] || { echo "real_sequences: build first (tools/test.sh)" >&2; exit 2; }
if [ -n "${EPITRACK_OUT:-}" ]; then out=$EPITRACK_OUT; mkdir -p "$out"; else
  out=$(mktemp -d); trap 'rm -rf "$out"' EXIT
fi

one() { # name frames intrinsics-or-empty groundtruth
  local name=$1 frames=$2 intr=$3 gt=$4 args=()
  [ -n "$intr" ] && args=(--intrinsics "$intr")
  local t0=$SECONDS rc=0
  "$solve" "$frames" --out "$out/$name" --force --quiet "${args[@]}" "${extra[@]}" || rc=$?
  if [ ! -f "$out/$name/summary.json" ]; then
    echo "$name: exit $rc, no summary.json"
    return 0
  fi
  local ev
  ev=$("$eval_cmd" --gt "$gt" --est "$out/$name/cameras.tum" 2>/dev/null) || true  # stdout: the JSON
  python3 - "$name" "$rc" "$((SECONDS - t0))" "$ev" "$out/$name/summary.json" <<'PY'
import json, sys
name, rc, secs, ev, path = sys.argv[1:]
s = json.load(open(path))
try:
    e = json.loads(ev)
except ValueError:
    print(f"{name}: exit {rc}, status {s.get('status')}: {ev.strip()}")
    sys.exit(0)
fb = s.get("focal_fallback", "")
cu = s.get("centre_uncertainty", {})
cu_text = (f", centre sd {cu['sd_steps']:.3f} step ({cu['sd_percent_of_path']:.3f} % of path)"
           if cu else "")
print(f"{name}: exit {rc}, {secs} s, status {s.get('status')}{cu_text}, {e['matched_frames']}/{e['gt_frames']} "
      f"frames, ATE {100 * e['ate_rmse_rel']:.4f} % ({e['ate_rmse']:.4g}), rotation "
      f"{e['rot_err_deg_mean']:.3f} deg, focal {s.get('focal_px'):.1f} px "
      f"({s.get('focal_source')}{', ' + fb if fb else ''}), reprojection {s.get('mean_reproj_px'):.3f} px")
PY
}
extra=("$@")
case "$which" in all | kitti)
  for s in kitti_seq06_excerpt kitti_highway_excerpt; do
    one "$s" "$data/$s/frames" "$data/$s/intrinsics.txt" "$data/$s/groundtruth.txt"
    one "$s-self" "$data/$s/frames" "" "$data/$s/groundtruth.txt"
  done ;;
esac
case "$which" in all | temple)
  # Views 12-30, the longest continuous run of the ring (its README), re-indexed from 0.
  t=$out/temple-input
  rm -rf "$t"
  mkdir -p "$t/frames"
  for i in $(seq 12 30); do
    ln -s "$data/middlebury_templeRing/frames/$(printf %06d "$i").png" \
      "$t/frames/$(printf %06d $((i - 12))).png"
  done
  awk '!/^#/ && NF { if ($1 >= 12 && $1 <= 30) { $1 = $1 - 12; print } }' \
    "$data/middlebury_templeRing/groundtruth.txt" >"$t/groundtruth.txt"
  one templeRing-12-30 "$t/frames" "$data/middlebury_templeRing/intrinsics.txt" "$t/groundtruth.txt"
  one templeRing-12-30-self "$t/frames" "" "$t/groundtruth.txt" ;;
esac
case "$which" in all | tum)
  s=tum_fr3_cabinet_keyframes
  one "$s" "$data/$s/frames" "$data/$s/intrinsics.txt" "$data/$s/groundtruth.txt" ;;
esac
