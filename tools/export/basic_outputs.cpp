// cameras.tum, rolling_shutter.txt, intrinsics.txt, points.ply and summary.json.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "hal/io/text_formats.hpp"
#include "tools/export/json_writer.hpp"
#include "tools/export/output_writers.hpp"

namespace epitrack::io {
namespace {

bool finitePose(const SolvedCamera& c) { return c.R_wc.allFinite() && c.p_wc.allFinite(); }

void appendLittleEndianFloat(std::vector<uint8_t>& out, float v) {
  uint32_t bits = 0;
  std::memcpy(&bits, &v, sizeof(bits));
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<uint8_t>(bits >> (8 * i)));
}

double median(std::vector<double> values) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  const std::size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(mid), values.end());
  double m = values[mid];
  if (values.size() % 2 == 0) {
    const double below =
        *std::max_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(mid));
    m = 0.5 * (m + below);
  }
  return m;
}

double mean(const std::vector<double>& values) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  double sum = 0.0;
  for (const double v : values) sum += v;
  return sum / static_cast<double>(values.size());
}

// "%.12g": enough digits for a pose's motion, short for the row numbers.
std::string shortNumber(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.12g", v);
  return buf;
}

}  // namespace

std::string formatCamerasTum(const Reconstruction& rec) {
  std::vector<hal::TrajectoryEntry> entries;
  entries.reserve(rec.cameras.size());
  for (const SolvedCamera& c : rec.cameras) {
    if (!c.solved || !finitePose(c)) continue;
    hal::TrajectoryEntry e;
    e.t = rec.has_timestamps ? c.timestamp : static_cast<double>(c.frame);
    e.position = c.p_wc;
    e.rotation = Eigen::Quaterniond(c.R_wc).normalized();
    entries.push_back(e);
  }
  // With a rolling shutter the poses are the middle row's (docs/rolling-shutter.md): said where a
  // reader of the file sees it; a global-shutter solve's file is unchanged.
  std::string comment = "epitrack-solve camera track (frames without a solution are omitted)";
  if (rec.readout_frames > 0.0) {
    comment += "; ";
    comment += rollingShutterNote(rec);
  }
  return hal::formatTrajectory(entries, comment);
}

std::string rollingShutterNote(const Reconstruction& rec) {
  if (!(rec.readout_frames > 0.0)) return {};
  std::string note = "rolling shutter: every pose is the middle row's (row ";
  note += shortNumber(rec.readout_reference_row);
  note += ") of a ";
  note += shortNumber(rec.readout_ms);
  note += " ms readout (";
  note += shortNumber(rec.readout_frames);
  note += " frame intervals); each frame's motion over the readout is in rolling_shutter.txt";
  return note;
}

std::string formatRollingShutter(const Reconstruction& rec) {
  std::string out =
      "# epitrack-solve rolling shutter: each solved frame's camera motion over its readout\n"
      "# (docs/formats.md). 'readout R ROWS REF MS FPS': row y is exposed tau(y) = R (y - REF) /\n"
      "# (ROWS - 1) frame intervals after the frame's pose in cameras.tum (row REF's), R the "
      "readout\n"
      "# in frame intervals (MS milliseconds at FPS frames per second). Then 't wx wy wz vx vy "
      "vz'\n"
      "# per solved frame (t as in cameras.tum): row y's pose is R_wc Exp(w tau(y)), centre\n"
      "# p_wc + v tau(y); w in the camera frame (rad per frame interval), v in the scene frame\n"
      "# (scene units per frame interval).\n";
  out += "readout";
  for (const double v : {rec.readout_frames, static_cast<double>(rec.intrinsics.height),
                         rec.readout_reference_row, rec.readout_ms, rec.fps}) {
    out += ' ';
    out += shortNumber(v);
  }
  out += '\n';
  for (const SolvedCamera& c : rec.cameras) {
    if (!c.solved || !finitePose(c)) continue;
    out += shortNumber(rec.has_timestamps ? c.timestamp : static_cast<double>(c.frame));
    for (int i = 0; i < 6; ++i) {
      out += ' ';
      out += shortNumber(i < 3 ? c.rs_angular[i] : c.rs_linear[i - 3]);
    }
    out += '\n';
  }
  return out;
}

std::string formatIntrinsicsFile(const Reconstruction& rec) {
  return hal::formatIntrinsics(rec.intrinsics,
                               "epitrack-solve intrinsics (focal " + rec.focal_source + ")");
}

