#include "algo/sfm/rolling_shutter_refinement.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

#include "algo/geometry/pose.hpp"
#include "algo/geometry/triangulation.hpp"
#include "algo/geometry/undistort.hpp"
#include "algo/sfm/ba_camera_pose.hpp"
#include "algo/sfm/bundle_adjustment.hpp"

namespace epitrack {

namespace {

// When the joint adjustment stops: an iteration that lowers the cost by less than half the
// residuals' variance, sigma^2 / 2 = cost / N of N residuals (2 per observation). The cost's
// excess over the minimum is 1/2 d^T H d for a deviation d of the parameters, i.e. sigma^2 / 2 per
// squared standard deviation of d along its direction. The tail converges linearly (the Huber
// loss's reweighting: the decrease falls 0.4-0.9x per iteration, chord steps or full ones), so what
// remains, rho / (1 - rho) times the last decrease, is within one standard deviation along the
// least determined direction at rho <= 0.5, three at 0.9. At 1e-6 of the cost (the global solve's
// stop) the adjustment took twelve iterations on the fast orbit (docs/rolling-shutter.md); this
// stop is about 1/N relative, 1.5e-5 there; 1e-4 was up to four standard deviations short.
double relativeDecreaseToStop(std::size_t observations) {
  return 1.0 / (2.0 * static_cast<double>(std::max<std::size_t>(observations, 1)));
}

struct Workspace {
  std::vector<int> point_of_track;
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> px;
  std::vector<PoseCw> poses;
  std::vector<Eigen::Vector2d> normalized;
};

// Reprojection RMS of every valid point's observations in solved frames, with the rows' poses.
double reprojectionRms(const TrackTable& tracks, const CameraIntrinsics& K,
                       const RollingShutter& shutter, const std::vector<SolvedFrame>& frames,
                       const std::vector<MapPoint>& points,
                       const std::vector<RollingShutterMotion>& motions, const Workspace& w,
                       double threshold_px) {
  double sum = 0.0;
  long n = 0;
  for (const auto& o : tracks.observations()) {
    const int p = w.point_of_track[static_cast<std::size_t>(o.track)];
    const auto& fr = frames[static_cast<std::size_t>(o.frame)];
    if (p < 0 || !fr.solved) continue;
    const auto px =
        projectRollingShutter(K, shutter, fr.pose, motions[static_cast<std::size_t>(o.frame)],
                              points[static_cast<std::size_t>(p)].X);
    if (px.status != RollingShutterProjection::kOk) continue;
    const double e2 = (px.px - Eigen::Vector2d(o.x, o.y)).squaredNorm();
    if (e2 > threshold_px * threshold_px) continue;
    sum += e2;
    ++n;
  }
  return n > 0 ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
}

// Each solved frame's pose and readout motion on its points (the points fixed).
int resectFrames(const TrackTable& tracks, const CameraIntrinsics& K, const RollingShutter& shutter,
                 std::vector<SolvedFrame>& frames, const std::vector<MapPoint>& points,
                 std::vector<RollingShutterMotion>& motions,
                 const RollingShutterRefinementOptions& options, Workspace& w) {
  int refined = 0;
  for (int f = 0; f < static_cast<int>(frames.size()); ++f) {
    auto& fr = frames[static_cast<std::size_t>(f)];
    if (!fr.solved) continue;
    auto& motion = motions[static_cast<std::size_t>(f)];
    w.X.clear();
    w.px.clear();
    for (const auto& o : tracks.frame(f)) {
      const int p = w.point_of_track[static_cast<std::size_t>(o.track)];
      if (p < 0) continue;
      const Eigen::Vector3d& X = points[static_cast<std::size_t>(p)].X;
      const auto px = projectRollingShutter(K, shutter, fr.pose, motion, X);
      if (px.status != RollingShutterProjection::kOk) continue;
      if ((px.px - Eigen::Vector2d(o.x, o.y)).norm() > options.reproj_threshold_px) continue;
      w.X.push_back(X);
      w.px.emplace_back(o.x, o.y);
    }
    if (w.X.size() < 12) continue;  // too few to observe 12 parameters well: keep the pose
    PoseCw pose = fr.pose;
    RollingShutterMotion m = motion;
    const auto r = refineRollingShutterPose(K, shutter, w.X, w.px, pose, m, options.resection);
    if (!pose.R_cw.allFinite() || !pose.t_cw.allFinite() || r.rms_px <= 0.0) continue;
    fr.pose = pose;
    motion = m;
    ++refined;
  }
  return refined;
}

// Every valid point from the poses of the rows it was seen on (observations of solved frames
// within the threshold of its current reprojection).
int intersectPoints(const TrackTable& tracks, const CameraIntrinsics& K,
                    const RollingShutter& shutter, const std::vector<SolvedFrame>& frames,
                    std::vector<MapPoint>& points, const std::vector<RollingShutterMotion>& motions,
                    const RollingShutterRefinementOptions& options, Workspace& w) {
  TriangulationOptions to;
  to.focal_px = K.fx;
  to.max_reproj_px = options.reproj_threshold_px;
  to.min_parallax_deg = 0.0;  // the global-shutter solve already chose the points
  int done = 0;
  for (auto& mp : points) {
    if (!mp.valid) continue;
    w.poses.clear();
    w.normalized.clear();
    for (const int i : tracks.track(mp.track)) {
      const auto& o = tracks.observations()[static_cast<std::size_t>(i)];
      const auto& fr = frames[static_cast<std::size_t>(o.frame)];
      if (!fr.solved) continue;
      const auto& motion = motions[static_cast<std::size_t>(o.frame)];
      const auto px = projectRollingShutter(K, shutter, fr.pose, motion, mp.X);
      if (px.status != RollingShutterProjection::kOk ||
          (px.px - Eigen::Vector2d(o.x, o.y)).norm() > options.reproj_threshold_px)
        continue;
      // Seen on row o.y: the camera as it was when that row was exposed.
      w.poses.push_back(poseAtTime(fr.pose, motion, shutter.rowTime(o.y)));
      w.normalized.push_back(undistortPixel(K, o.x, o.y));
    }
    if (w.poses.size() < 2) continue;
    const auto t = triangulatePoint(w.poses, w.normalized, to);
    if (t.status != TriangulationStatus::kOk) continue;
    mp.X = t.X;
    ++done;
  }
  return done;
}

Eigen::Vector3d logRotation(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

// The motion of the trajectory at each frame with both neighbours solved (central differences:
// R_cw(f + d) = Exp(-w d) R_cw(f), c(f + d) = c(f) + v d, per frame interval); other frames keep
// the motion they have.
void trajectoryMotions(const std::vector<SolvedFrame>& frames,
                       std::vector<RollingShutterMotion>& motions) {
  for (std::size_t f = 1; f + 1 < frames.size(); ++f) {
    const auto& prev = frames[f - 1];
    const auto& cur = frames[f];
    const auto& next = frames[f + 1];
    if (!prev.solved || !cur.solved || !next.solved) continue;
    motions[f].angular = 0.5 * (logRotation(prev.pose.R_cw * cur.pose.R_cw.transpose()) -
                                logRotation(next.pose.R_cw * cur.pose.R_cw.transpose()));
    motions[f].linear = 0.5 * (next.pose.centre() - prev.pose.centre());
  }
}

// The joint adjustment of every solved frame's pose and motion, the points and (optionally) the
// focal, on the observations within the threshold of their rolling-shutter reprojection.
void adjustJointly(const TrackTable& tracks, CameraIntrinsics& K, const RollingShutter& shutter,
                   std::vector<SolvedFrame>& frames, std::vector<MapPoint>& points,
                   std::vector<RollingShutterMotion>& motions,
                   const RollingShutterRefinementOptions& options, const Workspace& w,
                   std::span<const RollingShutterMotion> targets, double prior,
                   RollingShutterRefinementResult& result, double* initial_rms_px = nullptr) {
  std::vector<int> camera_of_frame(frames.size(), -1);
  std::vector<BaCamera> cameras;
  std::vector<uint8_t> fixed;
  std::vector<RollingShutterMotion> ba_motions;
  std::vector<RollingShutterMotion> ba_targets;
  for (std::size_t f = 0; f < frames.size(); ++f) {
    if (!frames[f].solved) continue;
    if (!targets.empty()) ba_targets.push_back(targets[f]);
    camera_of_frame[f] = static_cast<int>(cameras.size());
    cameras.push_back(toBa(frames[f].pose));
    fixed.push_back(cameras.size() == 1 ? 1 : 0);  // the gauge: the first solved frame
    ba_motions.push_back(motions[f]);
  }
  std::vector<int> ba_point(points.size(), -1);
  std::vector<Eigen::Vector3d> X;
  std::vector<BaObservation> observations;
  double sum2 = 0.0;  // of the kept observations' reprojection errors (reprojectionRms's)
  for (const auto& o : tracks.observations()) {
    const int p = w.point_of_track[static_cast<std::size_t>(o.track)];
    const int c = camera_of_frame[static_cast<std::size_t>(o.frame)];
    if (p < 0 || c < 0) continue;
    const auto px = projectRollingShutter(
        K, shutter, frames[static_cast<std::size_t>(o.frame)].pose,
        motions[static_cast<std::size_t>(o.frame)], points[static_cast<std::size_t>(p)].X);
    const double e2 = (px.px - Eigen::Vector2d(o.x, o.y)).squaredNorm();
    if (px.status != RollingShutterProjection::kOk ||
        e2 > options.reproj_threshold_px * options.reproj_threshold_px)
      continue;
    sum2 += e2;
    int& b = ba_point[static_cast<std::size_t>(p)];
    if (b < 0) {
      b = static_cast<int>(X.size());
      X.push_back(points[static_cast<std::size_t>(p)].X);
    }
    observations.push_back({c, b, Eigen::Vector2d(o.x, o.y)});
  }
  if (initial_rms_px != nullptr)
    *initial_rms_px =
        observations.empty() ? 0.0 : std::sqrt(sum2 / static_cast<double>(observations.size()));
  if (cameras.size() < 2 || observations.size() < 20) return;
  BundleAdjuster ba(
      static_cast<int>(cameras.size()), static_cast<int>(X.size()),
      static_cast<int>(observations.size()),
      options.smooth_trajectory ? BaCapacity::kSmoothTrajectory : BaCapacity::kRollingShutter);
  std::vector<BaTrajectoryNeighbours> neighbours(cameras.size());
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const int c = camera_of_frame[f];
    if (c < 0) continue;
    if (f > 0) neighbours[static_cast<std::size_t>(c)].previous = camera_of_frame[f - 1];
    if (f + 1 < frames.size())
      neighbours[static_cast<std::size_t>(c)].next = camera_of_frame[f + 1];
  }
  BundleAdjustmentOptions bo;
  bo.max_iterations = options.ba_iterations;
  bo.huber_px = options.huber_px;
  bo.refine_focal = options.refine_focal;
  bo.function_tolerance = relativeDecreaseToStop(observations.size());
  bo.reuse_factorization = true;
  bo.velocity_prior = prior;
  bo.motion_prior_mean = ba_targets;
  BaIntrinsics k{K.fx, K.fy / K.fx, K.cx, K.cy, K.k1, K.k2};
  bo.refine_readout = options.refine_readout;
  const auto summary =
      options.smooth_trajectory
          ? ba.solveTrajectory(cameras, fixed, X, {}, observations, k, bo, shutter, neighbours,
                               ba_motions)
          : ba.solve(cameras, fixed, X, {}, observations, k, bo, shutter, ba_motions);
  if (summary.status == BundleAdjustmentSummary::Status::kInvalidInput ||
      summary.status == BundleAdjustmentSummary::Status::kNumericalFailure ||
      !(std::isfinite(k.f) && k.f > 0.0))
    return;
  result.ba_iterations = summary.iterations;
  result.ba_observations = static_cast<int>(observations.size());
  if (options.smooth_trajectory) {
    result.line_delay = summary.line_delay;
    result.line_delay_std_error = summary.line_delay_std_error;
  }
  const double aspect = K.fy / K.fx;
  K.fx = k.f;
  K.fy = k.f * aspect;
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const int c = camera_of_frame[f];
    if (c < 0) continue;
    frames[f].pose = fromBa(cameras[static_cast<std::size_t>(c)]);
    motions[f] = ba_motions[static_cast<std::size_t>(c)];
  }
  for (std::size_t p = 0; p < points.size(); ++p)
    if (ba_point[p] >= 0) points[p].X = X[static_cast<std::size_t>(ba_point[p])];
}

}  // namespace

