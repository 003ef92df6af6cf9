#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Geometry>

#include "algo/sfm/scene_frame.hpp"
#include "tools/synth/random.hpp"

using namespace epitrack;

namespace {

/// Camera-to-world rotation of a camera at `c` looking at `target` (image y down, "up" = `up`).
Eigen::Matrix3d lookAt(const Eigen::Vector3d& c, const Eigen::Vector3d& target,
                       const Eigen::Vector3d& up) {
  const Eigen::Vector3d z = (target - c).normalized();
  const Eigen::Vector3d x = z.cross(up).normalized();
  Eigen::Matrix3d R;
  R.col(0) = x;
  R.col(1) = z.cross(x);
  R.col(2) = z;
  return R;
}

double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

/// A plane n.X = d with points on it, clutter kept at least 0.3 away from it, and cameras above.
struct PlaneScene {
  Eigen::Vector3d normal;
  double offset = 0.7;
  Eigen::Vector3d u, v;  // in-plane basis
  std::vector<Eigen::Vector3d> points;
  std::vector<int64_t> ids;
  int plane_points = 0;
  Eigen::Vector3d plane_centroid = Eigen::Vector3d::Zero();
  std::vector<ScenePose> cameras;
  std::vector<double> heights;

  PlaneScene(uint64_t seed, int on_plane, int clutter, double noise = 0.0) {
    synth::SplitMix64 rng(seed);
    normal = Eigen::Vector3d(0.2, -0.3, 1.0).normalized();
    u = normal.unitOrthogonal();
    v = normal.cross(u);
    const Eigen::Vector3d base = offset * normal + 0.4 * u - 0.9 * v;
    // One draw per statement, in the order x86-64 evaluated the former one-expression form
    // (tests/support/seeded_random.hpp), so the scene is the same on aarch64.
    for (int i = 0; i < on_plane; ++i) {
      const double h = noise * rng.gaussian();
      const double b = rng.uniform(-2, 4);
      const double a = rng.uniform(-3, 3);
      const Eigen::Vector3d X = base + a * u + b * v + h * normal;
      points.push_back(X);
      plane_centroid += X;
    }
    plane_points = on_plane;
    plane_centroid /= on_plane;
    for (int i = 0; i < clutter; ++i) {
      const double side = rng.uniform() < 0.7 ? 1.0 : -1.0;
      const double h = side * rng.uniform(0.3, 2.5);
      const double b = rng.uniform(-2, 4);
      const double a = rng.uniform(-3, 3);
      points.push_back(base + a * u + b * v + h * normal);
    }
    for (std::size_t i = 0; i < points.size(); ++i) ids.push_back(static_cast<int64_t>(100 + i));
    for (int i = 0; i < 9; ++i) {
      const double h = 1.5 + 0.25 * i;
      const double a = 0.3 * i;
      ScenePose c;
      c.p_wc = base + 4.0 * std::cos(a) * u + 4.0 * std::sin(a) * v + h * normal;
      c.R_wc = lookAt(c.p_wc, base, normal);
      cameras.push_back(c);
      heights.push_back(h);
    }
  }
};

}  // namespace

