#include "algo/sfm/scene_frame.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include <Eigen/Cholesky>
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
/// one on ties).
// The plane through three sampled points (one RANSAC draw); false for a repeated index or a nearly
// collinear sample (area tiny relative to the threshold squared), which defines no plane.
bool samplePlane(const std::vector<Eigen::Vector3d>& points, double threshold, SampleGenerator& rng,
                 Plane& plane) {
  const std::size_t n = points.size();
  const std::size_t a = rng.index(n);
  const std::size_t b = rng.index(n);
  const std::size_t c = rng.index(n);
  if (a == b || b == c || a == c) return false;
  const Eigen::Vector3d normal = (points[b] - points[a]).cross(points[c] - points[a]);
  const double norm = normal.norm();
  if (!(norm > threshold * threshold)) return false;
  plane.normal = normal / norm;
  plane.offset = plane.normal.dot(points[a]);
  return true;
}

PlaneCandidate ransacPlane(const std::vector<Eigen::Vector3d>& points, double threshold,
                           const SceneFrameOptions& options) {
  PlaneCandidate best;
  SampleGenerator rng(options.seed);
  for (int it = 0; it < options.ransac_iterations; ++it) {
    Plane candidate;
    if (!samplePlane(points, threshold, rng, candidate)) continue;
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

/// The cameras' up: the robust mean of their image-up axes (-y of each camera in the world).
/// Two rounds drop the axes more than 60 degrees from the current mean (a camera rolled on its
/// side, a bad pose). Confidence: the length of the mean of all unit axes counted as inliers
/// times their fraction (1: every camera agrees, 0: no common up).
struct CameraUp {
  Eigen::Vector3d up = Eigen::Vector3d::Zero();  ///< zero when undefined
  double confidence = 0.0;
  double spread_deg = 0.0;
};

CameraUp estimateCameraUp(std::span<const ScenePose> cameras) {
  CameraUp result;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const ScenePose& c : cameras) mean -= c.R_wc.col(1);
  if (mean.norm() < 1e-9) return result;
  Eigen::Vector3d direction = mean.normalized();
  const double cos_keep = std::cos(60.0 * std::numbers::pi / 180.0);
  double length = 0.0;
  for (int round = 0; round < 2; ++round) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    int kept = 0;
    for (const ScenePose& c : cameras) {
      const Eigen::Vector3d axis = -c.R_wc.col(1);
      if (axis.dot(direction) < cos_keep) continue;
      sum += axis;
      ++kept;
    }
    if (kept == 0 || sum.norm() < 1e-9) return result;
    direction = sum.normalized();
    length = sum.norm() / static_cast<double>(cameras.size());  // inlier fraction included
  }
  // Pitch bias: cameras looking down lean their image-up axes towards the view, while their x
  // axes (image right) stay level as long as the camera is not rolled. So prefer the direction
  // the kept x axes are all perpendicular to: minimise sum (x_i . u)^2 + w n |u - mean|^2, i.e.
  // u ~ (X + w n I)^-1 mean with X = sum x_i x_i^T. When the cameras panned, X has a clear null
  // direction (the true up) and it wins; when they all face one way, X only removes the roll
  // component from the mean and the pitch lean stays (it cannot be told from the cameras).
  constexpr double kMeanWeight = 0.05;
  Eigen::Matrix3d X = Eigen::Matrix3d::Zero();
  Eigen::Vector3d kept_mean = Eigen::Vector3d::Zero();
  int kept = 0;
  for (const ScenePose& c : cameras) {
    if (-c.R_wc.col(1).dot(direction) < cos_keep) continue;
    X += c.R_wc.col(0) * c.R_wc.col(0).transpose();
    kept_mean -= c.R_wc.col(1);
    ++kept;
  }
  if (kept > 0) {
    const double w = kMeanWeight * kept;
    const Eigen::Vector3d u =
        (X + w * Eigen::Matrix3d::Identity()).ldlt().solve(w * kept_mean / kept);
    if (u.allFinite() && u.norm() > 1e-9 && u.dot(direction) > 0.0) direction = u.normalized();
  }
  std::vector<double> angles;
  angles.reserve(cameras.size());
  for (const ScenePose& c : cameras) {
    angles.push_back(std::acos(std::clamp(-c.R_wc.col(1).dot(direction), -1.0, 1.0)));
  }
  result.up = direction;
  result.confidence = length;
  result.spread_deg = medianOf(angles) * 180.0 / std::numbers::pi;
  return result;
}