RollingShutterRefinementResult refineRollingShutter(
    const TrackTable& tracks, CameraIntrinsics& K, const RollingShutter& shutter,
    std::vector<SolvedFrame>& frames, std::vector<MapPoint>& points,
    std::vector<RollingShutterMotion>& motions, const RollingShutterRefinementOptions& options) {
  RollingShutterRefinementResult result;
  motions.assign(frames.size(), RollingShutterMotion{});
  Workspace w;
  w.point_of_track.assign(static_cast<std::size_t>(tracks.trackCount()), -1);
  for (std::size_t p = 0; p < points.size(); ++p)
    if (points[p].valid && points[p].track >= 0)
      w.point_of_track[static_cast<std::size_t>(points[p].track)] = static_cast<int>(p);
  result.line_delay = shutter.line_delay;
  if (options.smooth_trajectory) {
    // The global-shutter poses are the middle rows' to within the rows' error; the motions follow
    // from them, so the adjustment starts directly (the rms before from its selection of the
    // observations: the same projections). The rms after uses the readout found.
    adjustJointly(tracks, K, shutter, frames, points, motions, options, w, {}, 0.0, result,
                  &result.rms_before_px);
    RollingShutter found = shutter;
    found.line_delay = result.line_delay;
    result.rms_after_px =
        reprojectionRms(tracks, K, found, frames, points, motions, w, options.reproj_threshold_px);
    return result;
  }
  result.rms_before_px =
      reprojectionRms(tracks, K, shutter, frames, points, motions, w, options.reproj_threshold_px);
  for (int round = 0; round < options.rounds; ++round) {
    result.frames = resectFrames(tracks, K, shutter, frames, points, motions, options, w);
    result.points = intersectPoints(tracks, K, shutter, frames, points, motions, options, w);
  }
  if (options.bundle_adjustment) {
    adjustJointly(tracks, K, shutter, frames, points, motions, options, w, {},
                  options.resection.velocity_prior, result);
    if (options.trajectory_prior > 0.0) {
      // Each frame's motion tied to the trajectory's at that frame (central differences of the
      // poses just refined), then the adjustment again.
      std::vector<RollingShutterMotion> targets = motions;
      trajectoryMotions(frames, targets);
      adjustJointly(tracks, K, shutter, frames, points, motions, options, w, targets,
                    options.trajectory_prior, result);
    }
  }
  result.rms_after_px =
      reprojectionRms(tracks, K, shutter, frames, points, motions, w, options.reproj_threshold_px);
  return result;
}

