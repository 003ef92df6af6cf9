// Solver: the tripod solve of a rotating camera.
#include "algo/sfm/solver.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/LU>
#include <Eigen/SVD>

#include "algo/geometry/focal_self_calibration.hpp"
#include "algo/geometry/fundamental.hpp"
#include "algo/geometry/homography.hpp"
#include "algo/geometry/two_view_model_selection.hpp"
#include "algo/math/median.hpp"
#include "algo/sfm/rotation_adjustment.hpp"

namespace epitrack {

struct Solver::TripodProblem {
  int rows = 0;                            // image height (the rolling shutter's rows)
  std::vector<Eigen::Matrix3d> rotations;  // R_cw of each solved frame
  std::vector<uint8_t> fixed;              // the gauge
  std::vector<BaTrajectoryNeighbours> neighbours;
  std::vector<Eigen::Vector3d> directions;
  std::vector<RotationObservation> observations;
};

namespace {

// y = a (x - vertex)^2 + minimum through three points; valid when convex and finite.
struct ParabolaFit {
  bool valid = false;
  double a = 0.0, vertex = 0.0, minimum = 0.0;
};

ParabolaFit fitParabola(const std::array<double, 3>& x, const std::array<double, 3>& y) {
  ParabolaFit fit;
  const double d01 = (y[1] - y[0]) / (x[1] - x[0]);
  const double d12 = (y[2] - y[1]) / (x[2] - x[1]);
  fit.a = (d12 - d01) / (x[2] - x[0]);
  // p(x) = y0 + d01 (x - x0) + a (x - x0)(x - x1), p'(vertex) = 0.
  fit.vertex = 0.5 * (x[0] + x[1]) - d01 / (2.0 * fit.a);
  fit.minimum =
      y[0] + d01 * (fit.vertex - x[0]) + fit.a * (fit.vertex - x[0]) * (fit.vertex - x[1]);
  fit.valid =
      fit.a > 0.0 && std::isfinite(fit.vertex) && std::isfinite(fit.minimum) && fit.minimum > 0.0;
  return fit;
}

}  // namespace

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
  if (options_.tripod_adjustment) refineTripod();
  tripod_ = true;
  motion_ = MotionClass::kRotationOnly;
  status_ = Status::kRotationOnly;
  message_ = "the camera only rotates (tripod): rotation and focal solved, depth unknown";
  assessCoverage();
  return solved > 0;
}

// Each track with two or more solved views as a scene direction (initialised from its first
// view) and its observations in the solved views.
void Solver::directionsAndObservations(const TrackTable& tracks,
                                       const std::vector<int>& camera_of_frame,
                                       const std::vector<Eigen::Matrix3d>& rotations,
                                       std::vector<Eigen::Vector3d>& directions,
                                       std::vector<RotationObservation>& observations) const {
  Eigen::Matrix3d K;
  K << f_, 0, cx_, 0, f_ * aspect_, cy_, 0, 0, 1;
  const Eigen::Matrix3d Kinv = K.inverse();
  const auto cameraOf = [&](const TrackObservation& o) {
    return camera_of_frame[static_cast<std::size_t>(o.frame)];
  };
  for (int t = 0; t < tracks.trackCount(); ++t) {
    int views = 0;
    for (const int i : tracks.track(t))
      views += cameraOf(tracks.observations()[static_cast<std::size_t>(i)]) >= 0 ? 1 : 0;
    if (views < 2) continue;
    const int id = static_cast<int>(directions.size());
    for (const int i : tracks.track(t)) {
      const TrackObservation& o = tracks.observations()[static_cast<std::size_t>(i)];
      const int c = cameraOf(o);
      if (c < 0) continue;
      if (static_cast<int>(directions.size()) == id)
        directions.push_back((rotations[static_cast<std::size_t>(c)].transpose() *
                              (Kinv * undistortedPixel(o).homogeneous()))
                                 .normalized());
      observations.push_back({c, id, Eigen::Vector2d(o.x, o.y)});
    }
  }
}