/// Counts for a ground candidate (normal oriented along `up`): inliers, points clearly below,
/// and whether the cameras are above it (median signed distance positive).
struct GroundSupport {
  int inliers = 0;
  int below = 0;
  bool cameras_above = false;
};

GroundSupport groundSupport(const std::vector<Eigen::Vector3d>& points,
                            std::span<const ScenePose> cameras, const Plane& plane,
                            double threshold, std::vector<double>& scratch) {
  GroundSupport s;
  for (const Eigen::Vector3d& X : points) {
    const double d = plane.signedDistance(X);
    s.inliers += std::abs(d) < threshold ? 1 : 0;
    s.below += d < -3.0 * threshold ? 1 : 0;
  }
  scratch.resize(cameras.size());
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    scratch[i] = plane.signedDistance(cameras[i].p_wc);
  }
  s.cameras_above = medianOf(scratch) > threshold;
  return s;
}

/// The ground: RANSAC over 3-point samples (Fischler & Bolles 1981) restricted to planes within
/// options.ground_max_tilt_deg of `up`, with the cameras above and at most
/// options.ground_max_below_fraction of the points below; the largest consensus wins. Refined by
/// least squares like the dominant plane and checked again after the refit.
PlaneFit findGroundPlane(const std::vector<Eigen::Vector3d>& points,
                         std::span<const ScenePose> cameras, const Eigen::Vector3d& up,
                         double threshold, const SceneFrameOptions& options) {
  PlaneFit none;
  const std::size_t n = points.size();
  if (n < 3 || !(threshold > 0.0)) return none;
  const double min_cos = std::cos(options.ground_max_tilt_deg * std::numbers::pi / 180.0);
  const double max_below = options.ground_max_below_fraction * static_cast<double>(n);
  std::vector<double> scratch;
  auto acceptable = [&](const Plane& plane, int& inliers) {
    if (plane.normal.dot(up) < min_cos) return false;
    const GroundSupport s = groundSupport(points, cameras, plane, threshold, scratch);
    inliers = s.inliers;
    return s.cameras_above && static_cast<double>(s.below) <= max_below;
  };
  PlaneCandidate best;
  SampleGenerator rng(options.seed);
  for (int it = 0; it < options.ransac_iterations; ++it) {
    Plane candidate;
    if (!samplePlane(points, threshold, rng, candidate)) continue;
    if (candidate.normal.dot(up) < 0.0) {  // negation is exact: the same plane, facing up
      candidate.normal = -candidate.normal;
      candidate.offset = -candidate.offset;
    }
    int inliers = 0;
    if (!acceptable(candidate, inliers)) continue;
    if (inliers > best.count) {
      best.count = inliers;
      best.plane = candidate;
    }
  }
  PlaneFit fit = refinePlane(points, cameras, best, threshold, options);
  if (!fit.found) return none;
  // refinePlane oriented the normal towards the cameras; a ground's must also point up.
  int inliers = 0;
  if (!acceptable(fit.plane, inliers)) return none;
  return fit;
}

/// The dominant plane (largest RANSAC consensus, any tilt).
PlaneFit findDominantPlane(const std::vector<Eigen::Vector3d>& points,
                           std::span<const ScenePose> cameras, double threshold,
                           const SceneFrameOptions& options) {
  if (points.size() < 3 || !(threshold > 0.0)) return PlaneFit{};
  return refinePlane(points, cameras, ransacPlane(points, threshold, options), threshold, options);
}

