#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "algo/geometry/camera_intrinsics.hpp"

namespace epitrack::hal {

/// One line of a trajectory file (ARCHITECTURE.md "File formats"): `t tx ty tz qx qy qz qw`,
/// the pose T_wc (camera centre, camera-to-world rotation as a unit Hamilton quaternion).
struct TrajectoryEntry {
  double t = 0.0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
};

/// Parses a trajectory; `#` comment and blank lines are skipped. Errors name the line. Quaternions
/// are normalised; a zero or non-finite one is an error.
bool parseTrajectory(const std::string& text, std::vector<TrajectoryEntry>& entries,
                     std::string& error);
/// Formats entries one per line (frame-index times are printed as integers).
std::string formatTrajectory(const std::vector<TrajectoryEntry>& entries,
                             const std::string& comment = "");

/// Parses `intrinsics.txt`: one line `fx fy cx cy width height [k1 k2]`, `#` comments allowed.
bool parseIntrinsics(const std::string& text, CameraIntrinsics& intrinsics, std::string& error);
std::string formatIntrinsics(const CameraIntrinsics& intrinsics, const std::string& comment = "");

/// Reads a whole text file (errors name the file).
bool readTextFile(const std::string& path, std::string& text, std::string& error);
bool readTrajectoryFile(const std::string& path, std::vector<TrajectoryEntry>& entries,
                        std::string& error);
bool readIntrinsicsFile(const std::string& path, CameraIntrinsics& intrinsics, std::string& error);

}  // namespace epitrack::hal
