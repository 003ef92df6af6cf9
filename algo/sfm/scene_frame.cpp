#include "algo/sfm/scene_frame.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include <Eigen/Eigenvalues>

namespace epitrack {
namespace {

/// SplitMix64 (Steele, Lea & Flood 2014): integer-only, so the RANSAC samples are the same on
/// every platform and standard library.
class SampleGenerator {
 public:
  explicit SampleGenerator(uint64_t seed) : state_(seed) {}
  uint64_t next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  std::size_t index(std::size_t n) { return static_cast<std::size_t>(next() % n); }

 private:
  uint64_t state_;
};

/// normal . X = offset, |normal| = 1.
struct Plane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double offset = 0.0;
  [[nodiscard]] double signedDistance(const Eigen::Vector3d& X) const {
    return normal.dot(X) - offset;
  }
};

double medianOf(std::vector<double>& v) {
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  return v[mid];
}

/// The point cloud's scale: median distance of the points to their coordinate-wise median.
double cloudScale(const std::vector<Eigen::Vector3d>& points) {
  std::vector<double> values(points.size());
  Eigen::Vector3d centre;
  for (int a = 0; a < 3; ++a) {
    for (std::size_t i = 0; i < points.size(); ++i) values[i] = points[i][a];
    centre[a] = medianOf(values);
  }
  for (std::size_t i = 0; i < points.size(); ++i) values[i] = (points[i] - centre).norm();
  return medianOf(values);
}

/// Least-squares plane of the marked points: through their centroid, normal along the
/// eigenvector of the smallest eigenvalue of their scatter matrix (total least squares).
bool fitPlane(const std::vector<Eigen::Vector3d>& points, const std::vector<uint8_t>& inlier,
              Plane& plane, Eigen::Vector3d& centroid) {
  centroid.setZero();
  int n = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (inlier[i] == 0) continue;
    centroid += points[i];
    ++n;
  }
  if (n < 3) return false;
  centroid /= n;
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (inlier[i] == 0) continue;
    const Eigen::Vector3d d = points[i] - centroid;
    scatter += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
  if (eig.info() != Eigen::Success) return false;
  plane.normal = eig.eigenvectors().col(0).normalized();  // eigenvalues ascending
  plane.offset = plane.normal.dot(centroid);
  return plane.normal.allFinite();
}

int markInliers(const std::vector<Eigen::Vector3d>& points, const Plane& plane, double threshold,
                std::vector<uint8_t>& inlier) {
  int count = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    inlier[i] = std::abs(plane.signedDistance(points[i])) < threshold ? 1 : 0;
    count += inlier[i];
  }
  return count;
}

struct PlaneFit {
  bool found = false;
  Plane plane;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  int inliers = 0;
  double median_camera_distance = 0.0;
};

struct PlaneCandidate {
  Plane plane;
  int count = 0;
};

/// RANSAC on 3-point samples (Fischler & Bolles 1981): the largest consensus set wins (the first
/// one on ties). With `up` set, only planes whose normal makes at most acos(min_cos_up) with it
/// are considered (the ground search).
PlaneCandidate ransacPlane(const std::vector<Eigen::Vector3d>& points, double threshold,
                           const SceneFrameOptions& options, const Eigen::Vector3d* up,
                           double min_cos_up) {
  PlaneCandidate best;
  const std::size_t n = points.size();
  SampleGenerator rng(options.seed);
  for (int it = 0; it < options.ransac_iterations; ++it) {
    const std::size_t a = rng.index(n);
    const std::size_t b = rng.index(n);
    const std::size_t c = rng.index(n);
    if (a == b || b == c || a == c) continue;
    const Eigen::Vector3d normal = (points[b] - points[a]).cross(points[c] - points[a]);
    const double norm = normal.norm();
    // Nearly collinear samples define no plane (area tiny relative to the threshold squared).
    if (!(norm > threshold * threshold)) continue;
    Plane candidate;
    candidate.normal = normal / norm;
    candidate.offset = candidate.normal.dot(points[a]);
    if (up != nullptr && std::abs(candidate.normal.dot(*up)) < min_cos_up) continue;
    int count = 0;
    for (const Eigen::Vector3d& X : points) {
      count += std::abs(candidate.signedDistance(X)) < threshold ? 1 : 0;
    }
    if (count > best.count) {
      best.count = count;
      best.plane = candidate;
    }
  }
  return best;
}

