#include "tools/export/reprojection_errors.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <vector>

#include "algo/geometry/rolling_shutter.hpp"

namespace epitrack::io {

bool projectPoint(const CameraIntrinsics& k, const SolvedCamera& camera, const Eigen::Vector3d& X,
                  Eigen::Vector2d& pixel) {
  const Eigen::Vector3d xc = camera.R_wc.transpose() * (X - camera.p_wc);
  if (!(xc.z() > 0.0)) return false;
  const double u = xc.x() / xc.z();
  const double v = xc.y() / xc.z();
  const double r2 = u * u + v * v;
  const double d = 1.0 + k.k1 * r2 + k.k2 * r2 * r2;
  pixel = Eigen::Vector2d(k.fx * u * d + k.cx, k.fy * v * d + k.cy);
  return pixel.allFinite();
}

bool projectPoint(const Reconstruction& rec, const SolvedCamera& camera, const Eigen::Vector3d& X,
                  Eigen::Vector2d& pixel) {
  if (!(rec.readout_frames > 0.0)) return projectPoint(rec.intrinsics, camera, X, pixel);
  // Rolling shutter: the point is seen on the row whose pose sees it there (issue 27); the
  // camera's pose is the reference row's, its motion over the readout rs_angular / rs_linear.
  const RollingShutter shutter = RollingShutter::fromReadout(
      rec.readout_frames, rec.intrinsics.height, rec.readout_reference_row);
  PoseCw pose;
  pose.R_cw = camera.R_wc.transpose();
  pose.t_cw = -pose.R_cw * camera.p_wc;
  RollingShutterMotion motion;
  motion.angular = camera.rs_angular;
  motion.linear = camera.rs_linear;
  const RollingShutterPixel seen = projectRollingShutter(rec.intrinsics, shutter, pose, motion, X);
  pixel = seen.px;
  return seen.status == RollingShutterProjection::kOk && pixel.allFinite();
}

void computeReprojectionErrors(Reconstruction& rec, double outlier_px) {
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  std::unordered_map<int64_t, std::size_t> camera_of_frame;
  for (std::size_t i = 0; i < rec.cameras.size(); ++i) {
    if (rec.cameras[i].solved) camera_of_frame[rec.cameras[i].frame] = i;
  }
  std::unordered_map<int64_t, std::size_t> point_of_id;
  for (std::size_t i = 0; i < rec.points.size(); ++i) point_of_id[rec.points[i].id] = i;

  std::vector<double> camera_sum(rec.cameras.size(), 0.0);
  std::vector<int> camera_count(rec.cameras.size(), 0);
  std::vector<double> point_sum(rec.points.size(), 0.0);
  std::vector<int> point_count(rec.points.size(), 0);
  std::vector<double> all;
  all.reserve(rec.observations.size());
  for (PointObservation& o : rec.observations) {
    o.residual_px = kNaN;
    o.residual_dx = kNaN;
    o.residual_dy = kNaN;
    o.outlier = false;
    const auto cam = camera_of_frame.find(o.frame);
    const auto pt = point_of_id.find(o.point_id);
    if (cam == camera_of_frame.end() || pt == point_of_id.end()) continue;
    Eigen::Vector2d pixel;
    if (!projectPoint(rec, rec.cameras[cam->second], rec.points[pt->second].X, pixel)) {
      o.outlier = true;  // behind the camera (or no row sees it): no residual, no place in a track
      continue;
    }
    o.residual_dx = o.x - pixel.x();
    o.residual_dy = o.y - pixel.y();
    o.residual_px = std::sqrt(o.residual_dx * o.residual_dx + o.residual_dy * o.residual_dy);
    if (!std::isfinite(o.residual_px) || (outlier_px > 0.0 && o.residual_px > outlier_px)) {
      o.outlier = true;
      continue;
    }
    camera_sum[cam->second] += o.residual_px;
    camera_count[cam->second] += 1;
    point_sum[pt->second] += o.residual_px;
    point_count[pt->second] += 1;
    all.push_back(o.residual_px);
  }
  for (std::size_t i = 0; i < rec.cameras.size(); ++i) {
    if (!rec.cameras[i].solved) continue;
    rec.cameras[i].inliers = camera_count[i];
    rec.cameras[i].mean_reproj_px = camera_count[i] > 0 ? camera_sum[i] / camera_count[i] : kNaN;
  }
  for (std::size_t i = 0; i < rec.points.size(); ++i) {
    rec.points[i].observations = point_count[i];
    rec.points[i].reproj_px = point_count[i] > 0 ? point_sum[i] / point_count[i] : kNaN;
  }
  if (all.empty()) {
    rec.mean_reproj_px = kNaN;
    rec.median_reproj_px = kNaN;
    return;
  }
  double sum = 0.0;
  for (const double r : all) sum += r;
  rec.mean_reproj_px = sum / static_cast<double>(all.size());
  const std::size_t mid = all.size() / 2;
  std::nth_element(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(mid), all.end());
  double median = all[mid];
  if (all.size() % 2 == 0) {
    median = 0.5 * (median +
                    *std::max_element(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(mid)));
  }
  rec.median_reproj_px = median;
}

RowMisfit rowMisfitOf(const Reconstruction& rec, const RowMisfitOptions& options) {
  std::vector<RowResidual> residuals;
  residuals.reserve(rec.observations.size());
  for (const PointObservation& o : rec.observations) {
    if (o.outlier || !std::isfinite(o.residual_dx) || !std::isfinite(o.residual_dy)) continue;
    residuals.push_back({o.frame, o.x, o.y, o.residual_dx, o.residual_dy});
  }
  std::stable_sort(residuals.begin(), residuals.end(),
                   [](const RowResidual& a, const RowResidual& b) { return a.frame < b.frame; });
  return measureRowMisfit(residuals, rec.intrinsics.cx, rec.intrinsics.cy,
                          static_cast<double>(rec.intrinsics.height), options);
}

}  // namespace epitrack::io