// The rotation-only bundle adjustment of every solved frame (Hartley 1997, §4): each track with
// two or more solved views is a scene direction, initialised from its first view; the first
// solved frame holds the gauge; the focal is refined when it was self-calibrated. Chained
// homographies carry each pair's error into every later frame (0.33 deg at the end of a 90-frame
// fast pan) and re-anchor on overlaps as small as 20 tracks at one image edge.
void Solver::refineTripod() {
  const int n = tracks_.frameCount();
  std::vector<int> camera_of_frame(static_cast<std::size_t>(n), -1);
  std::vector<int> frame_of_camera;
  for (int f = 0; f < n; ++f)
    if (frames_[static_cast<std::size_t>(f)].solved) {
      camera_of_frame[static_cast<std::size_t>(f)] = static_cast<int>(frame_of_camera.size());
      frame_of_camera.push_back(f);
    }
  const int cameras = static_cast<int>(frame_of_camera.size());
  if (cameras < 2) return;
  TripodProblem p;
  p.rows = height_;
  for (int c = 0; c < cameras; ++c) {
    const int f = frame_of_camera[static_cast<std::size_t>(c)];
    p.rotations.push_back(frames_[static_cast<std::size_t>(f)].pose.R_cw);
    // The first camera holds the gauge (the rotation of the whole rig is free). Built by
    // push_back: armhf's g++ 12 cannot see that `cameras >= 2` and warns of a null fixed[0].
    p.fixed.push_back(c == 0 ? 1 : 0);
    BaTrajectoryNeighbours nb;
    nb.previous = f > 0 ? camera_of_frame[static_cast<std::size_t>(f - 1)] : -1;
    nb.next = f + 1 < n ? camera_of_frame[static_cast<std::size_t>(f + 1)] : -1;
    p.neighbours.push_back(nb);
  }
  // With a rolling shutter the adjustment models each row's time on the tracks as exposed.
  const bool rolling = options_.readout_frames > 0.0 && exposed_tracks_ != nullptr &&
                       exposed_tracks_->trackCount() == tracks_.trackCount();
  directionsAndObservations(rolling ? *exposed_tracks_ : tracks_, camera_of_frame, p.rotations,
                            p.directions, p.observations);
  RotationAdjuster adjuster(cameras, static_cast<int>(p.directions.size()),
                            static_cast<int>(p.observations.size()));
  BaIntrinsics k{f_, aspect_, cx_, cy_, k1_, k2_};
  RotationAdjustmentOptions ro;
  ro.huber_px = options_.huber_px;
  ro.refine_focal = focal_source_ == FocalSource::kSelfCalibrated;
  const double readout = rolling ? options_.readout_frames : 0.0;
  const RotationAdjustmentSummary r = adjustTripod(adjuster, p, readout, ro, k);
  if (r.failed || !(r.final_rms_px <= r.initial_rms_px) || !(k.f > 0.0)) return;
  keepTripodAdjustment(p, frame_of_camera, k, r, rolling);
  tripod_rms_before_px_ = r.initial_rms_px;
  if (options_.estimate_readout) estimateTripodReadout(adjuster, p, frame_of_camera, ro, readout);
}

void Solver::keepTripodAdjustment(const TripodProblem& p, const std::vector<int>& frame_of_camera,
                                  const BaIntrinsics& k, const RotationAdjustmentSummary& r,
                                  bool rows_modelled) {
  f_ = k.f;
  for (std::size_t c = 0; c < frame_of_camera.size(); ++c)
    frames_[static_cast<std::size_t>(frame_of_camera[c])].pose.R_cw = p.rotations[c];
  tripod_rms_after_px_ = r.final_rms_px;
  tripod_iterations_ = r.iterations;
  tripod_rows_modelled_ = rows_modelled;
}