/// Two rounds of least-squares refit and re-classification of a RANSAC plane, the size test, the
/// orientation (median signed camera distance positive) and the camera distance.
PlaneFit refinePlane(const std::vector<Eigen::Vector3d>& points, std::span<const ScenePose> cameras,
                     const PlaneCandidate& candidate, double threshold,
                     const SceneFrameOptions& options) {
  PlaneFit fit;
  const std::size_t n = points.size();
  if (candidate.count < 3) return fit;
  std::vector<uint8_t> inlier(n, 0);
  fit.plane = candidate.plane;
  fit.inliers = markInliers(points, fit.plane, threshold, inlier);
  for (int round = 0; round < 2; ++round) {
    Plane refit;
    if (!fitPlane(points, inlier, refit, fit.centroid)) return fit;
    fit.plane = refit;
    const int count = markInliers(points, fit.plane, threshold, inlier);
    if (count < 3) return fit;
    fit.inliers = count;
  }
  if (!fitPlane(points, inlier, fit.plane, fit.centroid)) return fit;

  const double needed = std::max(static_cast<double>(options.min_plane_inliers),
                                 options.min_plane_fraction * static_cast<double>(n));
  if (static_cast<double>(fit.inliers) < needed) return fit;

  std::vector<double> signed_distances(cameras.size());
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    signed_distances[i] = fit.plane.signedDistance(cameras[i].p_wc);
  }
  if (medianOf(signed_distances) < 0.0) {
    fit.plane.normal = -fit.plane.normal;
    fit.plane.offset = -fit.plane.offset;
  }
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    signed_distances[i] = std::abs(fit.plane.signedDistance(cameras[i].p_wc));
  }
  fit.median_camera_distance = medianOf(signed_distances);
  // Cameras on the plane (a wall seen edge-on, a degenerate solve) give no usable scale.
  fit.found = fit.median_camera_distance > threshold;
  return fit;
}

/// The cameras' mean "up" direction (their image -y axis in the world), or zero when they
/// disagree too much (|mean| < 0.5) to define one.
Eigen::Vector3d camerasUp(std::span<const ScenePose> cameras) {
  Eigen::Vector3d up = Eigen::Vector3d::Zero();
  for (const ScenePose& c : cameras) up -= c.R_wc.col(1);
  up /= static_cast<double>(cameras.size());
  return up.norm() >= 0.5 ? Eigen::Vector3d(up.normalized()) : Eigen::Vector3d::Zero();
}

/// The dominant plane (largest RANSAC consensus). With options.prefer_ground, when that plane is
/// steep relative to the cameras' mean up direction (a wall), a second RANSAC restricted to
/// planes within options.ground_max_tilt_deg of "up" looks for a ground; it is preferred when
/// it holds at least options.ground_min_ratio of the dominant plane's inliers.
PlaneFit findDominantPlane(const std::vector<Eigen::Vector3d>& points,
                           std::span<const ScenePose> cameras, double threshold,
                           const SceneFrameOptions& options) {
  if (points.size() < 3 || !(threshold > 0.0)) return PlaneFit{};
  PlaneFit fit = refinePlane(points, cameras, ransacPlane(points, threshold, options, nullptr, 0.0),
                             threshold, options);
  if (!options.prefer_ground) return fit;
  const Eigen::Vector3d up = camerasUp(cameras);
  if (up.isZero()) return fit;
  const double min_cos = std::cos(options.ground_max_tilt_deg * std::numbers::pi / 180.0);
  if (fit.found && std::abs(fit.plane.normal.dot(up)) >= min_cos) return fit;
  PlaneFit ground = refinePlane(
      points, cameras, ransacPlane(points, threshold, options, &up, min_cos), threshold, options);
  const bool level = std::abs(ground.plane.normal.dot(up)) >= min_cos;  // still after the refit
  if (ground.found && level &&
      (!fit.found ||
       static_cast<double>(ground.inliers) >= options.ground_min_ratio * fit.inliers)) {
    return ground;
  }
  return fit;
}

/// Rows: the scene axes in world coordinates (x from the first camera's x projected onto the
/// plane, z the normal, y = z x x).
Eigen::Matrix3d planeRotation(const Eigen::Vector3d& normal, const ScenePose& first) {
  Eigen::Vector3d x = first.R_wc.col(0) - normal.dot(first.R_wc.col(0)) * normal;
  if (x.norm() < 1e-6) {
    // The camera's x axis is along the normal: use its viewing direction instead.
    x = first.R_wc.col(2) - normal.dot(first.R_wc.col(2)) * normal;
  }
  if (x.norm() < 1e-6) x = normal.unitOrthogonal();
  x.normalize();
  const Eigen::Vector3d y = normal.cross(x);
  Eigen::Matrix3d R;
  R.row(0) = x.transpose();
  R.row(1) = y.transpose();
  R.row(2) = normal.transpose();
  return R;
}

