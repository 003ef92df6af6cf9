#include <catch2/catch.hpp>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "algo/tracking/feature_tracker.hpp"
#include "hal/frame_source.hpp"
#include "hal/io/text_formats.hpp"
#include "tests/support/test_support.hpp"
#include "tests/tracker/orbit_clip.hpp"

// The tracker on the real sequences of ../shared/data (skipped visibly when absent): tracks must
// survive (length figures) and, where there is ground truth, be consistent with the true relative
// camera motion (epipolar geometry from the ground-truth poses and intrinsics).

namespace {

using epitrack::FeatureTracker;
using epitrack::FeatureTrackerOptions;
namespace hal = epitrack::hal;

struct Observation {
  int frame;
  float x;
  float y;
};

struct RealRun {
  int frames = 0;
  std::map<int32_t, std::vector<Observation>> tracks;  // by id
  double mean_live = 0.0;
  double mean_aged_5 = 0.0;  // live tracks per frame at least 5 frames old
};

RealRun trackSequence(const std::string& name, int max_frames) {
  RealRun run;
  std::string error;
  auto source =
      hal::openFrameSource(epitrack::test::sharedDataDir() + "/" + name + "/frames", {}, error);
  REQUIRE(source != nullptr);
  std::unique_ptr<FeatureTracker> tracker;
  hal::Frame frame;
  long live = 0, aged = 0;
  while (run.frames < max_frames && source->next(frame) == hal::FrameStatus::kOk) {
    if (!tracker) {
      tracker = std::make_unique<FeatureTracker>(FeatureTrackerOptions{}, frame.luma.width,
                                                 frame.luma.height);
    }
    REQUIRE(tracker->track(frame.luma) == FeatureTracker::Status::kOk);
    for (const auto& f : tracker->features()) {
      run.tracks[f.id].push_back(Observation{run.frames, f.x, f.y});
      ++live;
      aged += f.age >= 5 ? 1 : 0;
    }
    ++run.frames;
  }
  REQUIRE(run.frames > 0);
  run.mean_live = static_cast<double>(live) / run.frames;
  run.mean_aged_5 = static_cast<double>(aged) / run.frames;
  return run;
}

int countAtLeast(const RealRun& run, std::size_t length) {
  int n = 0;
  for (const auto& [id, obs] : run.tracks) n += obs.size() >= length ? 1 : 0;
  return n;
}

/// Fundamental matrix from camera i to camera j of ground-truth poses T_wc (x_j^T F x_i = 0).
Eigen::Matrix3d groundTruthF(const hal::TrajectoryEntry& pi, const hal::TrajectoryEntry& pj,
                             const epitrack::CameraIntrinsics& k) {
  const Eigen::Matrix3d R_wi = pi.rotation.toRotationMatrix();
  const Eigen::Matrix3d R_wj = pj.rotation.toRotationMatrix();
  const Eigen::Matrix3d R_ji = R_wj.transpose() * R_wi;
  const Eigen::Vector3d t_ji = R_wj.transpose() * (pi.position - pj.position);
  Eigen::Matrix3d tx;
  tx << 0, -t_ji.z(), t_ji.y(), t_ji.z(), 0, -t_ji.x(), -t_ji.y(), t_ji.x(), 0;
  Eigen::Matrix3d K;
  K << k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1;
  const Eigen::Matrix3d Ki = K.inverse();
  return Ki.transpose() * (tx * R_ji) * Ki;  // Hartley & Zisserman eq. 9.12
}

/// Sampson distance (Hartley & Zisserman eq. 11.9), in pixels.
double sampson(const Eigen::Matrix3d& F, const Observation& a, const Observation& b) {
  const Eigen::Vector3d xa(a.x, a.y, 1.0);
  const Eigen::Vector3d xb(b.x, b.y, 1.0);
  const Eigen::Vector3d Fa = F * xa;
  const Eigen::Vector3d Fb = F.transpose() * xb;
  const double e = xb.dot(Fa);
  const double d = Fa.x() * Fa.x() + Fa.y() * Fa.y() + Fb.x() * Fb.x() + Fb.y() * Fb.y();
  return std::abs(e) / std::sqrt(d);
}

/// Median Sampson distance of every track between its observations `gap` frames apart.
double medianEpipolarError(const RealRun& run, const std::string& name, int gap, int& pairs) {
  std::vector<hal::TrajectoryEntry> gt;
  epitrack::CameraIntrinsics k;
  std::string error;
  const std::string dir = epitrack::test::sharedDataDir() + "/" + name;
  REQUIRE(hal::readTrajectoryFile(dir + "/groundtruth.txt", gt, error));
  REQUIRE(hal::readIntrinsicsFile(dir + "/intrinsics.txt", k, error));
  std::map<int, hal::TrajectoryEntry> pose;
  for (const auto& e : gt) pose[static_cast<int>(std::lround(e.t))] = e;
  std::vector<double> errors;
  for (const auto& [id, obs] : run.tracks) {
    for (std::size_t i = 0; i + static_cast<std::size_t>(gap) < obs.size(); ++i) {
      const Observation& a = obs[i];
      const Observation& b = obs[i + static_cast<std::size_t>(gap)];
      if (pose.count(a.frame) == 0 || pose.count(b.frame) == 0) continue;
      errors.push_back(sampson(groundTruthF(pose[a.frame], pose[b.frame], k), a, b));
    }
  }
  pairs = static_cast<int>(errors.size());
  return epitrack::test::percentile(errors, 0.5);
}

// Tracks on a KITTI excerpt: long, and consistent with the ground-truth epipolar geometry.
void checkKittiTracks(const std::string& name) {
  const RealRun run = trackSequence(name, 51);
  int pairs1 = 0, pairs5 = 0;
  const double e1 = medianEpipolarError(run, name, 1, pairs1);
  const double e5 = medianEpipolarError(run, name, 5, pairs5);
  std::printf(
      "%s: %d frames, %zu tracks, %d of 5+ frames, %d of 10+, %d of 20+; live %.0f/frame, "
      "%.0f of them 5+ frames old; median Sampson distance to the GT epipolar geometry %.3f px "
      "(1 frame apart, %d pairs), %.3f px (5 apart, %d pairs)\n",
      name.c_str(), run.frames, run.tracks.size(), countAtLeast(run, 5), countAtLeast(run, 10),
      countAtLeast(run, 20), run.mean_live, run.mean_aged_5, e1, pairs1, e5, pairs5);
  CHECK(countAtLeast(run, 10) >= 200);
  CHECK(run.mean_aged_5 >= 50.0);
  CHECK(e1 < 1.0);
  CHECK(e5 < 1.5);
}

}  // namespace