// --readout auto on a rotating camera. The adjustment's plain error as a function of the readout
// is close to a parabola (the rows' displacement is linear in the line delay for the motions of a
// frame interval): a parabola through trials at 0 (the global-shutter adjustment just made),
// 0.5 and 1 frame interval, then three trials about its vertex; the last parabola's vertex is the
// estimate and its curvature the standard error (mean square s(r) = S(r) / M over M independent
// residuals: var = 2 sigma^2 / S'' = 2 s_min / (M s'') with sigma^2 = s_min). Only the change of
// the rows' shear from frame to frame observes the readout (a steady pan's shear is absorbed by the
// directions), so a steady pan gives a flat parabola and a large error, a pan that reverses a sharp
// one.
void Solver::estimateTripodReadout(RotationAdjuster& adjuster, const TripodProblem& start,
                                   const std::vector<int>& frame_of_camera,
                                   const RotationAdjustmentOptions& ro, double initial_readout) {
  const double rms0 = tripod_rms_after_px_;
  // Each trial starts from the global-shutter adjustment (`start`, its focal in f_).
  const auto trial = [&](double readout, TripodProblem& p, BaIntrinsics& k) {
    p = start;
    k = BaIntrinsics{f_, aspect_, cx_, cy_, k1_, k2_};
    return adjustTripod(adjuster, p, readout, ro, k);
  };
  const auto sumOfSquares = [&](double readout) {
    TripodProblem p;
    BaIntrinsics k;
    const RotationAdjustmentSummary r = trial(readout, p, k);
    return r.failed ? std::numeric_limits<double>::quiet_NaN() : r.final_rms_px * r.final_rms_px;
  };
  // The adjustment just made is one of the trials (at 0, or at the readout the tracks were moved
  // to by --readout auto's search for a fast pan, see solve_pipeline.cpp).
  const auto at = [&](double readout) {
    return readout == initial_readout ? rms0 * rms0 : sumOfSquares(readout);
  };
  ParabolaFit fit = fitParabola({0.0, 0.5, 1.0}, {at(0.0), at(0.5), at(1.0)});
  if (!fit.valid) return;
  const double h = 0.1;
  const double centre = std::clamp(fit.vertex, h, 1.0 - h);
  fit = fitParabola({centre - h, centre, centre + h},
                    {sumOfSquares(centre - h), sumOfSquares(centre), sumOfSquares(centre + h)});
  if (!fit.valid) return;
  // A track's errors are correlated along it (the tracker's template drifts), so the independent
  // measurements are the tracks, not the observations: counted per observation, the standard
  // error came out 4-10x below the scatter of the estimates on tracked pans with a global shutter
  // (0.3-1.6 ms against 0.08-0.15 ms, 2026-12-05).
  const double m = 2.0 * static_cast<double>(start.directions.size());
  tripod_readout_frames_ = std::clamp(fit.vertex, 0.0, 1.0);
  tripod_readout_std_error_ = std::sqrt(fit.minimum / (m * fit.a));
  if (!(tripod_readout_frames_ > 3.0 * tripod_readout_std_error_ &&
        tripod_readout_frames_ > options_.readout_min_frames))
    return;
  TripodProblem p;
  BaIntrinsics k;
  const RotationAdjustmentSummary r = trial(tripod_readout_frames_, p, k);
  if (r.failed || !(r.final_rms_px <= rms0 * 1.001) || !(k.f > 0.0)) return;
  keepTripodAdjustment(p, frame_of_camera, k, r, true);
  tripod_readout_applied_ = true;
}

RotationAdjustmentSummary Solver::adjustTripod(RotationAdjuster& adjuster, TripodProblem& p,
                                               double readout_frames, RotationAdjustmentOptions ro,
                                               BaIntrinsics& k) const {
  ro.shutter = readout_frames > 0.0
                   ? RollingShutter::fromReadout(readout_frames, p.rows, 0.5 * (p.rows - 1))
                   : RollingShutter{};
  return adjuster.solve(p.rotations, p.fixed, p.directions, p.observations, p.neighbours, k, ro);
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