TEST_CASE("plane frame: origin, normal, axes and scale from a known plane", "[scene_frame]") {
  for (const uint64_t seed : {1u, 2u, 3u}) {
    PlaneScene scene(seed, 300, 120);
    const SceneFrame f = computeSceneFrame(scene.points, {}, scene.cameras, SceneFrameOptions{});
    REQUIRE(f.status == SceneFrameStatus::kOk);
    REQUIRE(f.plane_found);
    CHECK(f.origin_used == SceneOrigin::kPlane);
    CHECK(f.plane_inliers == scene.plane_points);
    CHECK((f.plane_normal - scene.normal).norm() < 1e-9);  // oriented towards the cameras
    CHECK(f.plane_offset == Approx(scene.offset).margin(1e-9));
    const Similarity3& S = f.world_to_scene;
    CHECK(S.scale == Approx(1.0 / median(scene.heights)).epsilon(1e-12));
    CHECK(S.apply(scene.plane_centroid).norm() < 1e-9);            // origin: the inlier centroid
    CHECK((S.R.row(2).transpose() - scene.normal).norm() < 1e-9);  // +Z up along the normal
    CHECK(S.R.determinant() == Approx(1.0));

    std::vector<ScenePose> cams = scene.cameras;
    std::vector<Eigen::Vector3d> pts = scene.points;
    applySimilarity(S, cams, pts);
    for (int i = 0; i < scene.plane_points; ++i)
      CHECK(std::abs(pts[static_cast<std::size_t>(i)].z()) < 1e-9);
    std::vector<double> z;
    for (std::size_t i = 0; i < cams.size(); ++i) {
      CHECK(cams[i].p_wc.z() == Approx(scene.heights[i] / median(scene.heights)));
      z.push_back(cams[i].p_wc.z());
    }
    CHECK(median(z) == Approx(1.0).epsilon(1e-12));
    // +X is the first camera's x axis projected onto the plane.
    const Eigen::Vector3d x0 = cams[0].R_wc.col(0);
    CHECK(std::abs(x0.y()) < 1e-9);
    CHECK(x0.x() > 0.0);
    // Poses stay rigid: R_wc orthonormal, relative geometry scaled.
    CHECK((cams[3].R_wc.transpose() * cams[3].R_wc - Eigen::Matrix3d::Identity()).norm() < 1e-12);
    CHECK((cams[3].p_wc - cams[1].p_wc).norm() ==
          Approx(S.scale * (scene.cameras[3].p_wc - scene.cameras[1].p_wc).norm()));
  }
}

TEST_CASE("plane frame does not depend on the world's gauge", "[scene_frame]") {
  PlaneScene scene(7, 250, 100);
  const SceneFrame a = computeSceneFrame(scene.points, {}, scene.cameras, SceneFrameOptions{});
  REQUIRE(a.status == SceneFrameStatus::kOk);
  // Same scene in another world frame (a similarity away): the scene coordinates agree.
  Similarity3 gauge;
  gauge.scale = 3.7;
  gauge.R = Eigen::AngleAxisd(1.1, Eigen::Vector3d(1, 2, -0.5).normalized()).toRotationMatrix();
  gauge.t = Eigen::Vector3d(5, -2, 9);
  std::vector<ScenePose> cams = scene.cameras;
  std::vector<Eigen::Vector3d> pts = scene.points;
  applySimilarity(gauge, cams, pts);
  const SceneFrame b = computeSceneFrame(pts, {}, cams, SceneFrameOptions{});
  REQUIRE(b.status == SceneFrameStatus::kOk);
  std::vector<ScenePose> cams_a = scene.cameras;
  std::vector<Eigen::Vector3d> pts_a = scene.points;
  applySimilarity(a.world_to_scene, cams_a, pts_a);
  applySimilarity(b.world_to_scene, cams, pts);
  for (std::size_t i = 0; i < pts.size(); ++i) CHECK((pts[i] - pts_a[i]).norm() < 1e-8);
  for (std::size_t i = 0; i < cams.size(); ++i) {
    CHECK((cams[i].p_wc - cams_a[i].p_wc).norm() < 1e-8);
    CHECK((cams[i].R_wc - cams_a[i].R_wc).norm() < 1e-8);
  }
}

TEST_CASE("plane frame with noise and a minority plane", "[scene_frame]") {
  // 30 % of the points on a noisy plane, the rest clutter: still the dominant plane.
  PlaneScene scene(11, 150, 350, 0.005);
  const SceneFrame f = computeSceneFrame(scene.points, {}, scene.cameras, SceneFrameOptions{});
  REQUIRE(f.status == SceneFrameStatus::kOk);
  const double angle_deg = std::acos(std::min(1.0, f.plane_normal.dot(scene.normal))) * 57.29578;
  CHECK(angle_deg < 0.5);
  CHECK(f.plane_inliers >= 140);
  CHECK(f.plane_inliers <= 150);
  CHECK(f.world_to_scene.scale == Approx(1.0 / median(scene.heights)).epsilon(0.01));
}