// One test case per sequence: a missing sequence skips only its own case (the skip is printed
// before anything is asserted), never hiding the other's failure.
TEST_CASE("The tracker keeps long tracks on the real KITTI highway excerpt", "[tracker][real]") {
  if (!epitrack::test::haveSharedSequence("kitti_highway_excerpt")) return;
  checkKittiTracks("kitti_highway_excerpt");
}

TEST_CASE("The tracker keeps long tracks on the real KITTI seq06 excerpt", "[tracker][real]") {
  if (!epitrack::test::haveSharedSequence("kitti_seq06_excerpt")) return;
  checkKittiTracks("kitti_seq06_excerpt");
}

TEST_CASE("The tracker keeps most features through the small-motion castle clip",
          "[tracker][real]") {
  const std::string name = "visp_castel_nogt";
  if (!epitrack::test::haveSharedSequence(name)) return;
  const RealRun run = trackSequence(name, 30);
  int whole = 0;
  for (const auto& [id, obs] : run.tracks) whole += obs.size() == 30 ? 1 : 0;
  std::printf("%s: %d frames, %zu tracks, %d through all frames, %d of 10+; live %.0f/frame\n",
              name.c_str(), run.frames, run.tracks.size(), whole, countAtLeast(run, 10),
              run.mean_live);
  CHECK(whole >= 150);
}
