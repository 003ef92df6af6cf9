#pragma once

// Seeded synthetic two-view (and multi-view) scenes with known K, R, t for the geometry tests
// (after libmv's TwoViewDataSet): points in a box in front of the cameras, projections with
// Gaussian noise (Box-Muller on SplitMix64, identical on every platform) and injected outliers.

#include <cmath>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "algo/geometry/pose.hpp"
#include "algo/math/random.hpp"

namespace epitrack::test {

inline double gaussian(SplitMix64& rng) {
  const double u1 = std::max(rng.uniform(), 1e-300), u2 = rng.uniform();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

inline Eigen::Vector3d randomUnit(SplitMix64& rng) {
  Eigen::Vector3d v(gaussian(rng), gaussian(rng), gaussian(rng));
  return v.normalized();
}

/// Camera looking from `centre` at `target` (camera y roughly along world +y, i.e. "down").
inline PoseCw lookAt(const Eigen::Vector3d& centre, const Eigen::Vector3d& target,
                     const Eigen::Vector3d& down = Eigen::Vector3d::UnitY()) {
  const Eigen::Vector3d z = (target - centre).normalized();
  const Eigen::Vector3d x = down.cross(z).normalized();
  const Eigen::Vector3d y = z.cross(x);
  PoseCw p;
  p.R_cw.row(0) = x.transpose();
  p.R_cw.row(1) = y.transpose();
  p.R_cw.row(2) = z.transpose();
  p.t_cw = -p.R_cw * centre;
  return p;
}

struct TwoViewScene {
  double f = 500.0;
  int width = 640, height = 480;
  PoseCw cam1, cam2;  // cam1 = identity
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> x1, x2;  // pixels (noisy, with outliers)
  std::vector<char> is_inlier;
  [[nodiscard]] Eigen::Matrix3d K() const {
    Eigen::Matrix3d k;
    k << f, 0, (width - 1) * 0.5, 0, f, (height - 1) * 0.5, 0, 0, 1;
    return k;
  }
  [[nodiscard]] Eigen::Vector2d project(const PoseCw& p, const Eigen::Vector3d& Xw) const {
    const Eigen::Vector3d c = p.toCamera(Xw);
    return {f * c.x() / c.z() + (width - 1) * 0.5, f * c.y() / c.z() + (height - 1) * 0.5};
  }
  [[nodiscard]] Eigen::Vector2d normalize(const Eigen::Vector2d& px) const {
    return {(px.x() - (width - 1) * 0.5) / f, (px.y() - (height - 1) * 0.5) / f};
  }
  [[nodiscard]] bool inside(const Eigen::Vector2d& p) const {
    return p.x() >= 0 && p.y() >= 0 && p.x() <= width - 1 && p.y() <= height - 1;
  }
};

enum class Motion { kGeneral, kRotation, kTranslation, kOrbit, kPlanarScene };

/// `count` correspondences; `outlier_fraction` of them replaced by uniform random pixels in view 2.
inline TwoViewScene makeTwoViewScene(uint64_t seed, int count, double noise_px,
                                     double outlier_fraction, Motion motion = Motion::kGeneral,
                                     double f = 500.0) {
  SplitMix64 rng(seed * 7919 + 13);
  TwoViewScene s;
  s.f = f;
  const Eigen::Vector3d target(0, 0, 6);
  switch (motion) {
    case Motion::kGeneral:
    case Motion::kPlanarScene: {
      // Lateral baseline with a rotation that keeps the scene in view but whose optical axes do
      // not meet (an off-target look point).
      const Eigen::Vector3d c2 = Eigen::Vector3d(1.5 + 0.5 * rng.uniform(),
                                                 0.4 * rng.uniform() - 0.2, 0.3 * rng.uniform());
      const Eigen::Vector3d look =
          target + Eigen::Vector3d(1.5 + rng.uniform(), 1.0 * rng.uniform() - 0.5, 0.0);
      s.cam2 = lookAt(c2, look);
      break;
    }
    case Motion::kRotation:
      s.cam2.R_cw = expSo3(Eigen::Vector3d(0.02, 0.15, 0.03));
      break;
    case Motion::kTranslation:
      s.cam2.t_cw = -Eigen::Vector3d(0.8, 0.1, 0.4);
      break;
    case Motion::kOrbit:
      s.cam2 = lookAt(target + expSo3(Eigen::Vector3d(0, 0.25, 0)) * (-target), target);
      break;
  }
  const int n_out = static_cast<int>(std::lround(outlier_fraction * count));
  int attempts = 0;
  while (static_cast<int>(s.X.size()) < count && attempts++ < 100 * count) {
    Eigen::Vector3d X;
    if (motion == Motion::kPlanarScene) {
      X = Eigen::Vector3d(6 * rng.uniform() - 3, 4 * rng.uniform() - 2, 0.0);
      X = target + expSo3(Eigen::Vector3d(0.4, 0.2, 0)) * X;  // a tilted plane
    } else {
      X = Eigen::Vector3d(8 * rng.uniform() - 4, 6 * rng.uniform() - 3, 3.0 + 7.0 * rng.uniform());
    }
    const Eigen::Vector2d p1 = s.project(s.cam1, X), p2 = s.project(s.cam2, X);
    if (s.cam2.toCamera(X).z() <= 0.5 || !s.inside(p1) || !s.inside(p2)) continue;
    s.X.push_back(X);
    s.x1.push_back(p1 + noise_px * Eigen::Vector2d(gaussian(rng), gaussian(rng)));
    s.x2.push_back(p2 + noise_px * Eigen::Vector2d(gaussian(rng), gaussian(rng)));
    s.is_inlier.push_back(1);
  }
  for (int k = 0; k < n_out && k < static_cast<int>(s.X.size());) {
    const auto i = static_cast<std::size_t>(rng.below(static_cast<uint32_t>(s.X.size())));
    if (!s.is_inlier[i]) continue;
    ++k;
    Eigen::Vector2d r;
    do {
      r = Eigen::Vector2d(rng.uniform() * (s.width - 1), rng.uniform() * (s.height - 1));
    } while ((r - s.x2[i]).norm() < 20.0);
    s.x2[i] = r;
    s.is_inlier[i] = 0;
  }
  return s;
}

/// Angle between two rotations in degrees.
inline double rotationErrorDeg(const Eigen::Matrix3d& A, const Eigen::Matrix3d& B) {
  return rotationAngle(A.transpose() * B) * 180.0 / M_PI;
}

/// Angle between two directions in degrees.
inline double directionErrorDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

}  // namespace epitrack::test
