// DescriptorTracker on rendered key frames with exact ground truth: an orbit subsampled to one
// frame in 24 (6 degrees, 0.63 m between key frames at 6 m: 60-120 px of image motion, beyond what
// LK bridges), matches checked against the true corner projections (landmarks), tracks chained
// over non-adjacent frames, and the key-frame solve against the true poses.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <numeric>
#include <random>
#include <set>
#include <vector>

#include <Eigen/Geometry>

#include "algo/image/image.hpp"
#include "algo/matching/descriptor_tracker.hpp"
#include "algo/sfm/solver.hpp"
#include "hal/io/text_formats.hpp"
#include "tools/eval/trajectory_metrics.hpp"
#include "tools/synth/synthetic_sequence.hpp"

using epitrack::DescriptorTracker;
using epitrack::DescriptorTrackerOptions;
using epitrack::Image;
using epitrack::TrackTable;

namespace {

constexpr int kKeyframes = 14;
constexpr int kSpacing = 24;  // orbit frames (0.25 deg each) between key frames

struct KeyframeClip {
  epitrack::synth::SynthOptions options;
  std::vector<Image<uint8_t>> frames;
  std::vector<std::vector<epitrack::synth::LandmarkObservation>> landmarks;
  std::vector<epitrack::synth::Pose> poses;
};

const KeyframeClip& keyframeClip() {
  static const KeyframeClip clip = [] {
    KeyframeClip c;
    c.options.kind = epitrack::synth::SceneKind::kOrbit;
    c.options.frames = kKeyframes * kSpacing;
    c.options.width = 640;
    c.options.height = 480;
    c.options.focal = 500.0;
    c.options.target_wander = 0.5;
    c.options.seed = 3;
    const epitrack::synth::SyntheticSequence seq(c.options);
    epitrack::synth::FrameRenderer renderer(seq);
    c.frames.resize(kKeyframes);
    c.landmarks.resize(kKeyframes);
    for (int k = 0; k < kKeyframes; ++k) {
      renderer.render(k * kSpacing, c.frames[static_cast<std::size_t>(k)]);
      seq.visibleLandmarks(k * kSpacing, c.landmarks[static_cast<std::size_t>(k)]);
      c.poses.push_back(seq.pose(k * kSpacing));
    }
    return c;
  }();
  return clip;
}

// The landmark within `radius` px of (x, y) in key frame k, or -1.
int landmarkAt(const KeyframeClip& clip, int k, double x, double y, double radius = 1.5) {
  int best = -1;
  double best_d = radius;
  for (const auto& l : clip.landmarks[static_cast<std::size_t>(k)]) {
    const double d = std::hypot(l.x - x, l.y - y);
    if (d < best_d) {
      best_d = d;
      best = l.id;
    }
  }
  return best;
}

struct Precision {
  int checked = 0;  // consecutive observations of a track both on a landmark
  int correct = 0;  // ... on the same landmark
  int tracks_3plus = 0;
  int gap_tracks = 0;  // tracks that skip a frame (chained over a non-adjacent match)
};

Precision measure(const KeyframeClip& clip, const TrackTable& t) {
  Precision p;
  for (int k = 0; k < t.trackCount(); ++k) {
    const auto idx = t.track(k);
    if (idx.size() >= 3) ++p.tracks_3plus;
    int prev_id = -1, prev_frame = -1;
    for (const int i : idx) {
      const auto& o = t.observations()[static_cast<std::size_t>(i)];
      if (prev_frame >= 0 && o.frame > prev_frame + 1) ++p.gap_tracks;
      const int id = landmarkAt(clip, o.frame, o.x, o.y);
      if (id >= 0 && prev_id >= 0) {
        ++p.checked;
        p.correct += id == prev_id ? 1 : 0;
      }
      prev_id = id;
      prev_frame = o.frame;
    }
  }
  return p;
}

void trackClip(const KeyframeClip& clip, const DescriptorTrackerOptions& o, TrackTable& t,
               DescriptorTracker*& out, std::unique_ptr<DescriptorTracker>& holder) {
  holder =
      std::make_unique<DescriptorTracker>(o, clip.options.width, clip.options.height, kKeyframes);
  for (const auto& f : clip.frames)
    REQUIRE(holder->addFrame(f.constView()) == DescriptorTracker::Status::kOk);
  holder->buildTracks(t);
  out = holder.get();
}

}  // namespace

