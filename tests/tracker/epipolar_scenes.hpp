#pragma once

// Track sets with known geometry for the epipolar check's tests: points of a rigid scene seen by
// a moving camera (orbit, pure rotation, a plane), with seeded measurement noise, and injected
// non-rigid tracks: a track that slides along an occluding edge moves smoothly (it would pass a
// forward-backward check) but leaves its epipolar line.

#include <cmath>
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "algo/math/random.hpp"
#include "tests/support/seeded_random.hpp"

namespace epitrack::test {

enum class EpipolarSceneKind { kOrbit, kPan, kPlanar };

struct EpipolarScene {
  int width = 704;
  int height = 576;
  double focal = 600.0;
  int tracks = 150;
  int frames = 60;
  std::vector<Eigen::Vector3d> points;  // world points, one per track
  std::vector<uint8_t> sliding;         // 1: the track slides from slide_start on
  int slide_start = 10;
  double slide_px_per_frame = 0.5;
  double noise_px = 0.1;
  EpipolarSceneKind kind = EpipolarSceneKind::kOrbit;

  /// Camera rotation (world to camera) and centre at frame f.
  void pose(int f, Eigen::Matrix3d& R_cw, Eigen::Vector3d& centre) const {
    const double t = static_cast<double>(f);
    if (kind == EpipolarSceneKind::kPan) {
      // Pure rotation about the camera centre: 0.3 deg/frame of yaw, a slight tilt.
      centre = Eigen::Vector3d::Zero();
      R_cw = (Eigen::AngleAxisd(0.3 * M_PI / 180.0 * t, Eigen::Vector3d::UnitY()) *
              Eigen::AngleAxisd(0.05 * M_PI / 180.0 * t, Eigen::Vector3d::UnitX()))
                 .toRotationMatrix()
                 .transpose();
      return;
    }
    // An arc around the point (0, 0, 8) (camera looks along +z at frame 0): 0.25 deg/frame.
    const double a = 0.25 * M_PI / 180.0 * t;
    const Eigen::Vector3d target(0.0, 0.0, 8.0);
    centre = target + Eigen::Vector3d(-8.0 * std::sin(a), 0.02 * t, -8.0 * std::cos(a));
    // Look at the target: camera z towards it, y down.
    const Eigen::Vector3d z = (target - centre).normalized();
    const Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z).normalized();
    const Eigen::Vector3d y = z.cross(x);
    Eigen::Matrix3d R_wc;
    R_wc.col(0) = x;
    R_wc.col(1) = y;
    R_wc.col(2) = z;
    R_cw = R_wc.transpose();
  }

  /// The true projection of track i at frame f (false: behind the camera).
  bool project(int i, int f, Eigen::Vector2d& p) const {
    Eigen::Matrix3d R_cw;
    Eigen::Vector3d c;
    pose(f, R_cw, c);
    const Eigen::Vector3d xc = R_cw * (points[static_cast<std::size_t>(i)] - c);
    if (xc.z() <= 0.1) return false;
    p = Eigen::Vector2d(focal * xc.x() / xc.z() + 0.5 * width,
                        focal * xc.y() / xc.z() + 0.5 * height);
    return true;
  }

  /// Track i's measured position at frame f: the projection, the slide, seeded noise.
  Eigen::Vector2d measure(int i, int f, SplitMix64& rng) const {
    Eigen::Vector2d p;
    project(i, f, p);
    if (sliding[static_cast<std::size_t>(i)] != 0 && f > slide_start) {
      // Across the point's own image motion (for a translating camera, across its epipolar
      // line): the slide of a corner along an occluding edge that cuts its path.
      Eigen::Vector2d p0, p1;
      project(i, slide_start, p0);
      project(i, slide_start + 1, p1);
      Eigen::Vector2d d = p1 - p0;
      d = d.norm() > 1e-9 ? Eigen::Vector2d(-d.y(), d.x()).normalized() : Eigen::Vector2d(1.0, 0.0);
      p += slide_px_per_frame * static_cast<double>(f - slide_start) * d;
    }
    const double nx = noise_px * standardNormal(rng);
    const double ny = noise_px * standardNormal(rng);
    return p + Eigen::Vector2d(nx, ny);
  }
};

/// A scene of `kind` with `tracks` points visible through `frames` frames and `outliers` sliding
/// tracks (every tracks / outliers-th one), seeded.
inline EpipolarScene makeEpipolarScene(EpipolarSceneKind kind, int outliers, uint64_t seed,
                                       int tracks = 150, int frames = 60) {
  EpipolarScene s;
  s.kind = kind;
  s.tracks = tracks;
  s.frames = frames;
  SplitMix64 rng(seed);
  s.points.resize(static_cast<std::size_t>(tracks));
  s.sliding.assign(static_cast<std::size_t>(tracks), 0);
  for (int i = 0; i < tracks; ++i) {
    // Inside the first frame's view (a margin for the motion), at a depth of the kind.
    const double u = rng.uniform();
    const double v = rng.uniform();
    const double w = rng.uniform();
    const double nx = (0.2 + 0.6 * u - 0.5) * s.width / s.focal;  // normalized image coordinates
    const double ny = (0.15 + 0.7 * v - 0.5) * s.height / s.focal;
    double depth = 4.0 + 8.0 * w;  // boxes at several depths (4-12 m)
    if (kind == EpipolarSceneKind::kPlanar) depth = 9.0 / (1.0 - 0.3 * nx);  // plane z = 9 + 0.3 x
    const double x = nx * depth;
    const double y = ny * depth;
    s.points[static_cast<std::size_t>(i)] = Eigen::Vector3d(x, y, depth);
  }
  if (outliers > 0) {
    const int step = tracks / outliers;
    for (int k = 0; k < outliers; ++k) s.sliding[static_cast<std::size_t>(k * step + step / 2)] = 1;
  }
  return s;
}

}  // namespace epitrack::test
