// The live loop's track prediction by the map (LiveMapOptions::map_prediction): each track with a
// map point is predicted by the point projected with a constant-velocity pose, and the 2D tracker
// starts LK there. On a rendered fast orbit the map's predictions must land nearer the true
// positions than the per-feature constant-velocity prediction, and the live poses with them must
// be as accurate as without.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "algo/image/image.hpp"
#include "algo/sfm/live_tracker.hpp"
#include "tools/eval/trajectory_metrics.hpp"
#include "tools/synth/synthetic_sequence.hpp"

using namespace epitrack;

namespace {

// A fast orbit: 1.2 degrees of arc a frame (about 8 px of image motion near the centre, up to
// 20 px at the sides), a wandering look-at target, sensor noise.
synth::SynthOptions fastOrbit() {
  return synth::SynthOptions{.kind = synth::SceneKind::kOrbit,
                             .frames = 90,
                             .width = 480,
                             .height = 360,
                             .focal = 420.0,
                             .noise_sigma = 1.0,
                             .target_wander = 0.5,
                             .orbit_speed_deg = 1.2};
}

// The clip's frames and, per frame, the true projections of its visible landmarks.
struct Clip {
  std::vector<Image<uint8_t>> frames;
  std::vector<std::vector<synth::LandmarkObservation>> landmarks;
};

Clip render(const synth::SyntheticSequence& seq) {
  const synth::SynthOptions& so = seq.options();
  synth::FrameRenderer renderer(seq);
  Clip clip;
  clip.landmarks.resize(static_cast<std::size_t>(so.frames));
  for (int f = 0; f < so.frames; ++f) {
    clip.frames.emplace_back(so.width, so.height);
    renderer.render(f, clip.frames.back());
    seq.visibleLandmarks(f, clip.landmarks[static_cast<std::size_t>(f)]);
  }
  return clip;
}

double percentile(std::vector<double> values, double q) {
  const auto k = static_cast<std::size_t>(q * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

struct PredictionErrors {
  std::vector<double> map_px;  // |map prediction - true position|
  std::vector<double>
      velocity_px;  // |constant-velocity image prediction - true position|, same tracks
};

struct LiveRun {
  PredictionErrors errors;
  std::vector<hal::TrajectoryEntry> gt, est;
  int tracking = 0;
  long predicted = 0;
};

// A track's last two positions (the per-feature constant-velocity prediction).
struct TrackHistory {
  int landmark = -1;             // associated at its first frame (-1: none within a pixel)
  Eigen::Vector2d offset{0, 0};  // the track's first position minus its landmark's
  int last_frame = -1;
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // positions at last_frame - 1 and last_frame
  bool two = false;
};

// A new track's landmark: the nearest within a pixel (none: -1), and the offset from it.
void associate(const std::vector<synth::LandmarkObservation>& lm, const TrackedFeature& t,
               TrackHistory& h) {
  const Eigen::Vector2d p(t.x, t.y);
  double best_d2 = 1.0;
  for (const auto& l : lm) {
    const Eigen::Vector2d offset = p - Eigen::Vector2d(l.x, l.y);
    if (offset.squaredNorm() >= best_d2) continue;
    best_d2 = offset.squaredNorm();
    h.landmark = l.id;
    h.offset = offset;
  }
}

// Compares this frame's map predictions with the true positions (the track's landmark) and with
// the per-feature constant-velocity prediction of the same tracks.
void scorePredictions(std::span<const TrackPrediction> predictions,
                      const std::map<int32_t, TrackHistory>& history, int frame,
                      const std::map<int, Eigen::Vector2d>& truth, PredictionErrors& errors) {
  for (const TrackPrediction& p : predictions) {
    const auto h = history.find(p.id);
    if (h == history.end() || !h->second.two || h->second.last_frame != frame - 1) continue;
    const auto t = truth.find(h->second.landmark);
    if (t == truth.end()) continue;
    const TrackHistory& th = h->second;
    const Eigen::Vector2d velocity(2 * th.x1 - th.x0, 2 * th.y1 - th.y0);
    // Where the track should be: its landmark, at the track's offset from it when it was found
    // (a detected corner is up to a pixel from the landmark; both predictions keep that offset).
    const Eigen::Vector2d expected = t->second + th.offset;
    errors.map_px.push_back((Eigen::Vector2d(p.x, p.y) - expected).norm());
    errors.velocity_px.push_back((velocity - expected).norm());
  }
}

LiveRun runLive(const Clip& clip, const synth::SyntheticSequence& seq, bool map_prediction) {
  const synth::SynthOptions& so = seq.options();
  FeatureTrackerOptions to = FeatureTrackerOptions{}.wholeWindow();  // the device's
  LiveMapOptions mo;
  mo.map_prediction = map_prediction;
  LiveTracker live(to, mo, CameraIntrinsics::centered(so.width, so.height, so.focal));
  std::map<int32_t, TrackHistory> history;
  LiveRun run;
  LiveFrameOutput out;
  for (int f = 0; f < so.frames; ++f) {
    const auto fi = static_cast<std::size_t>(f);
    REQUIRE(live.process(clip.frames[fi].constView(), out) == LiveTracker::Status::kOk);
    std::map<int, Eigen::Vector2d> truth;
    for (const auto& l : clip.landmarks[fi]) truth[l.id] = Eigen::Vector2d(l.x, l.y);
    scorePredictions(live.lastPredictions(), history, f, truth, run.errors);
    run.predicted += live.tracker().lastStats().predicted;
    for (const TrackedFeature& t : live.tracker().features()) {
      TrackHistory& h = history[t.id];
      if (t.age == 0) associate(clip.landmarks[fi], t, h);
      h.two = h.last_frame == f - 1;
      h.x0 = h.x1;
      h.y0 = h.y1;
      h.x1 = t.x;
      h.y1 = t.y;
      h.last_frame = f;
    }
    const auto pose = seq.pose(f);
    run.gt.push_back({static_cast<double>(f), pose.t_wc, Eigen::Quaterniond(pose.R_wc)});
    if (out.map.status != LiveStatus::kTracking) continue;
    ++run.tracking;
    const Eigen::Matrix3d R_wc = out.map.pose.R_cw.transpose();
    run.est.push_back({static_cast<double>(f), out.map.pose.centre(), Eigen::Quaterniond(R_wc)});
  }
  return run;
}

double ate(const LiveRun& run) {
  eval::TrajectoryMetrics m;
  std::string error;
  INFO(error);
  REQUIRE(eval::evaluateTrajectory(run.gt, run.est, 0.01, m, error));
  return m.ate_rmse_rel;
}

}  // namespace

TEST_CASE("The live map's track predictions beat the per-feature prediction on a fast orbit",
          "[sfm][live][slow]") {
  const synth::SynthOptions so = fastOrbit();
  const synth::SyntheticSequence seq(so);
  const Clip clip = render(seq);
  const LiveRun on = runLive(clip, seq, true);
  const LiveRun off = runLive(clip, seq, false);
  REQUIRE(on.errors.map_px.size() > 1000);
  const double map_median = percentile(on.errors.map_px, 0.5);
  const double velocity_median = percentile(on.errors.velocity_px, 0.5);
  const double map_p95 = percentile(on.errors.map_px, 0.95);
  const double velocity_p95 = percentile(on.errors.velocity_px, 0.95);
  const double ate_on = ate(on), ate_off = ate(off);
  std::printf(
      "live prediction, fast orbit: %zu predictions, error median %.3f px (per-feature %.3f), "
      "p95 %.3f px (%.3f); %d/%d frames tracking, ATE %.6f with prediction, %.6f without\n",
      on.errors.map_px.size(), map_median, velocity_median, map_p95, velocity_p95, on.tracking,
      off.tracking, ate_on, ate_off);
  // Measured (Release, x86-64): median 0.114 px against 0.149, p95 0.60 against 0.69.
  CHECK(map_median < 0.85 * velocity_median);
  CHECK(map_p95 < velocity_p95);
  // The tracks follow the predictions: most of the live tracks with a map point use one.
  CHECK(on.predicted > 100L * on.tracking / 2);
  CHECK(off.predicted == 0);
  CHECK(on.tracking >= off.tracking);
  // Measured: 0.000067 with, 0.000069 without. The live map's ATE moves by 10 % and more with
  // sub-0.01 px changes of the measurements (LK's epsilon 0.01 -> 0.003 px moved the device orbit
  // seed 1 from 0.000123 to 0.000196), so "not worse" is judged within that.
  CHECK(ate_on <= 1.1 * ate_off);
}