TEST_CASE("DescriptorTracker: key frames of a rendered orbit, matches against the landmarks",
          "[matching][keyframes][slow]") {
  const KeyframeClip& clip = keyframeClip();
  for (const bool known_k : {false, true}) {
    INFO((known_k ? "E-RANSAC (intrinsics known)" : "F-RANSAC"));
    DescriptorTrackerOptions o;
    if (known_k) {
      o.focal_px = clip.options.focal;
      o.cx = (clip.options.width - 1) * 0.5;
      o.cy = (clip.options.height - 1) * 0.5;
    }
    TrackTable t;
    DescriptorTracker* tr = nullptr;
    std::unique_ptr<DescriptorTracker> holder;
    trackClip(clip, o, t, tr, holder);
    // Every adjacent pair verified; no track holds two features of one frame.
    int adjacent = 0, verified = 0;
    for (const auto& p : tr->pairs()) {
      if (p.frame_b != p.frame_a + 1) continue;
      ++adjacent;
      verified += p.verified ? 1 : 0;
    }
    CHECK(adjacent == kKeyframes - 1);
    CHECK(verified == adjacent);
    for (int k = 0; k < t.trackCount(); ++k) {
      std::set<int> frames;
      for (const int i : t.track(k))
        frames.insert(t.observations()[static_cast<std::size_t>(i)].frame);
      REQUIRE(frames.size() == t.track(k).size());
    }
    const Precision p = measure(clip, t);
    const double precision = static_cast<double>(p.correct) / std::max(1, p.checked);
    std::printf(
        "keyframes %s: %d tracks (%d of 3+ frames, %d chained over a gap), %zu "
        "observations; precision %.4f (%d of %d consecutive observations on one landmark)\n",
        known_k ? "E" : "F", t.trackCount(), p.tracks_3plus, p.gap_tracks, t.observations().size(),
        precision, p.correct, p.checked);
    CHECK(p.checked >= 1500);
    CHECK(precision >= 0.98);
    CHECK(p.tracks_3plus >= 400);
    CHECK(p.gap_tracks >= 20);
  }
}

TEST_CASE("Key-frame solve of the rendered orbit from descriptor tracks", "[matching][keyframes]") {
  const KeyframeClip& clip = keyframeClip();
  DescriptorTrackerOptions o;
  o.focal_px = clip.options.focal;
  o.cx = (clip.options.width - 1) * 0.5;
  o.cy = (clip.options.height - 1) * 0.5;
  TrackTable t;
  DescriptorTracker* tr = nullptr;
  std::unique_ptr<DescriptorTracker> holder;
  trackClip(clip, o, t, tr, holder);
  epitrack::SolverOptions so;
  so.focal_px = clip.options.focal;
  so.keyframe_collection = true;
  epitrack::Solver s(t, clip.options.width, clip.options.height, so);
  REQUIRE(s.calibrate());
  REQUIRE(s.initialize());
  REQUIRE(s.registerFrames());
  REQUIRE(s.finalize());
  CHECK(s.solvedFrames() == kKeyframes);
  std::vector<epitrack::hal::TrajectoryEntry> gt, est;
  for (int k = 0; k < kKeyframes; ++k) {
    epitrack::hal::TrajectoryEntry g;
    g.t = k;
    g.position = clip.poses[static_cast<std::size_t>(k)].t_wc;
    g.rotation = Eigen::Quaterniond(clip.poses[static_cast<std::size_t>(k)].R_wc);
    gt.push_back(g);
    const auto& f = s.frames()[static_cast<std::size_t>(k)];
    if (!f.solved) continue;
    epitrack::hal::TrajectoryEntry e;
    e.t = k;
    e.position = f.pose.centre();
    e.rotation = Eigen::Quaterniond(f.pose.R_cw.transpose());
    est.push_back(e);
  }
  epitrack::eval::TrajectoryMetrics m;
  std::string error;
  REQUIRE(epitrack::eval::evaluateTrajectory(gt, est, 0.01, m, error));
  double mean = 0.0, median = 0.0;
  s.reprojectionStats(mean, median);
  std::printf(
      "keyframe orbit solve: %d/%d frames, ATE %.5f of the path, rotation %.3f deg mean, "
      "reprojection %.3f px mean\n",
      s.solvedFrames(), kKeyframes, m.ate_rmse_rel, m.rot_err_deg_mean, mean);
  CHECK(m.ate_rmse_rel < 1e-3);
  CHECK(m.rot_err_deg_mean < 0.2);
}

