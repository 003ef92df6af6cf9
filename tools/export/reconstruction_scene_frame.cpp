#include "tools/export/reconstruction_scene_frame.hpp"

#include <cerrno>
#include <cstdlib>
#include <vector>

namespace epitrack::io {

bool parseOriginOption(const std::string& text, SceneFrameOptions& options, std::string& error) {
  if (text == "plane") {
    options.origin = SceneOrigin::kPlane;
    return true;
  }
  if (text == "first-camera") {
    options.origin = SceneOrigin::kFirstCamera;
    return true;
  }
  const std::string prefix = "track:";
  if (text.rfind(prefix, 0) == 0 && text.size() > prefix.size()) {
    const std::string digits = text.substr(prefix.size());
    char* end = nullptr;
    errno = 0;
    const long long id = std::strtoll(digits.c_str(), &end, 10);
    if (errno == 0 && end != nullptr && *end == '\0' && id >= 0) {
      options.origin = SceneOrigin::kTrack;
      options.track_id = static_cast<int64_t>(id);
      return true;
    }
  }
  error =
      "--origin must be plane, first-camera or track:ID (ID a point id >= 0), not '" + text + "'";
  return false;
}

SceneFrame applySceneFrame(Reconstruction& rec, const SceneFrameOptions& options) {
  std::vector<ScenePose> poses;
  for (const SolvedCamera& c : rec.cameras) {
    if (c.solved) poses.push_back({c.R_wc, c.p_wc});
  }
  std::vector<Eigen::Vector3d> points;
  std::vector<int64_t> ids;
  points.reserve(rec.points.size());
  ids.reserve(rec.points.size());
  for (const ScenePoint& p : rec.points) {
    points.push_back(p.X);
    ids.push_back(p.id);
  }
  SceneFrame frame = computeSceneFrame(points, ids, poses, options);
  if (frame.status == SceneFrameStatus::kInvalidInput) {
    rec.origin_note = describe(frame.status);
    return frame;
  }
  const Similarity3& S = frame.world_to_scene;
  for (SolvedCamera& c : rec.cameras) {
    c.p_wc = S.apply(c.p_wc);
    c.R_wc = S.R * c.R_wc;
    // A rolling-shutter motion: w is in the camera frame (unchanged), v a world velocity.
    c.rs_linear = S.scale * (S.R * c.rs_linear);
  }
  for (ScenePoint& p : rec.points) p.X = S.apply(p.X);

  switch (frame.origin_used) {
    case SceneOrigin::kPlane:
      rec.origin = "plane";
      break;
    case SceneOrigin::kFirstCamera:
      rec.origin = "first-camera";
      break;
    case SceneOrigin::kTrack:
      rec.origin = "track:" + std::to_string(options.track_id);
      break;
  }
  rec.plane_found = frame.plane_found;
  rec.ground = frame.ground == SceneGround::kPlane     ? "plane"
               : frame.ground == SceneGround::kCameras ? "cameras"
                                                       : "none";
  if (options.up_from_cameras && options.origin != SceneOrigin::kFirstCamera) {
    rec.up_confidence = frame.up_confidence;
    rec.up_spread_deg = frame.up_spread_deg;
  }
  rec.plane_up_angle_deg = frame.plane_up_angle_deg;
  rec.origin_note = frame.status == SceneFrameStatus::kOk ? std::string() : describe(frame.status);
  return frame;
}

}  // namespace epitrack::io
