#include "algo/sfm/two_view_initialization.hpp"

#include "algo/geometry/essential.hpp"
#include "algo/geometry/triangulation.hpp"

namespace epitrack {

const char* toString(TwoViewStatus s) {
  switch (s) {
    case TwoViewStatus::kOk:
      return "ok";
    case TwoViewStatus::kNoPose:
      return "no-pose";
    case TwoViewStatus::kAmbiguous:
      return "ambiguous";
  }
  return "unknown";
}

TwoViewStatus reconstructTwoView(const Eigen::Matrix3d& F, const Eigen::Matrix3d& K,
                                 std::span<const Eigen::Vector2d> n1,
                                 std::span<const Eigen::Vector2d> n2, std::span<const uint8_t> mask,
                                 const TwoViewOptions& options, PoseCw& pose,
                                 std::span<Eigen::Vector3d> X, std::span<int> accepted,
                                 std::span<double> parallax, int& count) {
  count = 0;
  // Distortion is already out of n1, n2; E from F in pixels ignores it (refined below on them).
  const Eigen::Matrix3d E = essentialFromFundamental(F, K, K);
  RelativePoseResult rp;
  if (!recoverRelativePose(E, n1, n2, mask, rp)) return TwoViewStatus::kNoPose;
  if (rp.second_best * 10 > rp.in_front * 7) return TwoViewStatus::kAmbiguous;
  pose = rp.pose;
  refineRelativePose(n1, n2, mask, options.focal_px, pose);
  TriangulationOptions to;
  to.focal_px = options.focal_px;
  to.min_parallax_deg = options.min_point_parallax_deg;
  to.max_reproj_px = options.reproj_threshold_px;
  const PoseCw poses[2] = {PoseCw{}, pose};
  for (std::size_t i = 0; i < n1.size(); ++i) {
    if (!mask[i]) continue;
    const Eigen::Vector2d obs[2] = {n1[i], n2[i]};
    const auto t = triangulatePoint(poses, obs, to);
    if (t.status != TriangulationStatus::kOk) continue;
    X[i] = t.X;
    accepted[static_cast<std::size_t>(count)] = static_cast<int>(i);
    parallax[static_cast<std::size_t>(count)] = t.parallax_deg;
    ++count;
  }
  return TwoViewStatus::kOk;
}

}  // namespace epitrack