std::vector<uint8_t> formatPointsPly(const Reconstruction& rec) {
  std::size_t count = 0;
  for (const ScenePoint& p : rec.points) count += p.X.allFinite() ? 1 : 0;
  const std::string header =
      "ply\nformat binary_little_endian 1.0\ncomment epitrack-solve scene points (scene frame)\n" +
      (rec.readout_frames > 0.0
           ? "comment rolling shutter: solved with every image row at its own pose "
             "(rolling_shutter.txt)\n"
           : std::string()) +
      "element vertex " + std::to_string(count) +
      "\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\n"
      "property uchar green\nproperty uchar blue\nend_header\n";
  std::vector<uint8_t> out(header.begin(), header.end());
  out.reserve(out.size() + count * 15);
  for (const ScenePoint& p : rec.points) {
    if (!p.X.allFinite()) continue;
    for (int i = 0; i < 3; ++i) appendLittleEndianFloat(out, static_cast<float>(p.X[i]));
    for (int i = 0; i < 3; ++i) out.push_back(p.gray);
  }
  return out;
}

void reprojectionStatistics(const Reconstruction& rec, double& mean_px, double& median_px) {
  mean_px = rec.mean_reproj_px;
  median_px = rec.median_reproj_px;
  if (std::isfinite(mean_px) && std::isfinite(median_px)) return;
  std::vector<double> residuals;
  for (const PointObservation& o : rec.observations) {
    if (std::isfinite(o.residual_px)) residuals.push_back(o.residual_px);
  }
  if (residuals.empty()) {
    for (const ScenePoint& p : rec.points) {
      if (std::isfinite(p.reproj_px)) residuals.push_back(p.reproj_px);
    }
  }
  if (!std::isfinite(mean_px)) mean_px = mean(residuals);
  if (!std::isfinite(median_px)) median_px = median(residuals);
}

namespace {

// summary.json "distortion": where k1, k2 come from, and --distortion auto's trial.
void writeDistortion(JsonWriter& j, const Reconstruction& rec) {
  const DistortionTrial& trial = rec.distortion_trial;
  j.key("distortion");
  j.beginObject();
  j.field("source", distortionSourceName(rec.distortion_source));
  j.field("k1", rec.intrinsics.k1);
  j.field("k2", rec.intrinsics.k2);
  j.field("tried", trial.tried);
  if (trial.tried) {
    j.field("trial_views", trial.views);
    j.field("trial_k1", trial.k1);
    j.field("trial_k2", trial.k2);
    j.field("trial_max_displacement_px", trial.max_displacement_px);
    j.field("trial_median_before_px", trial.median_before_px);
    j.field("trial_median_after_px", trial.median_after_px);
  }
  j.field("reregistered", trial.reregistered);
  if (trial.reregistered) {
    j.field("reregistration_kept", trial.reregistration_kept);
    j.field("first_registration_median_px", trial.first_registration_median_px);
    j.field("reregistration_median_px", trial.reregistration_median_px);
  }
  j.endObject();
}

}  // namespace

std::string formatSummaryJson(const Reconstruction& rec) { return formatSummaryJson(rec, {}); }