TEST_CASE("plane RANSAC is deterministic for a seed", "[scene_frame]") {
  PlaneScene scene(5, 120, 200, 0.01);
  const SceneFrame a = computeSceneFrame(scene.points, {}, scene.cameras, SceneFrameOptions{});
  const SceneFrame b = computeSceneFrame(scene.points, {}, scene.cameras, SceneFrameOptions{});
  CHECK(a.plane_inliers == b.plane_inliers);
  CHECK(a.world_to_scene.R == b.world_to_scene.R);
  CHECK(a.world_to_scene.t == b.world_to_scene.t);
  CHECK(a.world_to_scene.scale == b.world_to_scene.scale);
}

TEST_CASE("first-camera frame: identity first pose, median depth 1", "[scene_frame]") {
  PlaneScene scene(3, 200, 50);
  SceneFrameOptions options;
  options.origin = SceneOrigin::kFirstCamera;
  const SceneFrame f = computeSceneFrame(scene.points, {}, scene.cameras, options);
  REQUIRE(f.status == SceneFrameStatus::kOk);
  CHECK(f.origin_used == SceneOrigin::kFirstCamera);
  CHECK_FALSE(f.plane_found);  // not searched
  std::vector<ScenePose> cams = scene.cameras;
  std::vector<Eigen::Vector3d> pts = scene.points;
  applySimilarity(f.world_to_scene, cams, pts);
  CHECK(cams[0].p_wc.norm() < 1e-12);
  CHECK((cams[0].R_wc - Eigen::Matrix3d::Identity()).norm() < 1e-12);
  std::vector<double> depths;
  for (const auto& X : pts) {
    if (X.z() > 0) depths.push_back(X.z());
  }
  CHECK(median(depths) == Approx(1.0).epsilon(1e-12));
}

TEST_CASE("no plane falls back to the first-camera frame with a status", "[scene_frame]") {
  synth::SplitMix64 rng(9);
  std::vector<Eigen::Vector3d> blob;
  for (int i = 0; i < 400; ++i) {
    const double z = rng.uniform(-1, 1);
    const double y = rng.uniform(-1, 1);
    const double x = rng.uniform(-1, 1);
    const Eigen::Vector3d X(x, y, z);
    blob.push_back(X + Eigen::Vector3d(0, 0, 5));
  }
  std::vector<ScenePose> cams(3);
  cams[1].p_wc = Eigen::Vector3d(0.5, 0, 0);
  cams[2].p_wc = Eigen::Vector3d(1.0, 0.1, 0);
  SceneFrameOptions dominant_plane_only;
  dominant_plane_only.up_from_cameras = false;  // the fallback before issue 23
  const SceneFrame f = computeSceneFrame(blob, {}, cams, dominant_plane_only);
  CHECK(f.status == SceneFrameStatus::kPlaneNotFound);
  CHECK_FALSE(f.plane_found);
  CHECK(f.origin_used == SceneOrigin::kFirstCamera);
  CHECK(f.world_to_scene.R == Eigen::Matrix3d::Identity());
  std::vector<double> depths;
  for (const auto& X : blob) depths.push_back(X.z());
  CHECK(f.world_to_scene.scale == Approx(1.0 / median(depths)));

  // With the cameras' up (their -y, the world's -y here) the ground is under the blob instead.
  const SceneFrame g = computeSceneFrame(blob, {}, cams, SceneFrameOptions{});
  CHECK(g.status == SceneFrameStatus::kGroundFromCameras);
  CHECK(g.ground == SceneGround::kCameras);
  CHECK((g.world_to_scene.R.row(2).transpose() + Eigen::Vector3d::UnitY()).norm() < 1e-9);
  CHECK(g.up_confidence == Approx(1.0));
  int below = 0;
  for (const auto& X : blob) below += g.world_to_scene.apply(X).z() < 0.0 ? 1 : 0;
  CHECK(below <= 20);  // the 5 % quantile of the heights
}

