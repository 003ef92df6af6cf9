// COLMAP text model: cameras.txt, images.txt, points3D.txt (https://colmap.github.io/format.html).

#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include <Eigen/Geometry>

#include "tools/export/output_writers.hpp"

namespace epitrack::io {
namespace {

// COLMAP's pixel origin is the top-left corner of the top-left pixel; ours is its centre.
constexpr double kColmapPixelShift = 0.5;

bool usableCamera(const SolvedCamera& c) {
  return c.solved && c.R_wc.allFinite() && c.p_wc.allFinite();
}

std::string imageName(const Reconstruction& rec, int64_t frame, const ExportOptions& options) {
  if (frame >= 0 && static_cast<std::size_t>(frame) < rec.frame_names.size() &&
      !rec.frame_names[static_cast<std::size_t>(frame)].empty()) {
    return rec.frame_names[static_cast<std::size_t>(frame)];
  }
  std::string digits = std::to_string(frame);
  if (digits.size() < static_cast<std::size_t>(options.image_name_digits)) {
    digits.insert(0, static_cast<std::size_t>(options.image_name_digits) - digits.size(), '0');
  }
  return digits + options.image_extension;
}

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.10g", v);
  return buf;
}

/// The 2D points of each exported image, in the order written on its POINTS2D line, and the
/// points written to points3D.txt. Kept: observations that are not outliers (so that COLMAP's own
/// adjustment sees exactly the observations behind the ERROR column and summary.json's means)
/// of finite points in solved frames, one per
/// (frame, point) pair (the first), of points seen in at least two exported images: COLMAP's
/// bundle adjuster asserts tracks of length >= 2. Shared by images.txt and points3D.txt so that
/// POINT2D_IDX references agree.
struct ColmapTracks {
  std::map<int64_t, std::vector<const PointObservation*>> per_frame;  // frame -> observations
  std::unordered_map<int64_t, std::vector<std::pair<int64_t, int>>> per_point;  // id -> (img, idx)
};

constexpr std::size_t kMinColmapTrackLength = 2;

ColmapTracks buildTracks(const Reconstruction& rec) {
  std::unordered_set<int64_t> solved_frames;
  for (const SolvedCamera& c : rec.cameras) {
    if (usableCamera(c)) solved_frames.insert(c.frame);
  }
  std::unordered_map<int64_t, std::size_t> track_length;
  for (const ScenePoint& p : rec.points) {
    if (p.X.allFinite() && p.id >= 0) track_length[p.id] = 0;
  }
  std::vector<const PointObservation*> kept;
  std::set<std::pair<int64_t, int64_t>> seen;  // (frame, point)
  for (const PointObservation& o : rec.observations) {
    if (o.outlier || solved_frames.count(o.frame) == 0) continue;
    const auto len = track_length.find(o.point_id);
    if (len == track_length.end() || !std::isfinite(o.x) || !std::isfinite(o.y)) continue;
    if (!seen.emplace(o.frame, o.point_id).second) continue;
    len->second += 1;
    kept.push_back(&o);
  }
  ColmapTracks t;
  for (const auto& [id, len] : track_length) {
    if (len >= kMinColmapTrackLength) t.per_point[id];  // listed even before its entries
  }
  for (const PointObservation* o : kept) {
    auto track = t.per_point.find(o->point_id);
    if (track == t.per_point.end()) continue;
    auto& list = t.per_frame[o->frame];
    track->second.emplace_back(o->frame + 1, static_cast<int>(list.size()));
    list.push_back(o);
  }
  return t;
}

/// The ERROR column: the point's mean reprojection error over its inlier observations, 0 when
/// unknown.
double colmapError(const ScenePoint& p) { return std::isfinite(p.reproj_px) ? p.reproj_px : 0.0; }

}  // namespace

ColmapCounts colmapCounts(const Reconstruction& rec) {
  const ColmapTracks tracks = buildTracks(rec);
  ColmapCounts n;
  for (const SolvedCamera& c : rec.cameras) n.images += usableCamera(c) ? 1 : 0;
  std::unordered_set<int64_t> listed;
  for (const ScenePoint& p : rec.points) {
    const auto it = tracks.per_point.find(p.id);
    if (it == tracks.per_point.end() || !p.X.allFinite() || !listed.insert(p.id).second) continue;
    n.points += 1;
    n.observations += static_cast<int64_t>(it->second.size());
    n.mean_error_px += colmapError(p);
  }
  if (n.points > 0) n.mean_error_px /= static_cast<double>(n.points);
  return n;
}

