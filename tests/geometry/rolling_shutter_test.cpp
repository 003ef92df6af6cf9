// The rolling-shutter camera (algo/geometry/rolling_shutter): the row a point is seen on is a
// fixed point of the projection, the global shutter is the special case line_delay = 0, and the
// resection recovers a frame's pose and readout motion where a global-shutter pose cannot fit.
#include "algo/geometry/rolling_shutter.hpp"

#include <cmath>
#include <vector>

#include <catch2/catch.hpp>

#include "algo/math/random.hpp"
#include "tests/support/seeded_random.hpp"

using namespace epitrack;

namespace {

constexpr double kDeg = M_PI / 180.0;

CameraIntrinsics camera() {
  CameraIntrinsics k = CameraIntrinsics::centered(640, 480, 600.0);
  k.k1 = -0.05;
  return k;
}

// 30 ms of readout on a 33.3 ms frame, referred to the middle row.
RollingShutter shutter30ms() { return RollingShutter::fromReadout(30.0 / 33.3, 480, 239.5); }

// A camera 5 m from a box of points around the origin, looking at it.
PoseCw framePose() {
  PoseCw pose;
  pose.R_cw = expSo3(Eigen::Vector3d(0.1, -0.2, 0.05));
  pose.t_cw = Eigen::Vector3d(0.2, -0.1, 5.0);
  return pose;
}

// Points in front of the camera spread over the image (drawn one per statement: portable).
std::vector<Eigen::Vector3d> scenePoints(uint64_t seed, int count) {
  SplitMix64 rng(seed);
  const PoseCw pose = framePose();
  std::vector<Eigen::Vector3d> X;
  for (int i = 0; i < count; ++i) {
    const double depth = 3.0 + 4.0 * rng.uniform();
    const double y = (rng.uniform() - 0.5) * 0.75 * depth;
    const double x = (rng.uniform() - 0.5) * 1.0 * depth;
    const Eigen::Vector3d x_c(x, y, depth);
    X.push_back(pose.R_cw.transpose() * (x_c - pose.t_cw));
  }
  return X;
}

// Hand-held shake at its fastest: 3 deg per frame about a tilted axis, 2 cm per frame sideways.
RollingShutterMotion shake() {
  RollingShutterMotion m;
  m.angular = Eigen::Vector3d(0.3, 1.0, 0.2).normalized() * (3.0 * kDeg);
  m.linear = Eigen::Vector3d(0.02, 0.0, 0.005);
  return m;
}

}  // namespace

TEST_CASE("rolling shutter: the pose of the reference row is the frame's", "[geometry][rs]") {
  const PoseCw pose = framePose();
  const RollingShutterMotion m = shake();
  const PoseCw same = poseAtTime(pose, m, 0.0);
  CHECK((same.R_cw - pose.R_cw).norm() == 0.0);
  CHECK((same.t_cw - pose.t_cw).norm() == 0.0);
  // Half a frame later the camera has turned by half the angular velocity and moved by half v.
  const PoseCw later = poseAtTime(pose, m, 0.5);
  CHECK(rotationAngle(later.R_cw * pose.R_cw.transpose()) == Approx(1.5 * kDeg).epsilon(1e-9));
  CHECK((later.centre() - pose.centre() - 0.5 * m.linear).norm() < 1e-12);
}

TEST_CASE("rolling shutter: the projection is the fixed point of the row", "[geometry][rs]") {
  const CameraIntrinsics k = camera();
  const RollingShutter rs = shutter30ms();
  const PoseCw pose = framePose();
  const RollingShutterMotion m = shake();
  int worst_iterations = 0;
  double worst_shift = 0.0;
  for (const auto& X : scenePoints(3, 300)) {
    const RollingShutterPixel p = projectRollingShutter(k, rs, pose, m, X);
    REQUIRE(p.status == RollingShutterProjection::kOk);
    // Seen where the camera was when its own row was exposed: projecting with that row's pose
    // gives the same pixel.
    const RollingShutterPixel again = projectRollingShutter(
        k, RollingShutter{}, poseAtTime(pose, m, rs.rowTime(p.px.y())), {}, X);
    CHECK((again.px - p.px).norm() < 1e-5);
    CHECK(p.tau == Approx(rs.rowTime(p.px.y())).margin(1e-12));
    worst_iterations = std::max(worst_iterations, p.iterations);
    const RollingShutterPixel global = projectRollingShutter(k, RollingShutter{}, pose, m, X);
    worst_shift = std::max(worst_shift, (global.px - p.px).norm());
  }
  INFO("worst iterations " << worst_iterations << ", largest rolling-shutter shift "
                           << worst_shift);
  CHECK(worst_iterations <= 6);  // 1e-6 px; each step gains line_delay x row speed (~0.06)
  CHECK(worst_shift > 10.0);     // 3 deg/frame over a 30 ms readout moves rows by tens of pixels
}