TEST_CASE("cameras on the plane and too few points fall back", "[scene_frame]") {
  PlaneScene scene(4, 100, 0);
  std::vector<ScenePose> on_plane = scene.cameras;
  for (auto& c : on_plane) c.p_wc -= scene.normal * (scene.normal.dot(c.p_wc) - scene.offset);
  SceneFrameOptions dominant_plane_only;
  dominant_plane_only.up_from_cameras = false;  // the fallback before issue 23
  SceneFrame f = computeSceneFrame(scene.points, {}, on_plane, dominant_plane_only);
  CHECK(f.status == SceneFrameStatus::kPlaneNotFound);
  CHECK(f.origin_used == SceneOrigin::kFirstCamera);
  // With the cameras' up: the plane is not a ground (the cameras are on it), and the horizontal
  // ground under the points has the cameras on it too: the first-camera frame again.
  f = computeSceneFrame(scene.points, {}, on_plane, SceneFrameOptions{});
  CHECK_FALSE(f.plane_found);

  // Two points: no plane; none in front of the first camera: scale from the farthest camera.
  std::vector<Eigen::Vector3d> two = {Eigen::Vector3d(0, 0, -1), Eigen::Vector3d(1, 0, -2)};
  std::vector<ScenePose> cams(2);
  cams[1].p_wc = Eigen::Vector3d(0, 0.5, 0);
  f = computeSceneFrame(two, {}, cams, SceneFrameOptions{});
  CHECK(f.status == SceneFrameStatus::kPlaneNotFound);
  CHECK(f.ground == SceneGround::kNone);
  CHECK(f.world_to_scene.scale == Approx(2.0));
}

TEST_CASE("track origin: the chosen point at the origin, plane orientation", "[scene_frame]") {
  PlaneScene scene(6, 200, 80);
  SceneFrameOptions options;
  options.origin = SceneOrigin::kTrack;
  options.track_id = scene.ids[250];  // a clutter point above the plane
  const SceneFrame f = computeSceneFrame(scene.points, scene.ids, scene.cameras, options);
  REQUIRE(f.status == SceneFrameStatus::kOk);
  CHECK(f.origin_used == SceneOrigin::kTrack);
  CHECK(f.world_to_scene.apply(scene.points[250]).norm() < 1e-12);
  CHECK((f.world_to_scene.R.row(2).transpose() - scene.normal).norm() < 1e-9);
  CHECK(f.world_to_scene.scale == Approx(1.0 / median(scene.heights)));

  options.track_id = 5;  // no such point
  const SceneFrame g = computeSceneFrame(scene.points, scene.ids, scene.cameras, options);
  CHECK(g.status == SceneFrameStatus::kTrackNotFound);
  CHECK(g.origin_used == SceneOrigin::kPlane);
  CHECK(g.world_to_scene.apply(scene.plane_centroid).norm() < 1e-9);

  // Track without a plane: origin at the point, the first camera's axes.
  std::vector<Eigen::Vector3d> few(scene.points.begin(), scene.points.begin() + 2);
  std::vector<int64_t> few_ids(scene.ids.begin(), scene.ids.begin() + 2);
  options.track_id = few_ids[1];
  const SceneFrame h = computeSceneFrame(few, few_ids, scene.cameras, options);
  CHECK(h.status == SceneFrameStatus::kPlaneNotFound);
  CHECK(h.origin_used == SceneOrigin::kTrack);
  CHECK(h.world_to_scene.apply(few[1]).norm() < 1e-12);
  CHECK((h.world_to_scene.R - scene.cameras[0].R_wc.transpose()).norm() < 1e-12);
}

