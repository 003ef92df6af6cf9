#pragma once

#include <cstdint>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace epitrack::synth {

/// The named camera motions of `epitrack-synth --scene`.
enum class SceneKind {
  kOrbit,      ///< arc of radius 6 m around a look-at target (which may wander), 0.25 deg/frame
  kDolly,      ///< forward motion towards a wall (<= 1.5 cm/frame), looking at a fixed far point
  kPan,        ///< pure rotation about the camera centre (yaw +-30 deg, slight tilt)
  kHandheld,   ///< slow sideways walk (5 mm/frame) looking at the boxes, plus seeded shake
  kPlanar,     ///< one textured plane seen from a moving, turning camera
  kShake,      ///< distant room from a slow sideways drift, hand-held jitter of 1-8 Hz and jerks
  kFastPan,    ///< fast back-and-forth pan (up to ~3.5 deg/frame, reversals) while walking sideways
  kOcclusion,  ///< orbit (0.35 deg/frame) around pillars at several depths that cross in the image
};

bool parseSceneKind(const std::string& name, SceneKind& kind);
const char* sceneKindName(SceneKind kind);

/// Camera-to-world pose T_wc: x_w = R_wc * x_c + t_wc (t_wc is the camera centre).
struct Pose {
  Eigen::Matrix3d R_wc = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t_wc = Eigen::Vector3d::Zero();
};

/// Camera at `eye` looking at `target` with world up +z (camera y points down in the image).
Pose lookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target);

struct TrajectoryParams {
  SceneKind kind = SceneKind::kOrbit;
  int frames = 100;
  double target_wander = 0.0;     ///< orbit only: amplitude (m) of the look-at target's motion
  double orbit_speed_deg = 0.25;  ///< orbit only: degrees of arc per frame
  double shake_deg = 2.0;         ///< shake only: peak rotational jitter (degrees), jerks scale too
  /// fastpan only: the centre's sideways walk per frame in metres (its forward drift and bob
  /// scale with it); 0 is a true tripod shot with the same rotation.
  double walk_m = 0.012;
  uint64_t seed = 1;
};

/// The pose at frame time `t` (frame units; fractional times are used for motion blur and for
/// the rows of a rolling shutter). Every trajectory is a smooth function of `t`, also for t < 0.
Pose trajectoryPose(const TrajectoryParams& params, double t);

/// Shake only: the jitter rotation vector (axis * angle, radians, camera frame: x right, y down,
/// z forward) that kShake applies on top of its smooth path at time `t`; zero for other kinds.
Eigen::Vector3d shakeRotation(const TrajectoryParams& params, double t);

}  // namespace epitrack::synth
