#!/usr/bin/env bash
# COLMAP 3.8 as a reference on a real sequence of ../shared/data (issue 6's KITTI and templeRing
# figures in the README): one line of epitrack-eval figures per result.
#   tools/figures/colmap_reference.sh kitti_highway_excerpt|kitti_seq06_excerpt|templeRing
#   1. COLMAP's incremental solve, intrinsics given and held (SIFT, sequential matching with an
#      overlap of 10; init_min_tri_angle 4 so that forward motion initialises);
#   2. COLMAP's bundle adjuster started at the ground-truth poses (points triangulated there),
#      intrinsics held, then with the focal lengths free: where the images and K pull the cameras;
#   3. epitrack-solve --tracks on COLMAP's tracks, intrinsics given.
#   tools/figures/colmap_reference.sh --exhaustive templeRing47|tum_cabinet
#   Photo sets (issue 22): every pair of views matched (COLMAP's exhaustive matcher), COLMAP's
#   incremental mapper with its default options and the intrinsics held, against epitrack-solve
#   with its default options and the intrinsics given, each timed on one thread (CPU seconds
#   from /usr/bin/time); one table row per solver: registered views, ATE, CPU, wall time.
#   EPITRACK_BUILD_DIR   build with the commands (default build/test)
#   EPITRACK_SHARED_DATA data directory (default ../shared/data beside the project)
#   EPITRACK_OUT         work directory (default a temporary directory, removed)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
build=${EPITRACK_BUILD_DIR:-$root/build/test}
data=${EPITRACK_SHARED_DATA:-$root/../shared/data}
exhaustive=0
if [ "${1:-}" = --exhaustive ]; then exhaustive=1; shift; fi
seq=${1:-}
usage="usage: $0 kitti_highway_excerpt|kitti_seq06_excerpt|templeRing, or $0 --exhaustive templeRing47|tum_cabinet"
if [ "$exhaustive" = 1 ]; then
  case "$seq" in templeRing47 | tum_cabinet) ;; *) echo "$usage" >&2; exit 2 ;; esac
else
  case "$seq" in kitti_highway_excerpt | kitti_seq06_excerpt | templeRing) ;;
    *) echo "$usage" >&2; exit 2 ;;
  esac
fi
[ -d "$data" ] || { echo "colmap_reference: no data directory $data" >&2; exit 2; }
solve=$build/tools/solve/epitrack-solve
eval_cmd=$build/tools/eval/epitrack-eval
[ -x "$solve" ] && [ -x "$eval_cmd" ] || { echo "colmap_reference: build first (tools/test.sh)" >&2; exit 2; }
"$root/tools/deps.sh" colmap
model=$root/tools/figures/colmap_model.py
if [ -n "${EPITRACK_OUT:-}" ]; then w=$EPITRACK_OUT; mkdir -p "$w"; else
  w=$(mktemp -d); trap 'rm -rf "$w"' EXIT
fi
export QT_QPA_PLATFORM=offscreen # COLMAP's command line without a display

if [ "$seq" = templeRing47 ]; then # all 47 views, in folder order
  d=$data/middlebury_templeRing
  frames=$d/frames
  gt=$d/groundtruth.txt
elif [ "$seq" = tum_cabinet ]; then
  d=$data/tum_fr3_cabinet_keyframes
  frames=$d/frames
  gt=$d/groundtruth.txt
elif [ "$seq" = templeRing ]; then # views 12-30, the longest continuous run, re-indexed from 0
  d=$data/middlebury_templeRing
  frames=$w/frames
  rm -rf "$frames"
  mkdir -p "$frames"
  for i in $(seq 12 30); do
    ln -s "$d/frames/$(printf %06d "$i").png" "$frames/$(printf %06d $((i - 12))).png"
  done
  gt=$w/groundtruth.txt
  awk '!/^#/ && NF { if ($1 >= 12 && $1 <= 30) { $1 = $1 - 12; print } }' "$d/groundtruth.txt" >"$gt"
else
  d=$data/$seq
  frames=$d/frames
  gt=$d/groundtruth.txt
fi
intr=$d/intrinsics.txt
# COLMAP puts the first pixel's centre at (0.5, 0.5), epitrack at (0, 0).
read -r fx fy cx cy width height < <(awk '!/^#/ && NF { print; exit }' "$intr")
params="$fx,$fy,$(awk -v c="$cx" 'BEGIN { print c + 0.5 }'),$(awk -v c="$cy" 'BEGIN { print c + 0.5 }')"
camera="PINHOLE $width $height ${params//,/ }"