TEST_CASE("invalid scene frame input", "[scene_frame]") {
  PlaneScene scene(2, 50, 10);
  CHECK(computeSceneFrame(scene.points, {}, {}, SceneFrameOptions{}).status ==
        SceneFrameStatus::kInvalidInput);
  std::vector<ScenePose> bad = scene.cameras;
  bad[2].p_wc.x() = std::numeric_limits<double>::quiet_NaN();
  CHECK(computeSceneFrame(scene.points, {}, bad, SceneFrameOptions{}).status ==
        SceneFrameStatus::kInvalidInput);
  SceneFrameOptions options;
  options.origin = SceneOrigin::kTrack;
  options.track_id = 100;
  CHECK(computeSceneFrame(scene.points, {}, scene.cameras, options).status ==
        SceneFrameStatus::kInvalidInput);  // ids missing
  // Non-finite points are ignored, not fatal.
  std::vector<Eigen::Vector3d> pts = scene.points;
  pts[0].y() = std::numeric_limits<double>::infinity();
  CHECK(computeSceneFrame(pts, {}, scene.cameras, SceneFrameOptions{}).status ==
        SceneFrameStatus::kOk);
}

namespace {

/// A room corner: `floor` points on z = 0, `wall` points on y = 3 (facing -y), none near their
/// intersection (where a point would be an inlier of both planes), cameras standing
/// at 1.6 m looking at the wall.
void roomCorner(int floor, int wall, std::vector<Eigen::Vector3d>& points,
                std::vector<ScenePose>& cameras) {
  synth::SplitMix64 rng(21);
  points.clear();
  cameras.clear();
  for (int i = 0; i < floor; ++i) {
    const double y = rng.uniform(-1, 2.7);
    const double x = rng.uniform(-3, 3);
    points.emplace_back(x, y, 0.0);
  }
  for (int i = 0; i < wall; ++i) {
    const double z = rng.uniform(0.3, 3);
    const double x = rng.uniform(-3, 3);
    points.emplace_back(x, 3.0, z);
  }
  for (int i = 0; i < 8; ++i) {
    ScenePose c;
    c.p_wc = Eigen::Vector3d(-1.0 + 0.25 * i, -2.0, 1.6 + 0.02 * i);
    c.R_wc = lookAt(c.p_wc, Eigen::Vector3d(0.0, 3.0, 1.0), Eigen::Vector3d::UnitZ());
    cameras.push_back(c);
  }
}

}  // namespace

TEST_CASE("plane frame prefers the ground to a larger wall", "[scene_frame]") {
  std::vector<Eigen::Vector3d> points;
  std::vector<ScenePose> cameras;
  roomCorner(150, 300, points, cameras);
  SceneFrameOptions options;
  SceneFrame f = computeSceneFrame(points, {}, cameras, options);
  REQUIRE(f.status == SceneFrameStatus::kOk);
  CHECK((f.plane_normal - Eigen::Vector3d::UnitZ()).norm() < 1e-9);
  CHECK(f.plane_inliers == 150);
  std::vector<double> heights;
  for (const auto& c : cameras) heights.push_back(c.p_wc.z());
  CHECK(f.world_to_scene.scale == Approx(1.0 / median(heights)));

  options.up_from_cameras = false;  // the dominant plane is the wall
  f = computeSceneFrame(points, {}, cameras, options);
  REQUIRE(f.status == SceneFrameStatus::kOk);
  CHECK((f.plane_normal + Eigen::Vector3d::UnitY()).norm() < 1e-9);  // facing the cameras
  CHECK(f.plane_inliers == 300);
  CHECK(f.ground == SceneGround::kPlane);

  // A floor too small to count as a plane (60 of 360 points, below min_plane_fraction): up comes
  // from the cameras and the ground is still under the points, at the floor's height.
  roomCorner(60, 300, points, cameras);
  f = computeSceneFrame(points, {}, cameras, SceneFrameOptions{});
  REQUIRE(f.status == SceneFrameStatus::kGroundFromCameras);
  CHECK(f.ground == SceneGround::kCameras);
  CHECK_FALSE(f.plane_found);
  // The cameras look 7 degrees down at the wall: their mean image-up leans that much towards
  // the wall (the bias of an up from the cameras alone), so the ground is level within 10 degrees.
  CHECK(f.plane_normal.dot(Eigen::Vector3d::UnitZ()) > std::cos(10.0 * M_PI / 180.0));
  CHECK(std::abs(f.world_to_scene.apply(Eigen::Vector3d(0.0, 1.0, 0.0)).z()) < 0.15);
}