/// Scale of the first-camera frame: 1 / median depth of the points in front of the first camera,
/// or 1 / distance to the farthest camera when no point is in front.
double firstCameraScale(const std::vector<Eigen::Vector3d>& points,
                        std::span<const ScenePose> cameras) {
  const ScenePose& first = cameras.front();
  std::vector<double> depths;
  depths.reserve(points.size());
  for (const Eigen::Vector3d& X : points) {
    const double z = first.R_wc.col(2).dot(X - first.p_wc);
    if (z > 0.0) depths.push_back(z);
  }
  if (!depths.empty()) {
    const double median_depth = medianOf(depths);
    if (median_depth > 0.0) return 1.0 / median_depth;
  }
  double farthest = 0.0;
  for (const ScenePose& c : cameras) farthest = std::max(farthest, (c.p_wc - first.p_wc).norm());
  return farthest > 0.0 ? 1.0 / farthest : 1.0;
}

Similarity3 makeSimilarity(double scale, const Eigen::Matrix3d& R, const Eigen::Vector3d& origin) {
  Similarity3 S;
  S.scale = scale;
  S.R = R;
  S.t = -scale * (R * origin);
  return S;
}

}  // namespace

SceneFrame computeSceneFrame(std::span<const Eigen::Vector3d> points,
                             std::span<const int64_t> point_ids, std::span<const ScenePose> cameras,
                             const SceneFrameOptions& options) {
  SceneFrame frame;
  if (cameras.empty()) return frame;
  for (const ScenePose& c : cameras) {
    if (!c.R_wc.allFinite() || !c.p_wc.allFinite()) return frame;
  }
  const bool by_track = options.origin == SceneOrigin::kTrack;
  if (by_track && point_ids.size() != points.size()) return frame;

  std::vector<Eigen::Vector3d> finite;
  finite.reserve(points.size());
  bool track_found = false;
  Eigen::Vector3d track_point = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) continue;
    finite.push_back(points[i]);
    if (by_track && point_ids[i] == options.track_id) {
      track_found = true;
      track_point = points[i];
    }
  }

  PlaneFit plane;
  if (options.origin != SceneOrigin::kFirstCamera && finite.size() >= 3) {
    frame.inlier_threshold = options.inlier_threshold_fraction * cloudScale(finite);
    plane = findDominantPlane(finite, cameras, frame.inlier_threshold, options);
  }
  frame.plane_found = plane.found;
  frame.plane_inliers = plane.inliers;
  if (plane.found) {
    frame.plane_normal = plane.plane.normal;
    frame.plane_offset = plane.plane.offset;
  }

  const ScenePose& first = cameras.front();
  Eigen::Matrix3d R;
  double scale = 1.0;
  Eigen::Vector3d origin;
  if (plane.found) {
    R = planeRotation(plane.plane.normal, first);
    scale = 1.0 / plane.median_camera_distance;
    origin = plane.centroid;
    frame.origin_used = SceneOrigin::kPlane;
  } else {
    R = first.R_wc.transpose();
    scale = firstCameraScale(finite, cameras);
    origin = first.p_wc;
    frame.origin_used = SceneOrigin::kFirstCamera;
  }
  if (by_track && track_found) {
    origin = track_point;
    frame.origin_used = SceneOrigin::kTrack;
  }
  frame.world_to_scene = makeSimilarity(scale, R, origin);

  if (by_track && !track_found) {
    frame.status = SceneFrameStatus::kTrackNotFound;
  } else if (options.origin != SceneOrigin::kFirstCamera && !plane.found) {
    frame.status = SceneFrameStatus::kPlaneNotFound;
  } else {
    frame.status = SceneFrameStatus::kOk;
  }
  return frame;
}

void applySimilarity(const Similarity3& S, std::span<ScenePose> cameras,
                     std::span<Eigen::Vector3d> points) {
  for (ScenePose& c : cameras) {
    c.p_wc = S.apply(c.p_wc);
    c.R_wc = S.R * c.R_wc;
  }
  for (Eigen::Vector3d& X : points) X = S.apply(X);
}

const char* describe(SceneFrameStatus status) {
  switch (status) {
    case SceneFrameStatus::kOk:
      return "ok";
    case SceneFrameStatus::kPlaneNotFound:
      return "no dominant plane: the first camera's axes and scale were used";
    case SceneFrameStatus::kTrackNotFound:
      return "the requested track is not a scene point: the plane (or first-camera) frame was used";
    case SceneFrameStatus::kInvalidInput:
      return "invalid input (no camera or non-finite values): identity frame";
  }
  return "unknown";
}

}  // namespace epitrack