std::string formatSummaryJson(const Reconstruction& rec,
                              const std::vector<std::string>& more_files) {
  int solved = 0;
  int keyframes = 0;
  for (const SolvedCamera& c : rec.cameras) {
    solved += c.solved ? 1 : 0;
    keyframes += (c.solved && c.keyframe) ? 1 : 0;
  }
  int finite_points = 0;
  for (const ScenePoint& p : rec.points) finite_points += p.X.allFinite() ? 1 : 0;
  double mean_px = 0.0;
  double median_px = 0.0;
  reprojectionStatistics(rec, mean_px, median_px);
  const CameraIntrinsics& k = rec.intrinsics;

  JsonWriter j;
  j.beginObject();
  j.field("status", rec.status);
  if (!rec.message.empty()) j.field("message", rec.message);
  if (!rec.interrupted_by.empty()) {
    j.key("interrupted");
    j.beginObject();
    j.field("signal", rec.interrupted_by);
    j.field("stage", rec.interrupted_stage);
    if (rec.solve_status.empty()) {
      j.key("solve_status");
      j.null();
    } else {
      j.field("solve_status", rec.solve_status);
    }
    j.endObject();
  }
  j.field("frames", rec.frames);
  j.field("skipped_frames", rec.skipped_frames);
  j.field("solved_frames", solved);
  j.field("keyframes", keyframes);
  if (!rec.frame_ranges.empty()) {
    // The frames named as the exports name them when their file names are known.
    const auto name = [&](int64_t f) -> const std::string* {
      return f >= 0 && static_cast<std::size_t>(f) < rec.frame_names.size()
                 ? &rec.frame_names[static_cast<std::size_t>(f)]
                 : nullptr;
    };
    for (const bool solved_runs : {true, false}) {
      j.key(solved_runs ? "solved_ranges" : "unsolved_ranges");
      j.beginArray();
      for (const FrameRangeEntry& r : rec.frame_ranges) {
        if (r.solved != solved_runs) continue;
        j.beginObject();
        j.field("first", r.first);
        j.field("last", r.last);
        j.field("frames", r.last - r.first + 1);
        if (const std::string* n = name(r.first)) j.field("first_name", *n);
        if (const std::string* n = name(r.last)) j.field("last_name", *n);
        if (!r.solved) {
          j.field("cause", r.cause);
          j.field("reason", r.reason);
        }
        j.endObject();
      }
      j.endArray();
    }
  }
  j.field("focal_px", k.fx);
  j.field("focal_source", rec.focal_source);
  j.field("focal_observable", rec.focal_observable);
  if (rec.focal_given_px > 0.0) {
    j.field("focal_refined", true);
    j.field("focal_given_px", rec.focal_given_px);
  }
  if (rec.readout_source != ReadoutSource::kNone) {
    j.key("rolling_shutter");
    j.beginObject();
    j.field("readout_ms", rec.readout_ms);
    if (rec.fps > 0.0) {  // the rate readout_ms is at, as rolling_shutter.txt says
      j.field("readout_frames", rec.readout_ms * rec.fps / 1000.0);
      j.field("fps", rec.fps);
    }
    j.field("readout_source", readoutSourceName(rec.readout_source));
    j.field("readout_observable", rec.readout_observable);
    if (rec.readout_source == ReadoutSource::kEstimated) {
      j.field("readout_std_error_ms", rec.readout_std_error_ms);
      j.field("readout_applied", rec.readout_applied);
    }
    j.field("reference_row", rec.readout_reference_row);
    j.field("rms_before_px", rec.readout_rms_before_px);
    j.field("rms_after_px", rec.readout_rms_after_px);
    j.field("ba_iterations", rec.readout_ba_iterations);
    j.endObject();
  }
  writeDistortion(j, rec);
  if (rec.row_misfit.frames_tested > 0) {
    const RowMisfit& m = rec.row_misfit;
    j.key("row_misfit");
    j.beginObject();
    j.field("misfit", m.misfit);
    j.field("frames_tested", m.frames_tested);
    j.field("frames_sheared", m.frames_sheared);
    j.field("median_shear_px", m.median_shear_px);
    j.field("p90_shear_px", m.p90_shear_px);
    j.field("max_shear_px", m.max_shear_px);
    j.field("max_shear_frame", m.max_shear_frame);
    j.endObject();
  }
  if (rec.centre_sd_steps >= 0.0) {
    j.key("centre_uncertainty");
    j.beginObject();
    j.field("sd_steps", rec.centre_sd_steps);
    j.field("limit_steps", rec.centre_sd_limit_steps);
    j.field("sd_percent_of_path", rec.centre_sd_percent);
    j.endObject();
  }
  if (rec.view_pairs_checked >= 0) {
    j.key("view_pair_check");
    j.beginObject();
    j.field("pairs_checked", rec.view_pairs_checked);
    j.key("contradicted");
    j.beginArray();
    for (const ViewPairContradiction& c : rec.contradicted_view_pairs) {
      j.beginObject();
      j.field("a", c.a);
      j.field("b", c.b);
      j.field("matches", c.matches);
      j.field("best_inliers", c.best_inliers);
      j.field("solve_inliers", c.solve_inliers);
      j.endObject();
    }
    j.endArray();
    j.endObject();
  }
  if (rec.tripod_iterations >= 0) {
    j.key("tripod_adjustment");
    j.beginObject();
    j.field("rms_before_px", rec.tripod_rms_before_px);
    j.field("rms_after_px", rec.tripod_rms_after_px);
    j.field("iterations", rec.tripod_iterations);
    j.field("rows_modelled", rec.tripod_rows_modelled);
    j.endObject();
  }
  j.field("motion", rec.motion);
  if (!rec.matcher.empty()) j.field("matcher", rec.matcher);
  j.field("mean_reproj_px", mean_px);
  j.field("median_reproj_px", median_px);
  j.field("points", finite_points);
  j.field("observations", static_cast<int64_t>(rec.observations.size()));
  int64_t outliers = 0;
  for (const PointObservation& o : rec.observations) outliers += o.outlier ? 1 : 0;
  j.field("outlier_observations", outliers);
  // The COLMAP model's own counts (colmap model_analyzer prints the same numbers).
  const ColmapCounts colmap = colmapCounts(rec);
  j.key("colmap");
  j.beginObject();
  j.field("images", colmap.images);
  j.field("points", colmap.points);
  j.field("observations", colmap.observations);
  j.field("mean_error_px", colmap.mean_error_px);
  j.endObject();
  j.key("seconds");
  j.beginObject();
  for (const auto& [stage, secs] : rec.seconds.stages) j.field(stage, secs);
  j.field("total", rec.seconds.total);
  j.endObject();
  j.key("intrinsics");
  j.beginObject();
  j.field("fx", k.fx);
  j.field("fy", k.fy);
  j.field("cx", k.cx);
  j.field("cy", k.cy);
  j.field("width", k.width);
  j.field("height", k.height);
  j.field("k1", k.k1);
  j.field("k2", k.k2);
  j.endObject();
  j.key("scene_frame");
  j.beginObject();
  j.field("origin", rec.origin);
  j.field("plane_found", rec.plane_found);
  if (!rec.origin_note.empty()) j.field("note", rec.origin_note);
  // Ground frames have +z up; the first-camera frame keeps the camera axes (-y up).
  j.field("up", std::string(rec.ground != "none" ? "+z" : "-y"));
  j.field("ground", rec.ground);
  j.field("up_confidence", rec.up_confidence);
  j.field("up_spread_deg", rec.up_spread_deg);
  j.field("plane_up_angle_deg", rec.plane_up_angle_deg);
  if (!rec.object.placement.empty()) {
    const AugmentedObject& o = rec.object;
    j.key("object");
    j.beginObject();
    j.field("placement", o.placement);
    j.key("at");
    j.beginArray();
    for (int a = 0; a < 3; ++a) j.value(o.at[a]);
    j.endArray();
    j.field("scale", o.scale);
    j.field("height", o.height);
    j.field("solved_frames", o.solved_frames);
    j.field("visible_frames", o.visible_frames);
    j.field("median_coverage", o.median_coverage);
    j.field("upright_cosine_median", o.upright_cosine_median);
    j.endObject();
  }
  j.endObject();
  if (!rec.focal_fallback.empty()) j.field("focal_fallback", rec.focal_fallback);
  if (!rec.focal_profile.empty()) {
    j.key("focal_profile");
    j.beginArray();
    for (const FocalProfileEntry& f : rec.focal_profile) {
      j.beginObject();
      j.field("start_px", f.start_px);
      j.field("focal_px", f.focal_px);
      j.field("refined", f.refined);
      j.field("median_reproj_px", f.median_reproj_px);
      j.field("solved_frames", f.solved_frames);
      j.endObject();
    }
    j.endArray();
  }
  j.key("focal_estimates");
  j.beginArray();
  for (const FocalEstimate& f : rec.focal_estimates) {
    j.beginObject();
    j.field("frame_a", f.frame_a);
    j.field("frame_b", f.frame_b);
    j.field("focal_px", f.focal_px);
    j.field("coherent", f.coherent);
    j.endObject();
  }
  j.endArray();
  j.key("files");
  j.beginArray();
  for (const std::string& f : rec.files) j.value(f);
  for (const std::string& f : more_files) j.value(f);
  j.endArray();
  j.key("cameras");
  j.beginArray();
  for (const SolvedCamera& c : rec.cameras) {
    j.beginObject();
    j.field("frame", c.frame);
    j.field("solved", c.solved);
    j.field("keyframe", c.keyframe);
    j.field("inliers", c.inliers);
    j.field("features", c.features);
    j.field("mean_reproj_px", c.mean_reproj_px);
    j.endObject();
  }
  j.endArray();
  j.endObject();
  return j.text();
}

}  // namespace epitrack::io