/// The ground without a plane: horizontal (normal `up`) at the options.ground_height_quantile
/// of the points' heights, origin under the points' median; `scale` from the median camera height
/// (0 when the cameras are not above it).
struct CameraGround {
  Plane plane;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  double median_camera_height = 0.0;
};

CameraGround groundUnderPoints(const std::vector<Eigen::Vector3d>& points,
                               std::span<const ScenePose> cameras, const Eigen::Vector3d& up,
                               const SceneFrameOptions& options) {
  CameraGround g;
  std::vector<double> values(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) values[i] = up.dot(points[i]);
  const double q = std::clamp(options.ground_height_quantile, 0.0, 1.0);
  const std::size_t k =
      std::min(points.size() - 1, static_cast<std::size_t>(q * static_cast<double>(points.size())));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  g.plane.normal = up;
  g.plane.offset = values[k];
  Eigen::Vector3d centre;
  for (int a = 0; a < 3; ++a) {
    for (std::size_t i = 0; i < points.size(); ++i) values[i] = points[i][a];
    centre[a] = medianOf(values);
  }
  g.origin = centre - g.plane.signedDistance(centre) * up;
  values.resize(cameras.size());
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    values[i] = g.plane.signedDistance(cameras[i].p_wc);
  }
  g.median_camera_height = std::max(0.0, medianOf(values));
  return g;
}

