#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>

#include <Eigen/Geometry>

#include "algo/geometry/pose.hpp"
#include "algo/sfm/live_map.hpp"

namespace epitrack::device {

/// Formats everything of a pose line after the frame numbers (see formatPoseLine), from `"t"` to
/// the newline. Returns snprintf's length.
inline int formatPoseLineTail(char* buffer, std::size_t size, double t, LiveStatus status,
                              int features, const PoseCw& pose, double ms,
                              const LiveInitProgress& init) {
  if (status == LiveStatus::kInitializing) {
    return std::snprintf(
        buffer, size,
        "\"t\": %.6f, \"status\": \"%s\", \"features\": %d, \"init\": "
        "{\"reason\": \"%s\", \"tracks\": %d, \"common\": %d, \"displacement_px\": %.2f, "
        "\"points\": %d, \"parallax_deg\": %.3f, \"pairs\": %d}, \"ms\": %.3f}\n",
        t, toString(status), features, toString(init.stage), init.tracks_alive, init.common_tracks,
        std::isfinite(init.displacement_px) ? init.displacement_px : 0.0, init.points,
        std::isfinite(init.parallax_deg) ? init.parallax_deg : 0.0, init.pairs, ms);
  }
  if (status == LiveStatus::kTracking) {
    const Eigen::Matrix3d R_wc = pose.R_cw.transpose();
    Eigen::Quaterniond q(R_wc);
    q.normalize();
    if (q.w() < 0.0) q.coeffs() = -q.coeffs();
    const Eigen::Vector3d p = pose.centre();
    return std::snprintf(buffer, size,
                         "\"t\": %.6f, \"status\": \"%s\", \"features\": %d, "
                         "\"q\": [%.9f, %.9f, %.9f, %.9f], \"p\": [%.9g, %.9g, %.9g], "
                         "\"ms\": %.3f}\n",
                         t, toString(status), features, q.x(), q.y(), q.z(), q.w(), p.x(), p.y(),
                         p.z(), ms);
  }
  return std::snprintf(buffer, size,
                       "\"t\": %.6f, \"status\": \"%s\", \"features\": %d, \"ms\": %.3f}\n", t,
                       toString(status), features, ms);
}

/// Formats one pose line (ARCHITECTURE.md `epitrack-device`): `frame` (the source's frame
/// number: the driver's sequence number from a camera, the position in a replay), with `--record`
/// `record_frame` (the same frame's number in the recording: its `NNNNNN.pgm` name, its position
/// in an .mjpeg, the `frame` a replay of the recording gives it; `record_frame` < 0 leaves the
/// field out), `t`, `status`, `features`, and when tracking `q` [qx, qy, qz, qw] and `p`
/// [x, y, z] of T_wc (the inverse of the world-to-camera `pose`); while initializing `init`, why
/// the map does not exist yet (`reason`, LiveInitStage) and how far it got (`tracks` alive,
/// `common` with the reference, their median `displacement_px`, triangulated `points` and their
/// median `parallax_deg`, and `pairs` of the focal self-calibration); then `ms`. Writes into
/// `buffer` (no allocation) and returns the length, newline included (negative on an encoding
/// error, >= size when truncated, as snprintf).
inline int formatPoseLine(char* buffer, std::size_t size, int64_t frame, int64_t record_frame,
                          double t, LiveStatus status, int features, const PoseCw& pose, double ms,
                          const LiveInitProgress& init = {}) {
  // The frame numbers first, then the rest appended: one format per status, not two.
  const int head =
      record_frame >= 0
          ? std::snprintf(buffer, size, "{\"frame\": %lld, \"record_frame\": %lld, ",
                          static_cast<long long>(frame), static_cast<long long>(record_frame))
          : std::snprintf(buffer, size, "{\"frame\": %lld, ", static_cast<long long>(frame));
  if (head < 0 || static_cast<std::size_t>(head) >= size) return head;
  const int tail = formatPoseLineTail(buffer + head, size - static_cast<std::size_t>(head), t,
                                      status, features, pose, ms, init);
  return tail < 0 ? tail : head + tail;
}

}  // namespace epitrack::device
