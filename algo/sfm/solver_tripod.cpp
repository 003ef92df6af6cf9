// Solver: the tripod solve of a rotating camera.
#include "algo/sfm/solver.hpp"

#include <algorithm>
#include <vector>

#include <Eigen/LU>
#include <Eigen/SVD>

#include "algo/geometry/focal_self_calibration.hpp"
#include "algo/geometry/homography.hpp"
#include "algo/math/median.hpp"

namespace epitrack {

// ---------------------------------------------------------------------------------------------
// Tripod solve: a rotating camera (Hartley 1997): focal from the rotation homographies, each
// frame's rotation from its homography to a reference frame, every centre at the origin.

bool Solver::tripodSolve() {
  const int n = tracks_.frameCount();
  if (options_.focal_px > 0.0) {
    f_ = options_.focal_px;
  } else {
    std::vector<double> fs;
    for (const auto& H : homographies_) {
      const auto e = estimateFocalFromRotation(H, width_, height_);
      if (e.observable) fs.push_back(e.focal_px);
    }
    if (fs.empty()) return false;
    f_ = upperMedian(fs);
    focal_source_ = FocalSource::kSelfCalibrated;
    focal_observable_ = true;
  }
  Eigen::Matrix3d K;
  K << f_, 0, cx_, 0, f_ * aspect_, cy_, 0, 0, 1;
  const Eigen::Matrix3d Kinv = K.inverse();
  int max_obs = 0;
  for (int f = 0; f < n; ++f)
    max_obs = std::max(max_obs, static_cast<int>(tracks_.frame(f).size()));
  HomographyRansac hr(std::max(8, max_obs));
  std::vector<Eigen::Vector2d> x1, x2;
  // The reference (identity rotation) is the first frame with enough tracks for a homography;
  // frames before it have fewer and stay unsolved. (It was frame 0 whatever its tracks: a dead
  // store computed its solved flag and the loop then set it.)
  int ref = 0;
  while (ref < n && tracks_.frame(ref).size() < 8) ++ref;
  if (ref == n) return false;
  Eigen::Matrix3d R_ref = Eigen::Matrix3d::Identity();  // R_cw of the reference frame
  int solved = 0;
  for (int f = ref; f < n; ++f) {
    if (f == ref) {
      frames_[static_cast<std::size_t>(f)].solved = true;
      frames_[static_cast<std::size_t>(f)].pose.R_cw = R_ref;
      ++solved;
      continue;
    }
    if (commonTracks(ref, f, &x1, &x2) < 20) {
      // Re-anchor on the previous solved frame.
      if (f - 1 != ref && frames_[static_cast<std::size_t>(f - 1)].solved) {
        ref = f - 1;
        R_ref = frames_[static_cast<std::size_t>(ref)].pose.R_cw;
        commonTracks(ref, f, &x1, &x2);
      }
      if (x1.size() < 8) continue;
    }
    HomographyResult h;
    if (hr.estimate(x1, x2, {}, h) != HomographyRansac::Status::kOk) continue;
    // x_f ~ K R_f R_ref^T K^-1 x_ref.
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(Kinv * h.H * K,
                                          Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d R = svd.matrixU() * svd.matrixV().transpose();
    if (R.determinant() < 0) R = -R;
    auto& fr = frames_[static_cast<std::size_t>(f)];
    fr.solved = true;
    fr.pose.R_cw = R * R_ref;
    fr.pose.t_cw.setZero();
    fr.rms_px = h.rms_transfer_px;
    fr.inliers = h.inliers;
    ++solved;
  }
  tripod_ = true;
  motion_ = MotionClass::kRotationOnly;
  status_ = Status::kRotationOnly;
  message_ = "the camera only rotates (tripod): rotation and focal solved, depth unknown";
  assessCoverage();
  return solved > 0;
}

}  // namespace epitrack