TEST_CASE("View graph: the rendered key frames in shuffled order, every pair matched, all register",
          "[matching][keyframes][slow]") {
  // Issue 22: a photo set whose file order is not the order of the views. The 14 key frames in a
  // seeded random order, matched pair by pair (the view graph): every view registers.
  const KeyframeClip& clip = keyframeClip();
  std::vector<int> order(kKeyframes);
  std::iota(order.begin(), order.end(), 0);
  std::mt19937 rng(22);
  std::shuffle(order.begin(), order.end(), rng);
  const auto solveShuffled = [&](int window, int& solved, double& ate) {
    DescriptorTrackerOptions o;
    o.focal_px = clip.options.focal;
    o.cx = (clip.options.width - 1) * 0.5;
    o.cy = (clip.options.height - 1) * 0.5;
    o.window = window;
    DescriptorTracker tr(o, clip.options.width, clip.options.height, kKeyframes);
    for (const int k : order)
      REQUIRE(tr.addFrame(clip.frames[static_cast<std::size_t>(k)].constView()) ==
              DescriptorTracker::Status::kOk);
    TrackTable t;
    tr.buildTracks(t);
    for (int k = 0; k < t.trackCount(); ++k) {  // no track holds two features of one view
      std::set<int> frames;
      for (const int i : t.track(k))
        frames.insert(t.observations()[static_cast<std::size_t>(i)].frame);
      REQUIRE(frames.size() == t.track(k).size());
    }
    epitrack::SolverOptions so;
    so.focal_px = clip.options.focal;
    so.keyframe_collection = true;
    epitrack::Solver s(t, clip.options.width, clip.options.height, so);
    solved = 0;
    ate = 1.0;
    if (!s.calibrate() || !s.initialize() || !s.registerFrames() || !s.finalize()) return;
    solved = s.solvedFrames();
    std::vector<epitrack::hal::TrajectoryEntry> gt, est;
    for (int i = 0; i < kKeyframes; ++i) {
      const auto& truth = clip.poses[static_cast<std::size_t>(order[static_cast<std::size_t>(i)])];
      epitrack::hal::TrajectoryEntry g;
      g.t = i;
      g.position = truth.t_wc;
      g.rotation = Eigen::Quaterniond(truth.R_wc);
      gt.push_back(g);
      const auto& f = s.frames()[static_cast<std::size_t>(i)];
      if (!f.solved) continue;
      epitrack::hal::TrajectoryEntry e;
      e.t = i;
      e.position = f.pose.centre();
      e.rotation = Eigen::Quaterniond(f.pose.R_cw.transpose());
      est.push_back(e);
    }
    epitrack::eval::TrajectoryMetrics m;
    std::string error;
    if (est.size() >= 3 && epitrack::eval::evaluateTrajectory(gt, est, 0.01, m, error))
      ate = m.ate_rmse_rel;
  };
  int chain_solved = 0, graph_solved = 0;
  double chain_ate = 0.0, graph_ate = 0.0;
  solveShuffled(2, chain_solved, chain_ate);
  solveShuffled(DescriptorTrackerOptions::kAllPairs, graph_solved, graph_ate);
  std::printf(
      "shuffled key frames: previous 2 files %d/%d registered; every pair %d/%d, ATE %.5f of "
      "the path\n",
      chain_solved, kKeyframes, graph_solved, kKeyframes, graph_ate);
  // Measured (seed 22): the previous two files also register 14/14 here (the 14 views span 84
  // degrees, so files two apart still overlap, and the relative-pose fallback bridges the rest);
  // the real templeRing ring is the case the chain misses (tests/matching/keyframe_sequences_test).
  CHECK(graph_solved == kKeyframes);
  CHECK(graph_ate < 1e-3);
}