TEST_CASE("wall-only shot: up from the cameras, the ground under the wall", "[scene_frame]") {
  // A textured wall (y = 3) filmed by level cameras walking along it: the only plane is vertical.
  synth::SplitMix64 rng(31);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 300; ++i) {
    const double z = rng.uniform(0.5, 3.0);
    const double x = rng.uniform(-3, 3);
    points.emplace_back(x, 3.0, z);
  }
  std::vector<ScenePose> cameras;
  for (int i = 0; i < 10; ++i) {
    ScenePose c;
    c.p_wc = Eigen::Vector3d(-1.0 + 0.2 * i, -1.0, 1.6);
    c.R_wc =
        lookAt(c.p_wc, c.p_wc + Eigen::Vector3d(0.1 * (i - 5), 1.0, 0.0), Eigen::Vector3d::UnitZ());
    cameras.push_back(c);
  }
  const SceneFrame f = computeSceneFrame(points, {}, cameras, SceneFrameOptions{});
  REQUIRE(f.status == SceneFrameStatus::kGroundFromCameras);
  CHECK(f.ground == SceneGround::kCameras);
  CHECK(f.up_confidence == Approx(1.0).margin(1e-9));
  // Up within 2 degrees of the true up, the ground at the wall's lowest points, cameras above.
  CHECK(f.world_to_scene.R.row(2).dot(Eigen::Vector3d::UnitZ()) > std::cos(2.0 * M_PI / 180.0));
  std::vector<double> z;
  for (const auto& X : points) z.push_back(f.world_to_scene.apply(X).z());
  std::sort(z.begin(), z.end());
  CHECK(z[z.size() / 20] == Approx(0.0).margin(1e-9));
  for (const auto& c : cameras) CHECK(f.world_to_scene.apply(c.p_wc).z() > 0.0);
  // Cameras looking 10 degrees down at the wall: their image-up axes lean 10 degrees towards it,
  // but up lies in the (vertical) wall, which takes the lean out.
  std::vector<ScenePose> looking_down = cameras;
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const double down = std::tan(10.0 * M_PI / 180.0);
    const ScenePose& c = cameras[i];
    looking_down[i].R_wc =
        lookAt(c.p_wc, c.p_wc + Eigen::Vector3d(0.1 * (static_cast<double>(i) - 5), 1.0, -down),
               Eigen::Vector3d::UnitZ());
  }
  const SceneFrame d = computeSceneFrame(points, {}, looking_down, SceneFrameOptions{});
  REQUIRE(d.ground == SceneGround::kCameras);
  CHECK(d.up_spread_deg > 3.0);  // the lean shows in the spread
  CHECK(d.world_to_scene.R.row(2).dot(Eigen::Vector3d::UnitZ()) > std::cos(0.5 * M_PI / 180.0));
  // Before issue 23 the wall was the ground: +z pointed at the cameras, horizontally.
  SceneFrameOptions old;
  old.up_from_cameras = false;
  const SceneFrame g = computeSceneFrame(points, {}, cameras, old);
  CHECK(std::abs(g.world_to_scene.R.row(2).dot(Eigen::Vector3d::UnitZ())) < 1e-6);
}

