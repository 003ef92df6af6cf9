#pragma once

// The user-facing coordinate frame of a solve (issue 6 "Coordinate frame"): a monocular
// reconstruction is only defined up to a similarity, so the solver picks one that an artist can
// use directly.
//
// Modes
// - plane (default): "up" comes from the cameras and the ground from the points (issue 23).
//   Hand-held, tripod and vehicle footage is shot roughly level, so the robust mean of the
//   cameras' image-up axes (each camera's -y in the world) is the scene's up, and the spread of
//   those axes says how much to trust it. The ground is the best-supported plane (RANSAC) whose
//   normal is within SceneFrameOptions::ground_max_tilt_deg of that up, with the cameras above it
//   and few points below it (a floor, a road, a table top: not a wall, not a ceiling, not a slice
//   through an object). Scene +Z is its normal, oriented towards the cameras; the origin is the
//   centroid of its inlier points; the scale makes the median camera-to-plane distance 1.
//   Without such a plane (a wall-only shot, an object on a turntable), +Z is the cameras' up and
//   the ground is the horizontal plane under the reconstructed points (a low quantile of their
//   heights), the origin below the points' median, the scale again the median camera height.
//   When the cameras disagree about up (confidence below min_up_confidence), the dominant plane
//   is used as before (normal towards the cameras), and failing that the first camera's frame.
//   In every ground frame +X is the first camera's x axis (image right) projected onto the
//   ground and +Y = Z x X.
// - first-camera: the first camera's frame: origin at its centre, its axes (x right, y down,
//   z forward, so "up" is -Y), and the scale makes the median depth of the points in front of it 1
//   (if no point is in front, the distance from the first camera to the farthest camera is 1).
// - track:ID: origin at the point with that id; orientation and scale from the ground when one is
//   found, otherwise the first camera's axes and scale.
// A plane is "found" when it holds enough inliers (SceneFrameOptions) and the cameras are not on
// it.

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
  /// Up from the cameras (issue 23): when false, the dominant plane is the ground whatever its
  /// tilt (the behaviour before issue 23).
  bool up_from_cameras = true;
  /// The cameras' up is trusted when the length of the mean of their unit image-up axes (1: all
  /// parallel, 0: no agreement) is at least this.
  double min_up_confidence = 0.5;
  /// A ground plane's normal is at most this far from the cameras' up.
  double ground_max_tilt_deg = 30.0;
  /// A ground has at most this fraction of the points clearly (3 inlier thresholds) below it.
  double ground_max_below_fraction = 0.2;
  /// Level the ground plane's normal with the cameras' x axes (image right), which stay level in
  /// footage shot without roll: removes the roll of a plane fitted to a grazing band of ground.
  bool level_ground_with_cameras = true;
  /// Without a level plane, the ground height is this quantile of the points' heights along up.
  double ground_height_quantile = 0.05;
};

/// What the scene's ground (z = 0, +z up) was taken from.
enum class SceneGround {
  kNone,     ///< no ground: the first camera's frame (-y up)
  kPlane,    ///< a fitted plane (level with the cameras' up when that was known)
  kCameras,  ///< the cameras' up, the ground under the reconstructed points
};

enum class SceneFrameStatus {
  kOk,                 ///< the requested frame was built
  kPlaneNotFound,      ///< no dominant plane (or cameras on it): first-camera axes/scale used
  kGroundFromCameras,  ///< no level plane: up from the cameras, the ground under the points
  kTrackNotFound,      ///< track:ID names no point: the plane (or first-camera) frame was used
  kInvalidInput,       ///< no camera or non-finite input: identity returned
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
  SceneGround ground = SceneGround::kNone;
  /// The cameras' up (world, unit; zero when the cameras did not define one), the length of the
  /// mean of their image-up axes (0..1, the confidence) and the median angle of those axes to
  /// the robust mean (degrees).
  Eigen::Vector3d camera_up = Eigen::Vector3d::Zero();
  double up_confidence = 0.0;
  double up_spread_deg = 0.0;
  /// Angle between the fitted plane's normal (before levelling) and camera_up (degrees), NaN
  /// without either. plane_normal is the levelled normal.
  double plane_up_angle_deg = 0.0;
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
