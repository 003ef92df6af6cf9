#pragma once

// A hand-made reconstruction for the exporter tests: cameras on a circle looking at the origin,
// points on a ground plane and above it, and every point observed (exact projections) in every
// solved frame where it lies in front of the camera.

#include <cmath>
#include <cstdint>
#include <limits>

#include <Eigen/Geometry>

#include "tools/export/reconstruction.hpp"

namespace epitrack::test {

/// Camera-to-world rotation of a camera at `centre` looking at `target`, image y down, with the
/// world +z as "up" (camera -y points as close to +z as possible).
inline Eigen::Matrix3d lookAt(const Eigen::Vector3d& centre, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - centre).normalized();
  Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ());
  if (x.norm() < 1e-9) x = Eigen::Vector3d::UnitX();
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;
  R.col(0) = x;
  R.col(1) = y;
  R.col(2) = z;
  return R;
}

inline Eigen::Vector2d projectPinhole(const CameraIntrinsics& k, const io::SolvedCamera& c,
                                      const Eigen::Vector3d& X) {
  const Eigen::Vector3d xc = c.R_wc.transpose() * (X - c.p_wc);
  const double u = xc.x() / xc.z();
  const double v = xc.y() / xc.z();
  const double r2 = u * u + v * v;
  const double d = 1.0 + k.k1 * r2 + k.k2 * r2 * r2;
  return {k.fx * u * d + k.cx, k.fy * v * d + k.cy};
}

/// `frames` frames, every `unsolved_every`-th one unsolved (0: all solved).
inline io::Reconstruction makeReconstruction(int frames = 12, int unsolved_every = 5,
                                             double k1 = 0.0, double k2 = 0.0) {
  io::Reconstruction rec;
  rec.intrinsics = CameraIntrinsics::centered(640, 480, 500.0);
  rec.intrinsics.k1 = k1;
  rec.intrinsics.k2 = k2;
  rec.frames = frames;
  rec.focal_source = "self-calibrated";
  rec.seconds.stages = {{"tracking", 0.5}, {"bundle_adjustment", 0.25}};
  rec.seconds.total = 0.75;
  for (int i = 0; i < frames; ++i) {
    io::SolvedCamera c;
    c.frame = i;
    c.timestamp = 0.04 * i;
    c.solved = unsolved_every == 0 || i % unsolved_every != unsolved_every - 1;
    const double a = 0.15 * i;
    c.p_wc = Eigen::Vector3d(4.0 * std::cos(a), 4.0 * std::sin(a), 1.5 + 0.1 * i);
    c.R_wc = lookAt(c.p_wc, Eigen::Vector3d(0.0, 0.0, 0.3));
    c.mean_reproj_px = 0.1 + 0.01 * i;
    c.inliers = 20;
    c.keyframe = i % 4 == 0;
    rec.cameras.push_back(c);
  }
  int64_t id = 3;  // ids need not start at 0 or be contiguous
  for (int gy = -2; gy <= 2; ++gy) {
    for (int gx = -2; gx <= 2; ++gx) {
      io::ScenePoint p;
      p.id = id;
      id += 2;
      p.X = Eigen::Vector3d(0.4 * gx, 0.4 * gy, (gx + gy) % 3 == 0 ? 0.0 : 0.05 * (gx - gy));
      p.gray = static_cast<uint8_t>(100 + 10 * gx + gy);
      p.reproj_px = 0.2;
      rec.points.push_back(p);
    }
  }
  for (const io::SolvedCamera& c : rec.cameras) {
    for (io::ScenePoint& p : rec.points) {
      const Eigen::Vector2d xy = projectPinhole(rec.intrinsics, c, p.X);
      io::PointObservation o;
      o.frame = c.frame;
      o.point_id = p.id;
      o.x = xy.x();
      o.y = xy.y();
      o.residual_px = 0.1 * static_cast<double>(p.id % 5);
      rec.observations.push_back(o);
      p.observations += 1;
    }
  }
  return rec;
}

}  // namespace epitrack::test