/// The ground normal levelled with the cameras' x axes: hand-held, tripod and vehicle footage
/// keeps the image's horizontal level (little roll), so up is perpendicular to every x axis,
/// while a plane fitted to a grazing band of road, kerb and verge can roll by several degrees.
/// Minimises sum (x_i . u)^2 + w k |u - normal|^2 over the k cameras whose image-up is within 60
/// degrees of `up` (u = (X + w k I)^-1 w k normal): the components the x axes pin down follow
/// them, the rest (the pitch a forward-facing clip cannot tell) stays the plane's.
Eigen::Vector3d levelWithCameraAxes(const Eigen::Vector3d& normal,
                                    std::span<const ScenePose> cameras, const Eigen::Vector3d& up) {
  constexpr double kPlaneWeight = 0.05;
  const double cos_keep = std::cos(60.0 * std::numbers::pi / 180.0);
  Eigen::Matrix3d X = Eigen::Matrix3d::Zero();
  int kept = 0;
  for (const ScenePose& c : cameras) {
    if (-c.R_wc.col(1).dot(up) < cos_keep) continue;
    X += c.R_wc.col(0) * c.R_wc.col(0).transpose();
    ++kept;
  }
  if (kept == 0) return normal;
  const double w = kPlaneWeight * kept;
  const Eigen::Vector3d u = (X + w * Eigen::Matrix3d::Identity()).ldlt().solve(w * normal);
  if (!u.allFinite() || u.norm() < 1e-9 || u.dot(normal) <= 0.0) return normal;
  return u.normalized();
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
  CameraGround camera_ground;
  bool use_camera_ground = false;
  if (options.origin != SceneOrigin::kFirstCamera && finite.size() >= 3) {
    frame.inlier_threshold = options.inlier_threshold_fraction * cloudScale(finite);
    if (options.up_from_cameras) {
      const CameraUp up = estimateCameraUp(cameras);
      frame.up_confidence = up.confidence;
      frame.up_spread_deg = up.spread_deg;
      if (!up.up.isZero() && up.confidence >= options.min_up_confidence) {
        frame.camera_up = up.up;
        plane = findGroundPlane(finite, cameras, up.up, frame.inlier_threshold, options);
        if (!plane.found) {
          // No ground, but a wall is vertical: when the dominant plane is within
          // ground_max_tilt_deg of vertical, up lies in it. Removing the normal component takes
          // out the lean of cameras that look up or down at the wall.
          Eigen::Vector3d level_up = up.up;
          const PlaneFit wall = findDominantPlane(finite, cameras, frame.inlier_threshold, options);
          const double max_sin = std::sin(options.ground_max_tilt_deg * std::numbers::pi / 180.0);
          // A correction of at most kMaxWallCorrectionDeg: a lean of the cameras, not a plane
          // through an object that merely happens to be steep.
          constexpr double kMaxWallCorrectionDeg = 15.0;
          if (wall.found &&
              std::abs(wall.plane.normal.dot(level_up)) <
                  std::min(max_sin, std::sin(kMaxWallCorrectionDeg * std::numbers::pi / 180.0))) {
            level_up -= wall.plane.normal.dot(level_up) * wall.plane.normal;
            level_up.normalize();
          }
          camera_ground = groundUnderPoints(finite, cameras, level_up, options);
          use_camera_ground = camera_ground.median_camera_height > frame.inlier_threshold;
          if (use_camera_ground) {
            frame.camera_up = level_up;
          } else if (level_up != up.up) {
            camera_ground = groundUnderPoints(finite, cameras, up.up, options);
            use_camera_ground = camera_ground.median_camera_height > frame.inlier_threshold;
          }
        }
      }
    }
    if (frame.camera_up.isZero()) {
      plane = findDominantPlane(finite, cameras, frame.inlier_threshold, options);
    }
  }
  frame.plane_up_angle_deg = std::numeric_limits<double>::quiet_NaN();
  if (plane.found && !frame.camera_up.isZero()) {
    frame.plane_up_angle_deg =
        std::acos(std::clamp(plane.plane.normal.dot(frame.camera_up), -1.0, 1.0)) * 180.0 /
        std::numbers::pi;
    if (options.level_ground_with_cameras) {
      // Through the same inlier centroid, with the levelled normal; the cameras stay above.
      Plane levelled;
      levelled.normal = levelWithCameraAxes(plane.plane.normal, cameras, frame.camera_up);
      levelled.offset = levelled.normal.dot(plane.centroid);
      std::vector<double> heights(cameras.size());
      for (std::size_t i = 0; i < cameras.size(); ++i) {
        heights[i] = levelled.signedDistance(cameras[i].p_wc);
      }
      const double median_height = medianOf(heights);
      if (median_height > frame.inlier_threshold) {
        plane.plane = levelled;
        plane.median_camera_distance = median_height;
      }
    }
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
    frame.ground = SceneGround::kPlane;
  } else if (use_camera_ground) {
    R = planeRotation(camera_ground.plane.normal, first);
    scale = 1.0 / camera_ground.median_camera_height;
    origin = camera_ground.origin;
    frame.origin_used = SceneOrigin::kPlane;
    frame.ground = SceneGround::kCameras;
    frame.plane_normal = camera_ground.plane.normal;
    frame.plane_offset = camera_ground.plane.offset;
  } else {
    R = first.R_wc.transpose();
    scale = firstCameraScale(finite, cameras);
    origin = first.p_wc;
    frame.origin_used = SceneOrigin::kFirstCamera;
    frame.ground = SceneGround::kNone;
  }
  if (by_track && track_found) {
    origin = track_point;
    frame.origin_used = SceneOrigin::kTrack;
  }
  frame.world_to_scene = makeSimilarity(scale, R, origin);

  if (by_track && !track_found) {
    frame.status = SceneFrameStatus::kTrackNotFound;
  } else if (options.origin != SceneOrigin::kFirstCamera && use_camera_ground) {
    frame.status = SceneFrameStatus::kGroundFromCameras;
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
    case SceneFrameStatus::kGroundFromCameras:
      return "no level plane: up from the cameras, the ground under the reconstructed points";
    case SceneFrameStatus::kTrackNotFound:
      return "the requested track is not a scene point: the plane (or first-camera) frame was used";
    case SceneFrameStatus::kInvalidInput:
      return "invalid input (no camera or non-finite values): identity frame";
  }
  return "unknown";
}

}  // namespace epitrack
