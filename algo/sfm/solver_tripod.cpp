// Solver: the tripod solve of a rotating camera.
#include "algo/sfm/solver.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/LU>
#include <Eigen/SVD>

#include "algo/geometry/focal_self_calibration.hpp"
#include "algo/geometry/fundamental.hpp"
#include "algo/geometry/homography.hpp"
#include "algo/geometry/two_view_model_selection.hpp"
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

// The tripod test. A homography between two views of a rotating camera fits their tracks to the
// noise; a moving camera leaves parallax that grows with the baseline. The calibration pairs are
// a few frames apart under a fast pan (the tracks cross 8 % of the width in two frames), too
// short for the parallax of a walking camera to show at the fixed 0.5 px of their GRIC. So each
// window here spans as many frames as 30 tracks persist, and compares the homography's residual
// scale with the noise scale of the same tracks, measured on the general model (F's Sampson
// distances): on tracker tracks of a true rotation the ratio is 1.1-1.4 (F's free epipole hides
// the noise along the motion), on a pan with a walking centre 2.5-3 and more.
RotationCheck Solver::checkRotationModel() const {
  RotationCheck check;
  const int n = tracks_.frameCount();
  int max_obs = 0;
  for (int f = 0; f < n; ++f)
    max_obs = std::max(max_obs, static_cast<int>(tracks_.frame(f).size()));
  if (max_obs < kRotationWindowTracks) return check;
  FundamentalRansac fr(max_obs);
  HomographyRansac hr(max_obs);
  FundamentalOptions fo;
  fo.ransac.seed = options_.seed;
  HomographyOptions ho;
  ho.ransac.seed = options_.seed;
  std::vector<Eigen::Vector2d> x1, x2;
  std::vector<double> noise, residual, ratio, e;
  const int step = std::max(1, n / 40);
  for (int a = 0; a + 1 < n; a += step) {
    const int b = farthestPartner(a, kRotationWindowTracks);
    if (b < 0) continue;
    commonTracks(a, b, &x1, &x2);
    FundamentalResult f;
    HomographyResult h;
    if (fr.estimate(x1, x2, fo, f) != FundamentalRansac::Status::kOk) continue;
    if (hr.estimate(x1, x2, ho, h) != HomographyRansac::Status::kOk) continue;
    // Noise per coordinate: F's Sampson distance of an inlier is one Gaussian coordinate (its
    // square's median is 0.4549 sigma^2, chi-square with 1 dof).
    e.clear();
    for (std::size_t i = 0; i < x1.size(); ++i)
      if (f.mask[i]) e.push_back(sampsonSquared(f.F, x1[i], x2[i]));
    const double sigma = std::sqrt(upperMedian(e) / 0.4549);
    // The homography's transfer error over every common track (parallax is not an outlier)
    // holds the noise of both views: its square's median is 2 sigma^2 x 1.3863 (chi-square, 2 dof).
    e.clear();
    for (std::size_t i = 0; i < x1.size(); ++i)
      e.push_back(homographyTransferSquared(h.H, x1[i], x2[i]));
    const double h_scale = std::sqrt(upperMedian(e) / (2.0 * 1.3863));
    if (!(sigma > 0.0) || !std::isfinite(h_scale)) continue;
    ++check.windows;
    check.parallax_windows += h_scale > kRotationResidualRatio * sigma ? 1 : 0;
    noise.push_back(sigma);
    residual.push_back(h_scale);
    ratio.push_back(h_scale / sigma);
  }
  if (check.windows == 0) return check;
  check.noise_px = upperMedian(noise);
  check.residual_px = upperMedian(residual);
  check.ratio = upperMedian(ratio);
  // A walking camera shows its parallax in the windows where tracks live long (the reversals of
  // a pan), not in all: the median can stay below the bound while a fifth of the windows do not.
  check.holds = check.parallax_windows * 5 <= check.windows;
  return check;
}

int Solver::farthestPartner(int a, int min_common) const {
  int b = -1;
  for (int k = a + 1; k < tracks_.frameCount(); ++k) {
    if (commonTracks(a, k, nullptr, nullptr) < min_common) break;
    b = k;
  }
  return b;
}

}  // namespace epitrack