TEST_CASE("turntable: up from a ring of cameras looking down at an object", "[scene_frame]") {
  // An object (points filling a box, no dominant plane) seen from a full ring of cameras 35
  // degrees above it: each camera's image-up leans inwards, their mean is vertical.
  synth::SplitMix64 rng(41);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 400; ++i) {
    const double z = rng.uniform(0.0, 0.3);
    const double y = rng.uniform(-0.1, 0.1);
    const double x = rng.uniform(-0.1, 0.1);
    points.emplace_back(x, y, z);
  }
  std::vector<ScenePose> cameras;
  for (int i = 0; i < 24; ++i) {
    const double a = 2.0 * M_PI * i / 24.0;
    const double elevation = 35.0 * M_PI / 180.0;
    ScenePose c;
    c.p_wc = 0.6 * Eigen::Vector3d(std::cos(elevation) * std::cos(a),
                                   std::cos(elevation) * std::sin(a), std::sin(elevation));
    c.R_wc = lookAt(c.p_wc, Eigen::Vector3d(0, 0, 0.15), Eigen::Vector3d::UnitZ());
    cameras.push_back(c);
  }
  const SceneFrame f = computeSceneFrame(points, {}, cameras, SceneFrameOptions{});
  REQUIRE(f.ground != SceneGround::kNone);
  CHECK(f.world_to_scene.R.row(2).dot(Eigen::Vector3d::UnitZ()) > std::cos(2.0 * M_PI / 180.0));
  // Each camera looks down at the object's middle by atan(0.6 sin 35 - 0.15, 0.6 cos 35): that
  // lean is the spread of the image-up axes, and the confidence is its cosine.
  const double down =
      std::atan2(0.6 * std::sin(35.0 * M_PI / 180.0) - 0.15, 0.6 * std::cos(35.0 * M_PI / 180.0));
  CHECK(f.up_spread_deg == Approx(down * 180.0 / M_PI).margin(0.01));
  CHECK(f.up_confidence == Approx(std::cos(down)).margin(1e-6));
  // The ground is at the object's base (within the 5 % quantile of its height, 0.015).
  CHECK(std::abs(f.world_to_scene.apply(Eigen::Vector3d::Zero()).z()) <
        0.03 * f.world_to_scene.scale);
}

TEST_CASE("a rolled ground fit is levelled with the cameras' x axes", "[scene_frame]") {
  // A road band seen by level cameras driving along +y; the fitted plane rolls 7 degrees about
  // the driving direction (as a plane through road, kerb and verge can). The cameras' x axes are
  // level, so the ground's normal follows them; the roll is reported as the plane-to-up angle.
  synth::SplitMix64 rng(51);
  const double roll = 7.0 * M_PI / 180.0;
  const Eigen::Vector3d normal(std::sin(roll), 0.0, std::cos(roll));
  const Eigen::Vector3d across = Eigen::Vector3d::UnitY().cross(normal);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 300; ++i) {
    const double along = rng.uniform(2.0, 30.0);
    const double side = rng.uniform(-4.0, 4.0);
    points.push_back(Eigen::Vector3d(0, along, 0) + side * across);
  }
  std::vector<ScenePose> cameras;
  for (int i = 0; i < 10; ++i) {
    ScenePose c;
    c.p_wc = Eigen::Vector3d(0.0, 1.0 * i, 1.6);
    c.R_wc = lookAt(c.p_wc, c.p_wc + Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ());
    cameras.push_back(c);
  }
  const SceneFrame f = computeSceneFrame(points, {}, cameras, SceneFrameOptions{});
  REQUIRE(f.ground == SceneGround::kPlane);
  CHECK(f.plane_up_angle_deg == Approx(7.0).margin(0.01));
  CHECK(f.plane_normal.dot(Eigen::Vector3d::UnitZ()) > std::cos(0.5 * M_PI / 180.0));
  SceneFrameOptions unlevelled;
  unlevelled.level_ground_with_cameras = false;
  const SceneFrame g = computeSceneFrame(points, {}, cameras, unlevelled);
  CHECK(g.plane_normal.dot(normal) == Approx(1.0).margin(1e-9));
}
