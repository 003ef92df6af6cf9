#pragma once

// Seeded synthetic two-view (and multi-view) scenes with known K, R, t for the geometry tests and
// benchmarks
// (after libmv's TwoViewDataSet): points in a box in front of the cameras, projections with
// Gaussian noise (Box-Muller on SplitMix64) and injected outliers. Bit-identical on x86-64 and
// aarch64: one draw per statement, in the order x86-64 used (tools/synth/seeded_random.hpp).

#include <cmath>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "algo/geometry/pose.hpp"
#include "algo/math/random.hpp"
#include "tools/synth/seeded_random.hpp"

namespace epitrack::scenes {

// epitrack's own generator (tools/synth/random.hpp has synth::SplitMix64, another type).
using epitrack::SplitMix64;

inline double gaussian(SplitMix64& rng) { return standardNormal(rng); }

/// Two independent normal draws (y drawn first, as x86-64 evaluated the former one-liner).
inline Eigen::Vector2d gaussian2(SplitMix64& rng) {
  const double y = gaussian(rng);
  const double x = gaussian(rng);
  return {x, y};
}

inline Eigen::Vector3d randomUnit(SplitMix64& rng) {
  const double z = gaussian(rng);
  const double y = gaussian(rng);
  const double x = gaussian(rng);
  return Eigen::Vector3d(x, y, z).normalized();
}

/// R x + t in plain scalar arithmetic: Eigen's vectorised products use fused multiply-adds on
/// NEON (not on SSE), which would make the scenes differ in the last bit on aarch64.
inline Eigen::Vector3d affineScalar(const Eigen::Matrix3d& R, const Eigen::Vector3d& x,
                                    const Eigen::Vector3d& t) {
  Eigen::Vector3d y;
  for (int r = 0; r < 3; ++r) {
    double acc = R(r, 0) * x(0);
    acc += R(r, 1) * x(1);
    acc += R(r, 2) * x(2);
    y(r) = acc + t(r);
  }
  return y;
}

/// exp of the rotation vector w (Rodrigues) in plain scalar arithmetic, for the same reason.
inline Eigen::Matrix3d rotationScalar(const Eigen::Vector3d& w) {
  const double theta2 = w(0) * w(0) + w(1) * w(1) + w(2) * w(2);
  const double theta = std::sqrt(theta2);
  const double a = theta2 < 1e-16 ? 1.0 : std::sin(theta) / theta;
  const double b = theta2 < 1e-16 ? 0.5 : (1.0 - std::cos(theta)) / theta2;
  // R = I + a [w]x + b [w]x^2, with [w]x^2 = w w^T - |w|^2 I.
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      const double wx2 = w(r) * w(c) - (r == c ? theta2 : 0.0);
      R(r, c) = (r == c ? 1.0 : 0.0) + b * wx2;
    }
  }
  R(0, 1) -= a * w(2);
  R(0, 2) += a * w(1);
  R(1, 0) += a * w(2);
  R(1, 2) -= a * w(0);
  R(2, 0) -= a * w(1);
  R(2, 1) += a * w(0);
  return R;
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
  p.t_cw = -affineScalar(p.R_cw, centre, Eigen::Vector3d::Zero());
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
    const Eigen::Vector3d c = affineScalar(p.R_cw, Xw, p.t_cw);
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
      const double c2z = 0.3 * rng.uniform();
      const double c2y = 0.4 * rng.uniform() - 0.2;
      const double c2x = 1.5 + 0.5 * rng.uniform();
      const Eigen::Vector3d c2(c2x, c2y, c2z);
      const double look_y = 1.0 * rng.uniform() - 0.5;
      const double look_x = 1.5 + rng.uniform();
      const Eigen::Vector3d look = target + Eigen::Vector3d(look_x, look_y, 0.0);
      s.cam2 = lookAt(c2, look);
      break;
    }
    case Motion::kRotation:
      s.cam2.R_cw = rotationScalar(Eigen::Vector3d(0.02, 0.15, 0.03));
      break;
    case Motion::kTranslation:
      s.cam2.t_cw = -Eigen::Vector3d(0.8, 0.1, 0.4);
      break;
    case Motion::kOrbit:
      s.cam2 = lookAt(target + affineScalar(rotationScalar(Eigen::Vector3d(0, 0.25, 0)), -target,
                                            Eigen::Vector3d::Zero()),
                      target);
      break;
  }
  const int n_out = static_cast<int>(std::lround(outlier_fraction * count));
  int attempts = 0;
  while (static_cast<int>(s.X.size()) < count && attempts++ < 100 * count) {
    Eigen::Vector3d X;
    if (motion == Motion::kPlanarScene) {
      const double y = 4 * rng.uniform() - 2;
      const double x = 6 * rng.uniform() - 3;
      X = Eigen::Vector3d(x, y, 0.0);
      X = affineScalar(rotationScalar(Eigen::Vector3d(0.4, 0.2, 0)), X, target);  // tilted plane
    } else {
      const double z = 3.0 + 7.0 * rng.uniform();
      const double y = 6 * rng.uniform() - 3;
      const double x = 8 * rng.uniform() - 4;
      X = Eigen::Vector3d(x, y, z);
    }
    const Eigen::Vector2d p1 = s.project(s.cam1, X), p2 = s.project(s.cam2, X);
    if (s.cam2.toCamera(X).z() <= 0.5 || !s.inside(p1) || !s.inside(p2)) continue;
    s.X.push_back(X);
    s.x1.push_back(p1 + noise_px * gaussian2(rng));
    s.x2.push_back(p2 + noise_px * gaussian2(rng));
    s.is_inlier.push_back(1);
  }
  for (int k = 0; k < n_out && k < static_cast<int>(s.X.size());) {
    const auto i = static_cast<std::size_t>(rng.below(static_cast<uint32_t>(s.X.size())));
    if (!s.is_inlier[i]) continue;
    ++k;
    Eigen::Vector2d r;
    do {
      const double y = rng.uniform() * (s.height - 1);
      const double x = rng.uniform() * (s.width - 1);
      r = Eigen::Vector2d(x, y);
    } while ((r - s.x2[i]).norm() < 20.0);
    s.x2[i] = r;
    s.is_inlier[i] = 0;
  }
  return s;
}

/// Angle between two rotations in degrees, from ||A - B||_F = 2 sqrt(2) sin(angle / 2): exact
/// down to 1e-12 deg, where acos((trace - 1) / 2) cannot resolve angles below about 1e-6 deg.
inline double rotationErrorDeg(const Eigen::Matrix3d& A, const Eigen::Matrix3d& B) {
  const double half_sin = std::min(1.0, (A - B).norm() / (2.0 * std::sqrt(2.0)));
  return 2.0 * std::asin(half_sin) * 180.0 / M_PI;
}

/// Angle between two directions in degrees.
inline double directionErrorDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

}  // namespace epitrack::scenes
