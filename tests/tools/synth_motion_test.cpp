// The real-camera-motion scenes of epitrack-synth (issue 20 item 5): shake, fastpan, occlusion.
// Their output is pinned, their ground truth is checked against an independent projection of the
// written files, and their motion statistics are measured from the truth poses.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "hal/io/text_formats.hpp"
#include "tests/support/test_support.hpp"
#include "tools/synth/portable_math.hpp"
#include "tools/synth/synthetic_sequence.hpp"

namespace synth = epitrack::synth;
using epitrack::Image;

namespace {

constexpr double kRadToDeg = 180.0 / synth::kPi;

uint64_t digest(const Image<uint8_t>& img) {
  uint64_t h = 1469598103934665603ull;
  for (int y = 0; y < img.height(); ++y)
    for (int x = 0; x < img.width(); ++x) h = (h ^ img(x, y)) * 1099511628211ull;
  return h;
}

double percentileOf(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

// Per frame f in [1, frames-2], the median over the landmarks visible in f-1, f and f+1 of the
// image acceleration |x(f+1) - 2 x(f) + x(f-1)| (px/frame^2) of their true projections.
std::vector<double> imageAccelerations(const synth::SyntheticSequence& seq, int frames) {
  std::vector<std::map<int, Eigen::Vector2d>> pos(static_cast<std::size_t>(frames));
  std::vector<synth::LandmarkObservation> obs;
  for (int f = 0; f < frames; ++f) {
    seq.visibleLandmarks(f, obs);
    for (const auto& o : obs) pos[static_cast<std::size_t>(f)][o.id] = {o.x, o.y};
  }
  std::vector<double> per_frame;
  for (std::size_t f = 1; f + 1 < pos.size(); ++f) {
    std::vector<double> a;
    for (const auto& [id, p] : pos[f]) {
      const auto prev = pos[f - 1].find(id);
      const auto next = pos[f + 1].find(id);
      if (prev == pos[f - 1].end() || next == pos[f + 1].end()) continue;
      a.push_back((next->second - 2.0 * p + prev->second).norm());
    }
    REQUIRE(a.size() > 50);
    per_frame.push_back(percentileOf(a, 0.5));
  }
  return per_frame;
}

}  // namespace

TEST_CASE("The motion scenes render deterministically (pinned digests)",
          "[synth][determinism][motion]") {
  synth::SynthOptions o;
  o.width = 320;
  o.height = 240;
  o.focal = 280;
  o.frames = 10;
  // A deliberate change of a scene or of the renderer updates these, and says so in its commit.
  const std::pair<synth::SceneKind, uint64_t> pinned[] = {
      {synth::SceneKind::kShake, 7970244165997797962ull},
      {synth::SceneKind::kFastPan, 3993830472333655982ull},
      {synth::SceneKind::kOcclusion, 13237180337243982868ull},
  };
  for (const auto& [kind, expected] : pinned) {
    o.kind = kind;
    const synth::SyntheticSequence a(o);
    const synth::SyntheticSequence b(o);
    synth::FrameRenderer ra(a);
    synth::FrameRenderer rb(b);
    Image<uint8_t> ia;
    Image<uint8_t> ib;
    ra.render(7, ia);
    rb.render(7, ib);
    REQUIRE(digest(ia) == digest(ib));
    INFO(synth::sceneKindName(kind) << ": FNV-1a digest " << digest(ia));
    CHECK(digest(ia) == expected);
  }
}

TEST_CASE("The motion scenes' written ground truth reprojects onto their landmark files",
          "[synth][landmarks][motion]") {
  const std::string exe = epitrack::test::binaryPath("tools/synth/epitrack-synth");
  for (const char* scene : {"shake", "fastpan", "occlusion"}) {
    epitrack::test::TempDir dir("synth-motion-gt");
    REQUIRE(epitrack::test::run(exe + " --scene " + scene +
                                " --frames 12 --size 320x240 --focal 280 --quiet --out " +
                                dir.path()) == 0);
    std::vector<epitrack::hal::TrajectoryEntry> gt;
    std::string err;
    REQUIRE(epitrack::hal::readTrajectoryFile(dir.file("groundtruth.txt"), gt, err));
    REQUIRE(gt.size() == 12);
    epitrack::CameraIntrinsics k;
    REQUIRE(epitrack::hal::readIntrinsicsFile(dir.file("intrinsics.txt"), k, err));
    std::map<int, Eigen::Vector3d> points;
    std::ifstream pts(dir.file("points3d.txt"));
    std::string line;
    while (std::getline(pts, line)) {
      if (line.empty() || line[0] == '#') continue;
      int id = 0;
      double x = 0, y = 0, z = 0;
      REQUIRE(std::sscanf(line.c_str(), "%d %lf %lf %lf", &id, &x, &y, &z) == 4);
      points[id] = {x, y, z};
    }
    std::ifstream lm(dir.file("landmarks.txt"));
    double worst = 0.0;
    int lines = 0;
    while (std::getline(lm, line)) {
      if (line.empty() || line[0] == '#') continue;
      int f = 0, id = 0;
      double x = 0, y = 0;
      REQUIRE(std::sscanf(line.c_str(), "%d %d %lf %lf", &f, &id, &x, &y) == 4);
      const auto& e = gt[static_cast<std::size_t>(f)];
      const Eigen::Vector3d pc =
          e.rotation.toRotationMatrix().transpose() * (points.at(id) - e.position);
      REQUIRE(pc.z() > 0.0);
      const Eigen::Vector2d px(k.fx * pc.x() / pc.z() + k.cx, k.fy * pc.y() / pc.z() + k.cy);
      worst = std::max(worst, (px - Eigen::Vector2d(x, y)).norm());
      ++lines;
    }
    std::printf("%s: %d landmark lines, worst reprojection %.2e px\n", scene, lines, worst);
    INFO(scene << ": " << lines << " landmark lines, worst reprojection " << worst << " px");
    REQUIRE(lines > 12 * 100);
    // The files round to 1e-4 px, 1e-6 m and 1e-9 in the quaternion.
    CHECK(worst < 2e-3);
  }
}

TEST_CASE("The shake scene has hand-held jitter as issue 20 states it", "[synth][motion]") {
  // 640x480, focal 600, 200 frames at 30 fps: the reproduction.
  synth::SynthOptions o;
  o.kind = synth::SceneKind::kShake;
  o.width = 640;
  o.height = 480;
  o.focal = 600;
  o.frames = 200;
  const synth::SyntheticSequence seq(o);
  synth::TrajectoryParams smooth = seq.trajectory();
  smooth.shake_deg = 0.0;
  // The jitter rotation: the shaken orientation relative to the same path without shake.
  std::vector<Eigen::Vector3d> jitter;
  double max_angle = 0.0;
  double sum2 = 0.0;
  for (int f = 0; f < o.frames; ++f) {
    const Eigen::Matrix3d R = seq.pose(f).R_wc;
    const Eigen::Matrix3d R0 = synth::trajectoryPose(smooth, f).R_wc;
    const Eigen::AngleAxisd aa(R0.transpose() * R);
    jitter.push_back(aa.angle() * aa.axis());
    max_angle = std::max(max_angle, aa.angle() * kRadToDeg);
    sum2 += aa.angle() * aa.angle();
  }
  const double rms_deg = std::sqrt(sum2 / o.frames) * kRadToDeg;
  std::printf("shake jitter: max %.2f deg, rms %.2f deg\n", max_angle, rms_deg);
  INFO("jitter: max " << max_angle << " deg, rms " << rms_deg << " deg");
  CHECK(max_angle >= 1.0);
  CHECK(max_angle <= 3.0);
  CHECK(rms_deg >= 0.5);
  // Spectrum of the pitch and yaw jitter (DFT over the clip): most power within 1-8 Hz at 30 fps.
  double in_band = 0.0;
  double total = 0.0;
  for (int axis = 0; axis < 2; ++axis) {
    for (int k = 1; k < o.frames / 2; ++k) {
      std::complex<double> c = 0.0;
      for (int f = 0; f < o.frames; ++f) {
        c += jitter[static_cast<std::size_t>(f)][axis] *
             std::polar(1.0, -2.0 * synth::kPi * k * f / o.frames);
      }
      const double hz = 30.0 * k / o.frames;
      total += std::norm(c);
      if (hz >= 0.9 && hz <= 8.1) in_band += std::norm(c);
    }
  }
  std::printf("shake jitter power within 1-8 Hz: %.1f %%\n", 100.0 * in_band / total);
  INFO("power within 1-8 Hz: " << 100.0 * in_band / total << " %");
  CHECK(in_band >= 0.8 * total);
  // Image accelerations of the true corner projections: 5-20 px/frame^2, jerks at the top.
  const std::vector<double> acc = imageAccelerations(seq, o.frames);
  const double median = percentileOf(acc, 0.5);
  const double p95 = percentileOf(acc, 0.95);
  const double peak = percentileOf(acc, 1.0);
  std::printf("shake image acceleration per frame: median %.2f, p95 %.2f, max %.2f px/frame^2\n",
              median, p95, peak);
  INFO("image acceleration per frame: median " << median << ", p95 " << p95 << ", max " << peak
                                               << " px/frame^2");
  CHECK(median >= 5.0);
  CHECK(p95 <= 20.0);
  CHECK(peak >= 12.0);
  CHECK(peak <= 25.0);
  // The slow sideways drift: the centre moves 0.6-1 m over the clip, mostly sideways.
  const Eigen::Vector3d drift = seq.pose(o.frames - 1).t_wc - seq.pose(0).t_wc;
  CHECK(drift.norm() > 0.6);
  CHECK(drift.norm() < 1.0);
  CHECK(std::abs(drift.normalized().dot(seq.pose(0).R_wc.col(0))) > 0.9);
  // --shake scales the jitter.
  o.shake_deg = 1.0;
  const synth::SyntheticSequence half(o);
  double max_half = 0.0;
  for (int f = 0; f < o.frames; ++f) {
    const Eigen::AngleAxisd aa(synth::trajectoryPose(smooth, f).R_wc.transpose() *
                               half.pose(f).R_wc);
    max_half = std::max(max_half, aa.angle() * kRadToDeg);
  }
  std::printf("shake --shake 1: max %.2f deg\n", max_half);
  CHECK(max_half == Approx(max_angle / 2.0).epsilon(0.02));
}

TEST_CASE("The fast pan turns 2-4 deg/frame with reversals and a small translation",
          "[synth][motion]") {
  synth::TrajectoryParams t;
  t.kind = synth::SceneKind::kFastPan;
  t.frames = 200;
  double peak = 0.0;
  int fast = 0;
  int reversals = 0;
  double previous_yaw_rate = 0.0;
  for (int f = 1; f < t.frames; ++f) {
    const synth::Pose a = synth::trajectoryPose(t, f - 1);
    const synth::Pose b = synth::trajectoryPose(t, f);
    const double deg = Eigen::AngleAxisd(a.R_wc.transpose() * b.R_wc).angle() * kRadToDeg;
    peak = std::max(peak, deg);
    fast += deg >= 2.0;
    // Yaw rate about world z from the optical axis' heading.
    const double ha = std::atan2(a.R_wc(0, 2), a.R_wc(1, 2));
    const double hb = std::atan2(b.R_wc(0, 2), b.R_wc(1, 2));
    const double rate = hb - ha;
    if (f > 1 && rate * previous_yaw_rate < 0.0) ++reversals;
    previous_yaw_rate = rate;
  }
  std::printf("fastpan: peak %.2f deg/frame, %d frames >= 2 deg/frame, %d reversals\n", peak, fast,
              reversals);
  INFO("peak " << peak << " deg/frame, " << fast << " frames >= 2 deg/frame, " << reversals
               << " reversals");
  CHECK(peak >= 3.0);
  CHECK(peak <= 4.0);
  CHECK(fast >= 100);
  CHECK(reversals >= 2);
  const double moved =
      (synth::trajectoryPose(t, 199).t_wc - synth::trajectoryPose(t, 0).t_wc).norm();
  CHECK(moved > 2.0);  // 2.4 m sideways: a walking pan, solvable with 6 DoF
}

TEST_CASE("The occlusion scene occludes far more corners per frame than the orbit",
          "[synth][motion]") {
  // An occlusion event: a corner visible in frame f whose projection in f+1 is still inside the
  // image and in front of its face, but hidden by another surface.
  const auto occlusion_rate = [](synth::SceneKind kind) {
    synth::SynthOptions o;
    o.kind = kind;
    o.width = 320;
    o.height = 240;
    o.focal = 280;
    o.frames = 60;
    const synth::SyntheticSequence seq(o);
    std::vector<synth::LandmarkObservation> obs;
    std::set<int> previous;
    int events = 0;
    int observations = 0;
    for (int f = 0; f < o.frames; ++f) {
      seq.visibleLandmarks(f, obs);
      std::set<int> now;
      for (const auto& l : obs) now.insert(l.id);
      const synth::Pose p = seq.pose(f);
      for (const int id : previous) {
        if (now.count(id) != 0) continue;
        const auto& l = seq.scene().landmarks[static_cast<std::size_t>(id)];
        const Eigen::Vector3d pc = p.R_wc.transpose() * (l.position - p.t_wc);
        Eigen::Vector2d px;
        const auto& q = seq.scene().quads[static_cast<std::size_t>(l.quad)];
        if (seq.camera().project(pc, px) && px.x() >= 0 && px.y() >= 0 && px.x() <= 319 &&
            px.y() <= 239 && (p.R_wc.transpose() * q.normal).dot(pc) < 0.0)
          ++events;
      }
      observations += static_cast<int>(obs.size());
      previous = std::move(now);
    }
    return static_cast<double>(events) / observations;
  };
  const double occlusion = occlusion_rate(synth::SceneKind::kOcclusion);
  const double orbit = occlusion_rate(synth::SceneKind::kOrbit);
  std::printf("occlusion events per observation: occlusion scene %.4f, orbit %.4f\n", occlusion,
              orbit);
  INFO("occlusion events per observation: occlusion scene " << occlusion << ", orbit " << orbit);
  CHECK(occlusion > 0.005);
  CHECK(occlusion > 4.0 * orbit);
}

TEST_CASE("synth: --orbit-speed sets the orbit's arc per frame", "[synth][motion]") {
  synth::TrajectoryParams t;
  t.kind = synth::SceneKind::kOrbit;
  t.orbit_speed_deg = 0.75;
  for (int f = 0; f < 100; f += 9) {
    const Eigen::Vector3d a = synth::trajectoryPose(t, f).t_wc;
    const Eigen::Vector3d b = synth::trajectoryPose(t, f + 1).t_wc;
    const double arc = std::atan2(b.y(), b.x()) - std::atan2(a.y(), a.x());
    REQUIRE(arc * kRadToDeg == Approx(0.75).epsilon(1e-9));
  }
}