namespace {

// The image motion (normalized coordinates per frame interval) a readout motion causes at the
// point x_c of the camera: x_c' = -w x x_c - R_cw v, then the projection's derivative.
Eigen::Vector2d imageMotion(const PoseCw& pose, const RollingShutterMotion& m,
                            const Eigen::Vector3d& x_c) {
  const Eigen::Vector3d d = -m.angular.cross(x_c) - pose.R_cw * m.linear;
  const double iz = 1.0 / x_c.z();
  return {(d.x() - x_c.x() * iz * d.z()) * iz, (d.y() - x_c.y() * iz * d.z()) * iz};
}

}  // namespace

ReadoutEstimate estimateReadout(const TrackTable& tracks, const RollingShutter& nominal, int rows,
                                const std::vector<SolvedFrame>& frames,
                                const std::vector<MapPoint>& points,
                                const std::vector<RollingShutterMotion>& motions,
                                double max_std_error) {
  ReadoutEstimate e;
  const double nominal_frames = nominal.line_delay * (rows - 1);
  if (!(nominal_frames > 0.0) || motions.size() != frames.size()) return e;
  std::vector<int> point_of_track(static_cast<std::size_t>(tracks.trackCount()), -1);
  for (std::size_t p = 0; p < points.size(); ++p)
    if (points[p].valid && points[p].track >= 0)
      point_of_track[static_cast<std::size_t>(points[p].track)] = static_cast<int>(p);
  // Regressed over every observed point of the frames with both neighbours solved: the image
  // motion of each point (where the rows see it) from the fitted motion against the frame-to-frame
  // one. Sums of 2-vectors; the residual variance per component.
  double sxy = 0.0, sxx = 0.0, syy = 0.0;
  long n = 0;
  for (int f = 1; f + 1 < static_cast<int>(frames.size()); ++f) {
    const auto& prev = frames[static_cast<std::size_t>(f - 1)];
    const auto& cur = frames[static_cast<std::size_t>(f)];
    const auto& next = frames[static_cast<std::size_t>(f + 1)];
    if (!prev.solved || !cur.solved || !next.solved) continue;
    // R_cw(f + d) = Exp(-w d) R_cw(f), c(f + d) = c(f) + v d (rolling_shutter.hpp).
    RollingShutterMotion between;
    between.angular = 0.5 * (logSo3(prev.pose.R_cw * cur.pose.R_cw.transpose()) -
                             logSo3(next.pose.R_cw * cur.pose.R_cw.transpose()));
    between.linear = 0.5 * (next.pose.centre() - prev.pose.centre());
    int used = 0;
    for (const auto& o : tracks.frame(f)) {
      const int p = point_of_track[static_cast<std::size_t>(o.track)];
      if (p < 0) continue;
      const Eigen::Vector3d x_c = cur.pose.toCamera(points[static_cast<std::size_t>(p)].X);
      if (!(x_c.z() > 0.0)) continue;
      const Eigen::Vector2d fit = imageMotion(cur.pose, motions[static_cast<std::size_t>(f)], x_c);
      const Eigen::Vector2d fd = imageMotion(cur.pose, between, x_c);
      sxy += fit.dot(fd);
      sxx += fd.squaredNorm();
      syy += fit.squaredNorm();
      ++n;
      ++used;
    }
    if (used > 0) ++e.frames;
  }
  if (e.frames < 5 || n < 20 || !(sxx > 0.0)) return e;
  const double slope = sxy / sxx;
  // The fitted motions' deviation from the slope (their own noise and the motion's change within
  // a frame interval) gives the error. A frame's points share its motion, so their deviations are
  // not independent: the slope's variance is the per-point residual variance times the points per
  // frame over sxx, i.e. sse / (frames sxx) (frames - 1 for the slope fitted).
  const double sse = std::max(0.0, syy - slope * sxy);
  e.std_error = nominal_frames * std::sqrt(sse / (static_cast<double>(e.frames - 1) * sxx));
  e.readout_frames = std::clamp(nominal_frames * slope, 0.0, 1.0);
  e.observable = std::isfinite(e.std_error) && e.std_error <= max_std_error;
  return e;
}

void rotationTrajectoryMotions(const std::vector<SolvedFrame>& frames,
                               std::vector<RollingShutterMotion>& motions) {
  const int n = static_cast<int>(frames.size());
  motions.assign(frames.size(), RollingShutterMotion{});
  std::vector<BaCamera> cameras(frames.size());
  for (std::size_t f = 0; f < frames.size(); ++f) cameras[f].R_cw = frames[f].pose.R_cw;
  const auto solved = [&](int f) {
    return f >= 0 && f < n && frames[static_cast<std::size_t>(f)].solved;
  };
  for (int f = 0; f < n; ++f) {
    if (!solved(f)) continue;
    BaTrajectoryNeighbours nb;
    nb.previous = solved(f - 1) ? f - 1 : -1;
    nb.next = solved(f + 1) ? f + 1 : -1;
    motions[static_cast<std::size_t>(f)].angular =
        BundleAdjuster::trajectoryMotion(cameras, nb, f, nullptr).angular;
  }
}

}  // namespace epitrack
