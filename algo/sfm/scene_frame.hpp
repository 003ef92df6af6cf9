#pragma once

// The user-facing coordinate frame of a solve (issue 6 "Coordinate frame"): a monocular
// reconstruction is only defined up to a similarity, so the solver picks one that an artist can
// use directly.
//
// Modes
// - plane (default): a dominant plane is fitted to the scene points by RANSAC (the ground or a
//   table; a level plane is preferred to a larger wall, see SceneFrameOptions::prefer_ground).
//   Scene +Z is the plane normal, oriented towards the cameras (so +Z is "up" and the cameras are
//   at z > 0, as in Blender); scene +X is the first camera's x axis (image right) projected onto
//   the plane; +Y = Z x X. The origin is the centroid of the plane's inlier points (it lies on the
//   least-squares plane). The scale makes the median camera-to-plane distance 1.
// - first-camera: the first camera's frame: origin at its centre, its axes (x right, y down,
//   z forward, so "up" is -Y), and the scale makes the median depth of the points in front of it 1
//   (if no point is in front, the distance from the first camera to the farthest camera is 1).
// - track:ID: origin at the point with that id; orientation and scale from the plane when one is
//   found, otherwise the first camera's axes and scale.
// A plane is "found" when it holds enough inliers (SceneFrameOptions) and the cameras are not on
// it; otherwise the first-camera frame is used and the status says so.

#include <cstdint>
#include <span>

#include <Eigen/Core>

namespace epitrack {

/// x_scene = scale * R * x_world + t (a proper rotation R, scale > 0).
struct Similarity3 {
  double scale = 1.0;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();

  [[nodiscard]] Eigen::Vector3d apply(const Eigen::Vector3d& X) const {
    return scale * (R * X) + t;
  }
};

/// A camera pose T_wc (camera -> world), ARCHITECTURE.md convention.
struct ScenePose {
  Eigen::Matrix3d R_wc = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_wc = Eigen::Vector3d::Zero();
};

enum class SceneOrigin { kPlane, kFirstCamera, kTrack };

struct SceneFrameOptions {
  SceneOrigin origin = SceneOrigin::kPlane;
  int64_t track_id = -1;  ///< the point for SceneOrigin::kTrack
  int ransac_iterations = 1000;
  /// Inlier threshold as a fraction of the point-cloud scale (the median distance of the points to
  /// their coordinate-wise median).
  double inlier_threshold_fraction = 0.01;
  int min_plane_inliers = 12;       ///< a plane needs at least this many inliers ...
  double min_plane_fraction = 0.2;  ///< ... and this fraction of the points
  uint64_t seed = 0x5eed;           ///< RANSAC samples are deterministic for a seed
  /// Prefer a ground to a wall: when the dominant plane is tilted more than ground_max_tilt_deg
  /// from the cameras' mean up direction (their image -y), a level plane holding at least
  /// ground_min_ratio of the dominant plane's inliers is used instead (the issue asks for "the
  /// ground or a table").
  bool prefer_ground = true;
  double ground_max_tilt_deg = 30.0;
  double ground_min_ratio = 0.3;
};

enum class SceneFrameStatus {
  kOk,             ///< the requested frame was built
  kPlaneNotFound,  ///< no dominant plane (or cameras on it): first-camera axes/scale used
  kTrackNotFound,  ///< track:ID names no point: the plane (or first-camera) frame was used
  kInvalidInput,   ///< no camera or non-finite input: identity returned
};

struct SceneFrame {
  SceneFrameStatus status = SceneFrameStatus::kInvalidInput;
  Similarity3 world_to_scene;
  SceneOrigin origin_used = SceneOrigin::kFirstCamera;  ///< what the transform actually is
  bool plane_found = false;
  Eigen::Vector3d plane_normal = Eigen::Vector3d::UnitZ();  ///< world frame, towards the cameras
  double plane_offset = 0.0;                                ///< plane: normal . X = offset (world)
  int plane_inliers = 0;
  double inlier_threshold = 0.0;  ///< world units
};

/// Chooses the scene frame (see the file comment). `point_ids` may be empty unless the origin is
/// kTrack; otherwise it parallels `points`. `cameras` are the solved cameras, the first one being
/// the "first camera". Deterministic for a seed. Allocates working buffers (called once per
/// solve).
SceneFrame computeSceneFrame(std::span<const Eigen::Vector3d> points,
                             std::span<const int64_t> point_ids, std::span<const ScenePose> cameras,
                             const SceneFrameOptions& options);

/// Maps poses and points into the scene frame in place: p <- s R p + t, R_wc <- R R_wc.
void applySimilarity(const Similarity3& S, std::span<ScenePose> cameras,
                     std::span<Eigen::Vector3d> points);

/// The status as a short sentence (for summary.json / messages).
const char* describe(SceneFrameStatus status);

}  // namespace epitrack