score() { # label tum
  local ev
  ev=$("$eval_cmd" --gt "$gt" --est "$2") || { echo "$1: no score"; return 0; }
  python3 - "$1" "$ev" <<'PY'
import json, sys
e = json.loads(sys.argv[2])
print(f"{sys.argv[1]}: {e['matched_frames']}/{e['gt_frames']} frames, ATE {100 * e['ate_rmse_rel']:.3f} % "
      f"({e['ate_rmse']:.4g}), rotation {e['rot_err_deg_mean']:.3f} deg")
PY
}
cost() { grep -E "Initial cost|Final cost" "$1" | awk '{ printf "%s %s ", $1, $4 }'; }

if [ "$exhaustive" = 1 ]; then
  timed() { # label command...: runs it, appends "label cpu_s wall_s" to $w/times
    local t0 t1
    t0=$(date +%s.%N)
    /usr/bin/time -f "%U %S" -o "$w/time.tmp" "${@:2}" >>"$w/$1.log" 2>&1 || true
    t1=$(date +%s.%N)
    awk -v l="$1" -v a="$t0" -v b="$t1" '{ printf "%s %.1f %.1f\n", l, $1 + $2, b - a }' \
      "$w/time.tmp" >>"$w/times"
  }
  total() { awk -v p="$1" '$1 ~ p { c += $2; s += $3 } END { printf "%.0f s CPU, %.0f s wall", c, s }' "$w/times"; }
  row() { # solver tum seconds: one table row
    local ev
    if ! ev=$("$eval_cmd" --gt "$gt" --est "$2" 2>/dev/null); then
      echo "| $1 | 0/$n | - | $3 |"
      return 0
    fi
    python3 - "$1" "$ev" "$n" "$3" <<'PY'
import json, sys
e = json.loads(sys.argv[2])
print(f"| {sys.argv[1]} | {e['matched_frames']}/{sys.argv[3]} | {100 * e['ate_rmse_rel']:.3f} % | {sys.argv[4]} |")
PY
  }
  n=$(find "$frames" -maxdepth 1 -type f | wc -l)
  db=$w/colmap.db
  rm -rf "$db" "$w/sparse" "$w/epitrack" "$w/times"
  mkdir -p "$w/sparse"
  timed colmap_extract colmap feature_extractor --database_path "$db" --image_path "$frames" \
    --ImageReader.camera_model PINHOLE --ImageReader.single_camera 1 \
    --ImageReader.camera_params "$params" --SiftExtraction.use_gpu 0 \
    --SiftExtraction.num_threads 1
  timed colmap_match colmap exhaustive_matcher --database_path "$db" --SiftMatching.use_gpu 0 \
    --SiftMatching.num_threads 1
  timed colmap_map colmap mapper --database_path "$db" --image_path "$frames" \
    --output_path "$w/sparse" --Mapper.num_threads 1 --Mapper.ba_refine_focal_length 0 \
    --Mapper.ba_refine_principal_point 0 --Mapper.ba_refine_extra_params 0
  mapper_options="default options"
  if [ -z "$(ls -A "$w/sparse")" ]; then
    # No model with the defaults (the TUM cabinet: no initial pair): the relaxed initialisation
    # of the sequential mode above.
    mapper_options="init_min_tri_angle 4, init_min_num_inliers 50, abs_pose_min_num_inliers 15"
    timed colmap_map_relaxed colmap mapper --database_path "$db" --image_path "$frames" \
      --output_path "$w/sparse" --Mapper.num_threads 1 --Mapper.ba_refine_focal_length 0 \
      --Mapper.ba_refine_principal_point 0 --Mapper.ba_refine_extra_params 0 \
      --Mapper.init_min_tri_angle 4 --Mapper.abs_pose_min_num_inliers 15 \
      --Mapper.init_min_num_inliers 50
  fi
  # The largest model (COLMAP numbers its models in the order found, not by size).
  best=""
  best_n=0
  for m in "$w"/sparse/*/; do
    [ -d "$m" ] || continue
    colmap model_converter --input_path "$m" --output_path "$m" --output_type TXT >/dev/null 2>&1
    k=$(grep -vc '^#' "$m/images.txt" || true)
    k=$((k / 2))
    if [ "$k" -gt "$best_n" ]; then best=$m; best_n=$k; fi
  done
  models=$(find "$w/sparse" -mindepth 1 -maxdepth 1 -type d | wc -l)
  echo "| solver ($seq, intrinsics given) | registered | ATE (of the path) | time |"
  echo "|---|---|---|---|"
  if [ -n "$best" ]; then
    python3 "$model" to-tum "$best/images.txt" "$w/colmap.tum"
    row "COLMAP 3.8 (SIFT, exhaustive, $mapper_options, $models model(s))" "$w/colmap.tum" "$(total colmap_)"
  else
    row "COLMAP 3.8 (SIFT, exhaustive, $mapper_options, no model)" /nonexistent "$(total colmap_)"
  fi
  timed epitrack taskset -c 0 "$solve" "$frames" --out "$w/epitrack" --intrinsics "$intr" --quiet --force
  status=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["status"])' \
    "$w/epitrack/summary.json" 2>/dev/null || echo "no summary")
  row "epitrack-solve (defaults, status $status)" "$w/epitrack/cameras.tum" "$(total epitrack)"
  exit 0
fi

db=$w/colmap.db
rm -rf "$db" "$w/sparse" "$w/gt_model" "$w/gt_points" "$w/gt_ba" "$w/gt_ba_focal"
mkdir -p "$w/sparse" "$w/gt_model" "$w/gt_points" "$w/gt_ba" "$w/gt_ba_focal"
colmap feature_extractor --database_path "$db" --image_path "$frames" \
  --ImageReader.camera_model PINHOLE --ImageReader.single_camera 1 \
  --ImageReader.camera_params "$params" --SiftExtraction.use_gpu 0 >"$w/extract.log" 2>&1
colmap sequential_matcher --database_path "$db" --SiftMatching.use_gpu 0 \
  --SequentialMatching.overlap 10 >"$w/match.log" 2>&1
held=(--Mapper.ba_refine_focal_length 0 --Mapper.ba_refine_principal_point 0
  --Mapper.ba_refine_extra_params 0)
colmap mapper --database_path "$db" --image_path "$frames" --output_path "$w/sparse" "${held[@]}" \
  --Mapper.init_min_tri_angle 4 --Mapper.abs_pose_min_num_inliers 15 \
  --Mapper.init_min_num_inliers 50 >"$w/mapper.log" 2>&1 || true
if [ -d "$w/sparse/0" ]; then
  colmap model_converter --input_path "$w/sparse/0" --output_path "$w/sparse/0" --output_type TXT
  python3 "$model" to-tum "$w/sparse/0/images.txt" "$w/colmap.tum"
  score "COLMAP incremental solve, K held" "$w/colmap.tum"
  python3 "$model" to-tracks "$w/sparse/0/images.txt" "$w/colmap_tracks.csv"
  "$solve" "$frames" --out "$w/epitrack_on_colmap" --intrinsics "$intr" \
    --tracks "$w/colmap_tracks.csv" --quiet --force || true
  score "epitrack-solve --tracks (COLMAP's tracks), K given" "$w/epitrack_on_colmap/cameras.tum"
else
  echo "COLMAP incremental solve: failed (see $w/mapper.log)"
fi

python3 "$model" gt-model "$db" "$gt" "$camera" "$w/gt_model"
colmap point_triangulator --database_path "$db" --image_path "$frames" --input_path "$w/gt_model" \
  --output_path "$w/gt_points" "${held[@]}" >"$w/triangulate.log" 2>&1
for free in 0 1; do
  out=$w/gt_ba
  [ "$free" = 1 ] && out=$w/gt_ba_focal
  colmap bundle_adjuster --input_path "$w/gt_points" --output_path "$out" \
    --BundleAdjustment.refine_focal_length "$free" --BundleAdjustment.refine_principal_point 0 \
    --BundleAdjustment.refine_extra_params 0 --BundleAdjustment.max_num_iterations 500 \
    >"$out.log" 2>&1
  colmap model_converter --input_path "$out" --output_path "$out" --output_type TXT
  python3 "$model" to-tum "$out/images.txt" "$out.tum"
  if [ "$free" = 0 ]; then
    score "COLMAP bundle adjustment from the ground truth, K held ($(cost "$out.log")px)" "$out.tum"
  else
    focals=$(awk '!/^#/ && NF { print "fx " $5 ", fy " $6; exit }' "$out/cameras.txt")
    score "the same, focal lengths free ($focals; $(cost "$out.log")px)" "$out.tum"
  fi
done
