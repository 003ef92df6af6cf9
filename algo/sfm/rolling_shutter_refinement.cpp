#include "algo/sfm/rolling_shutter_refinement.hpp"

#include <cmath>

#include "algo/geometry/triangulation.hpp"
#include "algo/geometry/undistort.hpp"

namespace epitrack {

namespace {

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

}  // namespace

RollingShutterRefinementResult refineRollingShutter(
    const TrackTable& tracks, const CameraIntrinsics& K, const RollingShutter& shutter,
    std::vector<SolvedFrame>& frames, std::vector<MapPoint>& points,
    std::vector<RollingShutterMotion>& motions, const RollingShutterRefinementOptions& options) {
  RollingShutterRefinementResult result;
  motions.assign(frames.size(), RollingShutterMotion{});
  Workspace w;
  w.point_of_track.assign(static_cast<std::size_t>(tracks.trackCount()), -1);
  for (std::size_t p = 0; p < points.size(); ++p)
    if (points[p].valid && points[p].track >= 0)
      w.point_of_track[static_cast<std::size_t>(points[p].track)] = static_cast<int>(p);
  result.rms_before_px =
      reprojectionRms(tracks, K, shutter, frames, points, motions, w, options.reproj_threshold_px);
  for (int round = 0; round < options.rounds; ++round) {
    result.frames = resectFrames(tracks, K, shutter, frames, points, motions, options, w);
    result.points = intersectPoints(tracks, K, shutter, frames, points, motions, options, w);
  }
  result.rms_after_px =
      reprojectionRms(tracks, K, shutter, frames, points, motions, w, options.reproj_threshold_px);
  return result;
}

}  // namespace epitrack