std::string formatColmapCameras(const Reconstruction& rec) {
  const CameraIntrinsics& k = rec.intrinsics;
  const double cx = k.cx + kColmapPixelShift;
  const double cy = k.cy + kColmapPixelShift;
  const bool square = k.fx == k.fy;
  std::string model;
  std::string params;
  if (!k.hasDistortion()) {
    model = "PINHOLE";
    params = num(k.fx) + " " + num(k.fy) + " " + num(cx) + " " + num(cy);
  } else if (square && k.k2 == 0.0) {
    model = "SIMPLE_RADIAL";
    params = num(k.fx) + " " + num(cx) + " " + num(cy) + " " + num(k.k1);
  } else if (square) {
    model = "RADIAL";
    params = num(k.fx) + " " + num(cx) + " " + num(cy) + " " + num(k.k1) + " " + num(k.k2);
  } else {
    model = "OPENCV";  // fx fy cx cy k1 k2 p1 p2
    params = num(k.fx) + " " + num(k.fy) + " " + num(cx) + " " + num(cy) + " " + num(k.k1) + " " +
             num(k.k2) + " 0 0";
  }
  std::string out =
      "# Camera list with one line of data per camera:\n"
      "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
      "# Number of cameras: 1\n";
  out += "1 " + model + " " + std::to_string(k.width) + " " + std::to_string(k.height) + " " +
         params + "\n";
  return out;
}

std::string formatColmapImages(const Reconstruction& rec, const ExportOptions& options) {
  const ColmapTracks tracks = buildTracks(rec);
  int images = 0;
  std::size_t total_points = 0;
  for (const SolvedCamera& c : rec.cameras) {
    if (!usableCamera(c)) continue;
    ++images;
    const auto it = tracks.per_frame.find(c.frame);
    if (it != tracks.per_frame.end()) total_points += it->second.size();
  }
  std::string out =
      "# Image list with two lines of data per image:\n"
      "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
      "#   POINTS2D[] as (X, Y, POINT3D_ID)\n";
  char buf[512];
  std::snprintf(buf, sizeof(buf), "# Number of images: %d, mean observations per image: %.6g\n",
                images, images > 0 ? static_cast<double>(total_points) / images : 0.0);
  out += buf;
  // COLMAP's cameras are global-shutter: a rolling-shutter solve's poses are the middle row's.
  if (rec.readout_frames > 0.0) out += "# " + rollingShutterNote(rec) + "\n";
  for (const SolvedCamera& c : rec.cameras) {
    if (!usableCamera(c)) continue;
    // COLMAP stores the world-to-camera transform: x_c = R_cw X + t_cw.
    const Eigen::Matrix3d R_cw = c.R_wc.transpose();
    const Eigen::Vector3d t_cw = -R_cw * c.p_wc;
    Eigen::Quaterniond q(R_cw);
    q.normalize();
    if (q.w() < 0.0) q.coeffs() = -q.coeffs();
    std::snprintf(buf, sizeof(buf), "%lld %.12g %.12g %.12g %.12g %.12g %.12g %.12g 1 ",
                  static_cast<long long>(c.frame) + 1, q.w(), q.x(), q.y(), q.z(), t_cw.x(),
                  t_cw.y(), t_cw.z());
    out += buf;
    out += imageName(rec, c.frame, options);
    out += "\n";
    const auto it = tracks.per_frame.find(c.frame);
    if (it != tracks.per_frame.end()) {
      bool first = true;
      for (const PointObservation* o : it->second) {
        std::snprintf(buf, sizeof(buf), "%s%.6f %.6f %lld", first ? "" : " ",
                      o->x + kColmapPixelShift, o->y + kColmapPixelShift,
                      static_cast<long long>(o->point_id));
        out += buf;
        first = false;
      }
    }
    out += "\n";
  }
  return out;
}

std::string formatColmapPoints3D(const Reconstruction& rec) {
  const ColmapTracks tracks = buildTracks(rec);
  std::size_t count = 0;
  std::size_t track_total = 0;
  std::unordered_set<int64_t> listed;  // a repeated id is written once
  for (const ScenePoint& p : rec.points) {
    const auto it = tracks.per_point.find(p.id);
    if (it == tracks.per_point.end() || !p.X.allFinite() || !listed.insert(p.id).second) continue;
    ++count;
    track_total += it->second.size();
  }
  std::string out =
      "# 3D point list with one line of data per point:\n"
      "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n";
  char buf[256];
  std::snprintf(buf, sizeof(buf), "# Number of points: %zu, mean track length: %.6g\n", count,
                count > 0 ? static_cast<double>(track_total) / static_cast<double>(count) : 0.0);
  out += buf;
  listed.clear();
  for (const ScenePoint& p : rec.points) {
    const auto it = tracks.per_point.find(p.id);
    if (it == tracks.per_point.end() || !p.X.allFinite() || !listed.insert(p.id).second) continue;
    const double err = colmapError(p);
    std::snprintf(buf, sizeof(buf), "%lld %.12g %.12g %.12g %u %u %u %.6g",
                  static_cast<long long>(p.id), p.X.x(), p.X.y(), p.X.z(),
                  static_cast<unsigned>(p.gray), static_cast<unsigned>(p.gray),
                  static_cast<unsigned>(p.gray), err);
    out += buf;
    for (const auto& [image_id, idx] : it->second) {
      std::snprintf(buf, sizeof(buf), " %lld %d", static_cast<long long>(image_id), idx);
      out += buf;
    }
    out += "\n";
  }
  return out;
}

}  // namespace epitrack::io
