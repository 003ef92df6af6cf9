#include "algo/geometry/determined_relative_pose.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

namespace epitrack {

bool relativePoseOverSeeds(std::span<const Eigen::Vector2d> n1, std::span<const Eigen::Vector2d> n2,
                           const EssentialRansacOptions& options, int trials,
                           RelativePoseHypothesis& best) {
  EssentialRansac ransac(static_cast<int>(n1.size()));
  std::vector<RelativePoseHypothesis> found;
  for (int t = 0; t < std::max(1, trials); ++t) {
    EssentialRansacOptions o = options;
    o.ransac.seed = options.ransac.seed + 1000003u * static_cast<uint64_t>(t);
    EssentialRansacResult e;
    if (ransac.estimate(n1, n2, o, e) != EssentialRansac::Status::kOk) continue;
    RelativePoseHypothesis h;
    h.inliers = e.inliers;
    h.mask.assign(e.mask.begin(), e.mask.end());
    if (!recoverRelativePose(e.E, n1, n2, h.mask, h.relative)) continue;
    found.push_back(std::move(h));
  }
  if (found.empty()) return false;
  const auto most = std::max_element(found.begin(), found.end(), [](const auto& a, const auto& b) {
    return a.inliers < b.inliers;
  });
  double spread = 0.0;
  for (const auto& h : found) {
    if (h.inliers * 10 < most->inliers * 9) continue;
    const Eigen::AngleAxisd between(h.relative.pose.R_cw * most->relative.pose.R_cw.transpose());
    spread = std::max(spread, between.angle() * 180.0 / M_PI);
  }
  best = std::move(*most);
  best.rotation_spread_deg = spread;
  return true;
}

}  // namespace epitrack
