// camera.chan: Nuke channel file for a Camera node (Camera > File > Import chan file).

#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>

#include "tools/export/export_geometry.hpp"
#include "tools/export/output_writers.hpp"

namespace epitrack::io {

std::string formatNukeChan(const Reconstruction& rec, const ExportOptions& options) {
  constexpr double kDegrees = 180.0 / std::numbers::pi;
  const CameraIntrinsics& k = rec.intrinsics;
  // Vertical field of view over the full image height (pixel edges), in degrees.
  const double vfov_deg =
      (k.fy > 0.0 && k.height > 0) ? 2.0 * std::atan(0.5 * k.height / k.fy) * kDegrees : 0.0;
  const Eigen::Matrix3d W = ourWorldToNukeWorld();
  std::string out;
  char buf[256];
  Eigen::Vector3d previous = Eigen::Vector3d::Zero();
  bool have_previous = false;
  for (const SolvedCamera& c : rec.cameras) {
    if (!c.solved || !c.R_wc.allFinite() || !c.p_wc.allFinite()) continue;
    const Eigen::Vector3d t = W * c.p_wc;
    Eigen::Vector3d r = nukeZxyFromRotation(W * glCameraRotation(c.R_wc)) * kDegrees;
    // Unwrap each angle to within 180 degrees of the previous frame's, so that Nuke's
    // interpolation between frames (motion blur, retiming) never spins the camera around.
    if (have_previous) {
      for (int a = 0; a < 3; ++a) r[a] -= 360.0 * std::round((r[a] - previous[a]) / 360.0);
    }
    previous = r;
    have_previous = true;
    std::snprintf(buf, sizeof(buf), "%lld %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n",
                  static_cast<long long>(c.frame) + options.nuke_frame_offset, t.x(), t.y(), t.z(),
                  r.x(), r.y(), r.z(), vfov_deg);
    out += buf;
  }
  return out;
}

}  // namespace epitrack::io
