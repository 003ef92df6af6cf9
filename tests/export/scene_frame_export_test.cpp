// The scene frame on a real synthetic clip's ground truth (epitrack-synth's room: floor z = 0),
// seen through an arbitrary solver gauge, then exported.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include <Eigen/Geometry>

#include "hal/io/text_formats.hpp"
#include "tests/support/test_support.hpp"
#include "tools/export/colmap_text.hpp"
#include "tools/export/output_writers.hpp"
#include "tools/export/reconstruction_scene_frame.hpp"
#include "tools/synth/synthetic_sequence.hpp"

using namespace epitrack;
using namespace epitrack::io;

namespace {

double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

/// Ground truth of an orbit clip as a Reconstruction, in a world moved by a similarity (what a
/// monocular solver would output: arbitrary origin, rotation and scale).
Reconstruction groundTruthReconstruction(int frames, std::vector<double>& true_heights,
                                         std::map<int64_t, double>& true_z) {
  synth::SynthOptions so;
  so.kind = synth::SceneKind::kOrbit;
  so.frames = frames;
  so.width = 352;
  so.height = 288;
  so.focal = 300.0;
  const synth::SyntheticSequence seq(so);
  const Eigen::Matrix3d G =
      Eigen::AngleAxisd(0.8, Eigen::Vector3d(0.3, -1, 0.4).normalized()).toRotationMatrix();
  const double g_scale = 0.37;
  const Eigen::Vector3d g_t(2.0, -1.0, 0.5);
  Reconstruction rec;
  rec.intrinsics = CameraIntrinsics::centered(so.width, so.height, so.focal);
  rec.frames = frames;
  std::map<int, Eigen::Vector3d> landmarks;
  for (const auto& l : seq.scene().landmarks) landmarks[l.id] = l.position;
  std::map<int64_t, int> seen;
  std::vector<synth::LandmarkObservation> visible;
  for (int i = 0; i < frames; ++i) {
    const synth::Pose pose = seq.pose(i);
    SolvedCamera c;
    c.frame = i;
    c.solved = true;
    c.R_wc = G * pose.R_wc;
    c.p_wc = g_scale * (G * pose.t_wc) + g_t;
    rec.cameras.push_back(c);
    true_heights.push_back(pose.t_wc.z());
    seq.visibleLandmarks(i, visible);
    for (const auto& o : visible) {
      rec.observations.push_back({i, o.id, o.x, o.y, 0.0});
      seen[o.id] += 1;
    }
  }
  for (const auto& [id, n] : seen) {
    ScenePoint p;
    p.id = id;
    p.X = g_scale * (G * landmarks[static_cast<int>(id)]) + g_t;
    p.observations = n;
    rec.points.push_back(p);
    true_z[id] = landmarks[static_cast<int>(id)].z();
  }
  return rec;
}

}  // namespace

TEST_CASE("plane origin on an epitrack-synth orbit puts the floor at z = 0", "[export][scene]") {
  std::vector<double> heights;
  std::map<int64_t, double> true_z;
  Reconstruction rec = groundTruthReconstruction(40, heights, true_z);
  REQUIRE(rec.points.size() > 50);
  SceneFrameOptions options;
  std::string error;
  REQUIRE(parseOriginOption("plane", options, error));
  const SceneFrame frame = applySceneFrame(rec, options);
  REQUIRE(frame.status == SceneFrameStatus::kOk);
  CHECK(rec.origin == "plane");
  CHECK(rec.plane_found);
  // Floor points (true z = 0) at scene z = 0; everything else scaled by 1 / median height.
  const double s = 1.0 / median(heights);
  int floor_points = 0;
  for (const ScenePoint& p : rec.points) {
    CHECK(p.X.z() == Approx(true_z[p.id] * s).margin(1e-9));
    floor_points += true_z[p.id] == 0.0 ? 1 : 0;
  }
  CHECK(frame.plane_inliers == floor_points);
  std::vector<double> z;
  for (const SolvedCamera& c : rec.cameras) z.push_back(c.p_wc.z());
  CHECK(median(z) == Approx(1.0).epsilon(1e-12));
  // Cameras look roughly level: their image "up" (-y) has a positive scene z component.
  for (const SolvedCamera& c : rec.cameras) CHECK(-c.R_wc.col(1).z() > 0.0);

  // Exports of the moved reconstruction stay consistent.
  test::TempDir dir("scene-export");
  REQUIRE(writeAllOutputs(rec, dir.path(), error));
  ColmapModel model;
  REQUIRE(readColmapModel(dir.path() + "/colmap", model, error));
  INFO(error);
  CHECK(checkColmapConsistency(model, error));
  CHECK(model.images.size() == 40);
  std::string summary;
  REQUIRE(hal::readTextFile(dir.file("summary.json"), summary, error));
  CHECK(summary.find("\"plane_found\": true") != std::string::npos);
  CHECK(summary.find("\"up\": \"+z\"") != std::string::npos);
}

TEST_CASE("origin option parsing (--origin)", "[export][scene]") {
  SceneFrameOptions o;
  std::string error;
  CHECK(parseOriginOption("first-camera", o, error));
  CHECK(o.origin == SceneOrigin::kFirstCamera);
  CHECK(parseOriginOption("track:42", o, error));
  CHECK(o.origin == SceneOrigin::kTrack);
  CHECK(o.track_id == 42);
  for (const char* bad :
       {"track:", "track:-1", "track:4x", "Plane", "", "track:99999999999999999999"}) {
    INFO(bad);
    CHECK_FALSE(parseOriginOption(bad, o, error));
  }
}

TEST_CASE("first-camera origin on the same clip", "[export][scene]") {
  std::vector<double> heights;
  std::map<int64_t, double> true_z;
  Reconstruction rec = groundTruthReconstruction(20, heights, true_z);
  SceneFrameOptions options;
  options.origin = SceneOrigin::kFirstCamera;
  const SceneFrame frame = applySceneFrame(rec, options);
  REQUIRE(frame.status == SceneFrameStatus::kOk);
  CHECK(rec.origin == "first-camera");
  CHECK_FALSE(rec.plane_found);
  CHECK(rec.cameras[0].p_wc.norm() < 1e-9);
  CHECK((rec.cameras[0].R_wc - Eigen::Matrix3d::Identity()).norm() < 1e-9);
}