TEST_CASE("rolling shutter: line delay 0 is the global shutter exactly", "[geometry][rs]") {
  const CameraIntrinsics k = camera();
  const PoseCw pose = framePose();
  for (const auto& X : scenePoints(5, 50)) {
    const RollingShutterPixel rs = projectRollingShutter(k, RollingShutter{}, pose, shake(), X);
    const RollingShutterPixel still = projectRollingShutter(k, shutter30ms(), pose, {}, X);
    const Eigen::Vector3d x_c = pose.toCamera(X);
    const Eigen::Vector2d n = x_c.hnormalized();
    const double d = 1.0 + n.squaredNorm() * k.k1;
    const Eigen::Vector2d expected(k.fx * n.x() * d + k.cx, k.fy * n.y() * d + k.cy);
    CHECK(rs.px == expected);     // no motion model used at all
    CHECK(still.px == expected);  // no motion: every row has the same pose
    CHECK(rs.iterations == 0);
  }
}

TEST_CASE("rolling shutter: behind the camera and too fast are statuses", "[geometry][rs]") {
  const CameraIntrinsics k = camera();
  const PoseCw pose = framePose();
  const Eigen::Vector3d behind = pose.R_cw.transpose() * (Eigen::Vector3d(0, 0, -2) - pose.t_cw);
  CHECK(projectRollingShutter(k, shutter30ms(), pose, shake(), behind).status ==
        RollingShutterProjection::kBehindCamera);
  // A whip pan of 60 degrees per frame: the rows do not settle.
  RollingShutterMotion whip;
  whip.angular = Eigen::Vector3d(1.0, 0.0, 0.0) * (60.0 * kDeg);
  const Eigen::Vector3d X = pose.R_cw.transpose() * (Eigen::Vector3d(0.0, 1.5, 4.0) - pose.t_cw);
  CHECK(projectRollingShutter(k, shutter30ms(), pose, whip, X, 10).status !=
        RollingShutterProjection::kOk);
}

TEST_CASE("rolling shutter: resection recovers the pose and the readout motion", "[geometry][rs]") {
  const CameraIntrinsics k = camera();
  const RollingShutter rs = shutter30ms();
  const PoseCw truth = framePose();
  const RollingShutterMotion motion = shake();
  const auto X = scenePoints(11, 200);
  SplitMix64 rng(12);
  std::vector<Eigen::Vector2d> observed;
  for (const auto& p : X) {
    const double ny = test::standardNormal(rng);
    const double nx = test::standardNormal(rng);
    observed.push_back(projectRollingShutter(k, rs, truth, motion, p).px +
                       0.3 * Eigen::Vector2d(nx, ny));
  }
  // A start a global-shutter resection could give: off by a degree and 5 cm, no motion.
  PoseCw start = truth;
  start.R_cw = expSo3(Eigen::Vector3d(0.0, 1.0 * kDeg, 0.0)) * truth.R_cw;
  start.t_cw += Eigen::Vector3d(0.05, 0.0, 0.0);

  // With the readout modelled: the noise level, the pose and the angular velocity.
  PoseCw pose = start;
  RollingShutterMotion estimated;
  const auto result = refineRollingShutterPose(k, rs, X, observed, pose, estimated);
  INFO("rms " << result.rms_px << " px in " << result.iterations << " iterations");
  CHECK(result.converged);
  CHECK(result.rms_px < 0.45);  // the noise: sqrt(2) x 0.3 px = 0.42 px
  CHECK(rotationAngle(pose.R_cw * truth.R_cw.transpose()) < 0.02 * kDeg);
  CHECK((pose.centre() - truth.centre()).norm() < 0.01);
  CHECK((estimated.angular - motion.angular).norm() < 0.05 * motion.angular.norm());

  // The same data with a global shutter (line delay 0): no pose fits, the error stays pixels.
  PoseCw global = start;
  RollingShutterMotion none;
  const auto g = refineRollingShutterPose(k, RollingShutter{}, X, observed, global, none);
  INFO("global-shutter rms " << g.rms_px << " px");
  CHECK(g.rms_px > 5.0 * result.rms_px);
}
