// blender_camera.py run by Blender itself (headless; skipped visibly when `blender` is absent):
// Blender's own projection of the point cloud through the camera the script builds
// (bpy_extras world_to_camera_view, tests/export/blender_probe.py) must land where cameras.tum and
// intrinsics.txt project the same points, on a camera with fx != fy, an off-centre principal point
// and radial distortion (carried by the plate clip's lens). Also the scene's frame range and rate
// and the plate: the input frames loaded as the camera's background clip.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "algo/image/image.hpp"
#include "hal/io/image_codec.hpp"
#include "hal/io/text_formats.hpp"
#include "tests/export/export_fixture.hpp"
#include "tests/support/test_support.hpp"
#include "tools/export/output_writers.hpp"

using namespace epitrack::io;
using epitrack::CameraIntrinsics;
namespace et = epitrack::test;

namespace {

struct BlenderReadBack {
  int width = 0, height = 0;
  double aspect_x = 0.0, aspect_y = 0.0;
  int fps = 0;
  double fps_base = 0.0;
  int frame_start = 0, frame_end = 0;
  bool have_clip = false;
  int clip_width = 0, clip_height = 0, clip_start = 0, clip_frames = 0;
  double clip_focal = 0.0, clip_aspect = 0.0, clip_px = 0.0, clip_py = 0.0, clip_k1 = 0.0,
         clip_k2 = 0.0;
  int backgrounds = 0, show_backgrounds = 0;
  std::map<int, double> plate_gray;  // Blender frame -> gray level of the rendered plate
  std::vector<Eigen::Vector3d> vertices;
  std::map<int, std::pair<Eigen::Vector3d, Eigen::Quaterniond>> poses;  // Blender frame -> pose
  std::map<int, std::vector<Eigen::Vector3d>> views;  // Blender frame -> (x, y, depth) per vertex
};

BlenderReadBack readProbe(const std::string& path) {
  BlenderReadBack b;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream f(line);
    std::string what;
    f >> what;
    if (what == "render") {
      f >> b.width >> b.height >> b.aspect_x >> b.aspect_y;
    } else if (what == "fps") {
      f >> b.fps >> b.fps_base;
    } else if (what == "frames") {
      f >> b.frame_start >> b.frame_end;
    } else if (what == "clip") {
      b.have_clip = true;
      f >> b.clip_width >> b.clip_height >> b.clip_start >> b.clip_frames >> b.clip_focal >>
          b.clip_aspect >> b.clip_px >> b.clip_py >> b.clip_k1 >> b.clip_k2;
    } else if (what == "background") {
      f >> b.backgrounds >> b.show_backgrounds;
    } else if (what == "plate") {
      int frame = 0;
      double gray = 0.0;
      f >> frame >> gray;
      b.plate_gray[frame] = gray;
    } else if (what == "vertex") {
      int i = 0;
      Eigen::Vector3d v;
      f >> i >> v.x() >> v.y() >> v.z();
      b.vertices.push_back(v);
    } else if (what == "pose") {
      int frame = 0;
      Eigen::Vector3d t;
      double w = 0, x = 0, y = 0, z = 0;
      f >> frame >> t.x() >> t.y() >> t.z() >> w >> x >> y >> z;
      b.poses[frame] = {t, Eigen::Quaterniond(w, x, y, z).normalized()};
    } else if (what == "view") {
      int frame = 0, i = 0;
      Eigen::Vector3d v;
      f >> frame >> i >> v.x() >> v.y() >> v.z();
      b.views[frame].push_back(v);
    }
  }
  return b;
}

Eigen::Vector2d projectWith(const CameraIntrinsics& k, const epitrack::hal::TrajectoryEntry& pose,
                            const Eigen::Vector3d& X, bool distort) {
  const Eigen::Vector3d xc = pose.rotation.toRotationMatrix().transpose() * (X - pose.position);
  const double u = xc.x() / xc.z();
  const double v = xc.y() / xc.z();
  const double r2 = u * u + v * v;
  const double d = distort ? 1.0 + k.k1 * r2 + k.k2 * r2 * r2 : 1.0;
  return {k.fx * u * d + k.cx, k.fy * v * d + k.cy};
}

}  // namespace

TEST_CASE("Blender loads blender_camera.py and projects the points as cameras.tum does",
          "[export][blender][slow][no-asan]") {
  if (et::run("command -v blender > /dev/null 2>&1") != 0) {
    std::printf(
        "EPITRACK-SKIP: blender not installed (tools/deps.sh clients), Blender itself not run\n");
    return;
  }
  Reconstruction rec = et::makeReconstruction(12, 5, -0.08, 0.01);
  // fx != fy and a principal point well off the centre: the vertical lens shift must account for
  // the pixel aspect the script sets (issue 25 item 1).
  rec.intrinsics.fy = 530.0;
  rec.intrinsics.cx = 347.25;
  rec.intrinsics.cy = 203.5;
  rec.fps = 30.0;
  et::TempDir dir("blender-real");
  // The input frames, as an image directory source names them.
  epitrack::Image<uint8_t> frame(rec.intrinsics.width, rec.intrinsics.height);
  std::string error;
  REQUIRE(et::run("mkdir -p '" + dir.file("frames") + "'") == 0);
  for (int i = 0; i < rec.frames; ++i) {
    // Frame i is uniformly 10 + 20 i: the gray level tells which frame the plate shows.
    for (int y = 0; y < frame.height(); ++y)
      for (int x = 0; x < frame.width(); ++x)
        frame.view()(x, y) = static_cast<uint8_t>(10 + 20 * i);
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.jpg", i);
    REQUIRE(epitrack::hal::writeJpegGray(dir.file("frames/") + name, frame.constView(), 80, error));
    rec.frame_names.emplace_back(name);
  }
  rec.frames_dir = dir.file("frames");
  ExportOptions options;
  REQUIRE(writeAllOutputs(rec, dir.file("out"), options, error));

  const std::string probe = dir.file("probe.txt");
  REQUIRE(et::run("cd '" + dir.file("out") +
                  "' && blender -b --factory-startup --python-exit-code 1 --python "
                  "blender_camera.py --python '" +
                  EPITRACK_SOURCE_DIR + "/tests/export/blender_probe.py' -- '" + probe + "' '" +
                  dir.path() + "' 1 8 12 > '" + dir.file("blender.log") + "' 2>&1") == 0);
  const BlenderReadBack b = readProbe(probe);

  // What the export says, read back from its own files.
  CameraIntrinsics k;
  REQUIRE(epitrack::hal::readIntrinsicsFile(dir.file("out/intrinsics.txt"), k, error));
  std::vector<epitrack::hal::TrajectoryEntry> tum;
  REQUIRE(epitrack::hal::readTrajectoryFile(dir.file("out/cameras.tum"), tum, error));
  REQUIRE(tum.size() == 10);

  CHECK(b.width == k.width);
  CHECK(b.height == k.height);
  CHECK(b.aspect_x / b.aspect_y == Approx(k.fy / k.fx).epsilon(1e-6));
  // The clip's rate and every frame of it (1-based), solved or not (issue 25 item 2).
  CHECK(b.fps / b.fps_base == Approx(30.0));
  CHECK(b.frame_start == 1);
  CHECK(b.frame_end == rec.frames);
  // The plate: the input frames as the camera's background clip, first frame at frame 1.
  REQUIRE(b.have_clip);
  CHECK(b.clip_width == k.width);
  CHECK(b.clip_height == k.height);
  CHECK(b.clip_start == 1);
  CHECK(b.clip_frames == rec.frames);
  CHECK(b.backgrounds == 1);
  CHECK(b.show_backgrounds == 1);
  // The clip's lens: our intrinsics in Blender's tracking conventions (pixels from the bottom-left
  // corner, pixel aspect fy / fx).
  CHECK(b.clip_focal == Approx(k.fx).epsilon(1e-6));
  CHECK(b.clip_focal * b.clip_aspect == Approx(k.fy).epsilon(1e-6));
  CHECK(b.clip_px - 0.5 == Approx(k.cx).epsilon(1e-6));
  CHECK(k.height - b.clip_py - 0.5 == Approx(k.cy).epsilon(1e-6));
  CHECK(b.clip_k1 == Approx(k.k1).epsilon(1e-6));
  CHECK(b.clip_k2 == Approx(k.k2).epsilon(1e-6));
  // Blender frame f shows input frame f - 1 (gray 10 + 20 (f - 1); JPEG keeps a flat gray within
  // a level or two).
  REQUIRE(b.plate_gray.size() == 3);
  for (const auto& [bf, gray] : b.plate_gray) {
    INFO("Blender frame " << bf);
    CHECK(std::abs(gray - (10.0 + 20.0 * (bf - 1))) < 3.0);
  }
  const double lens_fx = b.clip_focal;
  const double lens_fy = b.clip_focal * b.clip_aspect;
  const double lens_cx = b.clip_px - 0.5;
  const double lens_cy = k.height - b.clip_py - 0.5;

  // The point cloud kept (Blender stores vertices as floats).
  REQUIRE(b.vertices.size() == rec.points.size());
  for (std::size_t i = 0; i < b.vertices.size(); ++i)
    CHECK((b.vertices[i] - rec.points[i].X).norm() < 1e-6);

  double worst_pinhole_px = 0.0;
  double worst_distorted_px = 0.0;
  double worst_position = 0.0;
  double worst_angle = 0.0;
  int frames_compared = 0;
  for (const auto& pose : tum) {
    const int bf = static_cast<int>(pose.t) + options.blender_frame_offset;
    REQUIRE(b.poses.count(bf) == 1);
    REQUIRE(b.views.count(bf) == 1);
    ++frames_compared;
    // The camera object: our pose with the axes (x, -y, -z).
    const auto& [location, rotation] = b.poses.at(bf);
    worst_position = std::max(worst_position, (location - pose.position).norm());
    const Eigen::Quaterniond expected(pose.rotation.toRotationMatrix() *
                                      Eigen::Vector3d(1, -1, -1).asDiagonal());
    worst_angle = std::max(worst_angle, rotation.angularDistance(expected));
    const auto& views = b.views.at(bf);
    REQUIRE(views.size() == b.vertices.size());
    for (std::size_t i = 0; i < views.size(); ++i) {
      REQUIRE(views[i].z() > 0.0);
      // Blender's frame coordinates -> our pixels (origin at the centre of the top-left pixel).
      const Eigen::Vector2d blender(views[i].x() * k.width - 0.5,
                                    (1.0 - views[i].y()) * k.height - 0.5);
      const Eigen::Vector2d pinhole = projectWith(k, pose, b.vertices[i], false);
      worst_pinhole_px = std::max(worst_pinhole_px, (blender - pinhole).norm());
      // Blender's pinhole camera + the plate clip's lens distortion = our full model.
      const double xn = (blender.x() - lens_cx) / lens_fx;
      const double yn = (blender.y() - lens_cy) / lens_fy;
      const double r2 = xn * xn + yn * yn;
      const double d = 1.0 + b.clip_k1 * r2 + b.clip_k2 * r2 * r2;
      const Eigen::Vector2d distorted(lens_fx * xn * d + lens_cx, lens_fy * yn * d + lens_cy);
      worst_distorted_px = std::max(worst_distorted_px,
                                    (distorted - projectWith(k, pose, b.vertices[i], true)).norm());
    }
  }
  std::printf(
      "Blender %d frames x %zu points: worst projection difference %.2e px (pinhole), %.2e px "
      "(with the clip's distortion); camera position %.2e, rotation %.2e rad\n",
      frames_compared, b.vertices.size(), worst_pinhole_px, worst_distorted_px, worst_position,
      worst_angle);
  CHECK(frames_compared == 10);
  CHECK(worst_pinhole_px < 0.01);
  CHECK(worst_distorted_px < 0.01);
  CHECK(worst_position < 1e-5);
  CHECK(worst_angle < 1e-5);
}

TEST_CASE("Blender's Nuke .chan importer puts camera.chan's camera where cameras.tum is",
          "[export][blender][nuke][slow][no-asan]") {
  if (et::run("command -v blender > /dev/null 2>&1") != 0) {
    std::printf(
        "EPITRACK-SKIP: blender not installed (tools/deps.sh clients), Blender itself not run\n");
    return;
  }
  Reconstruction rec = et::makeReconstruction(12, 5);
  rec.intrinsics.cx = 347.25;  // off-centre: what .chan cannot carry
  rec.intrinsics.cy = 203.5;
  et::TempDir dir("blender-chan");
  std::string error;
  ExportOptions options;
  options.nuke_frame_offset = 1;  // Blender's importer keys frame = the .chan's frame
  REQUIRE(writeAllOutputs(rec, dir.path(), options, error));
  {
    std::ofstream points(dir.file("points.txt"));
    for (const auto& p : rec.points) points << p.X.x() << ' ' << p.X.y() << ' ' << p.X.z() << '\n';
  }
  const std::string probe = dir.file("probe.txt");
  REQUIRE(et::run("blender -b --factory-startup --python-exit-code 1 --python '" +
                  std::string(EPITRACK_SOURCE_DIR) + "/tests/export/blender_chan_probe.py' -- '" +
                  probe + "' '" + dir.file("camera.chan") + "' 640 480 '" + dir.file("points.txt") +
                  "' > '" + dir.file("blender.log") + "' 2>&1") == 0);
  const BlenderReadBack b = readProbe(probe);
  CameraIntrinsics k;
  REQUIRE(epitrack::hal::readIntrinsicsFile(dir.file("intrinsics.txt"), k, error));
  std::vector<epitrack::hal::TrajectoryEntry> tum;
  REQUIRE(epitrack::hal::readTrajectoryFile(dir.file("cameras.tum"), tum, error));
  REQUIRE(b.poses.size() == tum.size());
  double worst_position = 0.0, worst_angle = 0.0, worst_centred_px = 0.0, worst_ours_px = 0.0;
  for (const auto& pose : tum) {
    const int bf = static_cast<int>(pose.t) + options.nuke_frame_offset;
    REQUIRE(b.poses.count(bf) == 1);
    const auto& [location, rotation] = b.poses.at(bf);
    worst_position = std::max(worst_position, (location - pose.position).norm());
    const Eigen::Quaterniond expected(pose.rotation.toRotationMatrix() *
                                      Eigen::Vector3d(1, -1, -1).asDiagonal());
    worst_angle = std::max(worst_angle, rotation.angularDistance(expected));
    const auto& views = b.views.at(bf);
    REQUIRE(views.size() == rec.points.size());
    // .chan carries fy (as the vertical field of view) but no principal point: the imported
    // camera is ours with the principal point at the centre, and off by the offset from ours.
    CameraIntrinsics centred = k;
    centred.cx = 0.5 * (k.width - 1);
    centred.cy = 0.5 * (k.height - 1);
    for (std::size_t i = 0; i < views.size(); ++i) {
      const Eigen::Vector2d blender(views[i].x() * k.width - 0.5,
                                    (1.0 - views[i].y()) * k.height - 0.5);
      worst_centred_px = std::max(
          worst_centred_px, (blender - projectWith(centred, pose, rec.points[i].X, false)).norm());
      worst_ours_px =
          std::max(worst_ours_px, (blender - projectWith(k, pose, rec.points[i].X, false)).norm());
    }
  }
  std::printf(
      "Blender .chan import, %zu frames: camera position %.2e, rotation %.2e rad; projection vs "
      "a centred camera %.2e px, vs ours (principal point (%.2f, %.2f)) %.1f px\n",
      tum.size(), worst_position, worst_angle, worst_centred_px, k.cx, k.cy, worst_ours_px);
  CHECK(worst_position < 1e-5);
  CHECK(worst_angle < 1e-5);
  CHECK(worst_centred_px < 0.01);
  CHECK(worst_ours_px == Approx(std::hypot(347.25 - 319.5, 203.5 - 239.5)).margin(0.01));
}

TEST_CASE("blender_camera.py builds the scene without a plate Blender cannot read",
          "[export][blender][slow][no-asan]") {
  if (et::run("command -v blender > /dev/null 2>&1") != 0) {
    std::printf(
        "EPITRACK-SKIP: blender not installed (tools/deps.sh clients), Blender itself not run\n");
    return;
  }
  Reconstruction rec = et::makeReconstruction(6, 0);
  et::TempDir dir("blender-pgm");
  epitrack::Image<uint8_t> frame(rec.intrinsics.width, rec.intrinsics.height);
  std::string error;
  REQUIRE(et::run("mkdir -p '" + dir.file("frames") + "'") == 0);
  for (int i = 0; i < rec.frames; ++i) {  // PGM: epitrack-synth's frames, not readable by Blender
    et::fillRandom(frame.view(), static_cast<uint32_t>(i + 1));
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.pgm", i);
    REQUIRE(epitrack::hal::writePgm(dir.file("frames/") + name, frame.constView(), error));
    rec.frame_names.emplace_back(name);
  }
  rec.frames_dir = dir.file("frames");
  REQUIRE(writeAllOutputs(rec, dir.file("out"), error));
  const std::string probe = dir.file("probe.txt");
  REQUIRE(et::run("cd '" + dir.file("out") +
                  "' && blender -b --factory-startup --python-exit-code 1 --python "
                  "blender_camera.py --python '" +
                  EPITRACK_SOURCE_DIR + "/tests/export/blender_probe.py' -- '" + probe + "' > '" +
                  dir.file("blender.log") + "' 2>&1") == 0);
  const BlenderReadBack b = readProbe(probe);
  CHECK_FALSE(b.have_clip);
  CHECK(b.poses.size() == 6);
  CHECK(b.vertices.size() == rec.points.size());
  CHECK(
      et::readWholeFile(dir.file("blender.log")).find("epitrack: no plate, Blender cannot read") !=
      std::string::npos);
}

TEST_CASE("blender_camera.py carries a rolling-shutter solve's readout and motions",
          "[export][blender][slow][no-asan]") {
  if (et::run("command -v blender > /dev/null 2>&1") != 0) {
    std::printf(
        "EPITRACK-SKIP: blender not installed (tools/deps.sh clients), Blender itself not run\n");
    return;
  }
  Reconstruction rec = et::makeReconstruction(6, 0);
  rec.readout_frames = 0.9;
  rec.readout_ms = 30.0;
  rec.fps = 30.0;
  rec.readout_reference_row = 0.5 * (rec.intrinsics.height - 1);
  for (std::size_t i = 0; i < rec.cameras.size(); ++i) {
    const double s = 0.01 * static_cast<double>(i + 1);
    rec.cameras[i].rs_angular = Eigen::Vector3d(s, -2.0 * s, 0.5 * s);
    rec.cameras[i].rs_linear = Eigen::Vector3d(-s, 0.3 * s, 3.0 * s);
  }
  et::TempDir dir("blender-rs");
  std::string error;
  REQUIRE(writeAllOutputs(rec, dir.file("out"), error));
  const std::string probe = dir.file("probe.txt");
  // Blender's own values of the custom properties: the constants, and the keyed F-curves
  // evaluated at every frame of the scene.
  {
    std::ofstream script(dir.file("rs_probe.py"));
    script << R"PY(import sys
import bpy
out = open(sys.argv[sys.argv.index("--") + 1], "w")
scene = bpy.context.scene
camera = bpy.data.objects["epitrack_camera"]
out.write("readout %r %r %r\n" % (camera["epitrack_readout_frames"], camera["epitrack_readout_ms"],
                                  camera["epitrack_reference_row"]))
curves = {(c.data_path, c.array_index): c for c in camera.animation_data.action.fcurves}
for frame in range(scene.frame_start, scene.frame_end + 1):
    w = [curves[('["epitrack_rs_angular"]', i)].evaluate(frame) for i in range(3)]
    v = [curves[('["epitrack_rs_linear"]', i)].evaluate(frame) for i in range(3)]
    out.write("motion %d %r %r %r %r %r %r\n" % (frame, w[0], w[1], w[2], v[0], v[1], v[2]))
out.close()
)PY";
  }
  REQUIRE(et::run("cd '" + dir.file("out") +
                  "' && blender -b --factory-startup --python-exit-code 1 --python "
                  "blender_camera.py --python '" +
                  dir.file("rs_probe.py") + "' -- '" + probe + "' > '" + dir.file("blender.log") +
                  "' 2>&1") == 0);
  std::ifstream in(probe);
  std::string line;
  int motions = 0;
  double worst = 0.0;
  bool have_readout = false;
  while (std::getline(in, line)) {
    std::istringstream f(line);
    std::string what;
    f >> what;
    if (what == "readout") {
      double frames = 0, ms = 0, row = 0;
      f >> frames >> ms >> row;
      have_readout = true;
      CHECK(frames == 0.9);
      CHECK(ms == 30.0);
      CHECK(row == rec.readout_reference_row);
    } else if (what == "motion") {
      int frame = 0;
      Eigen::Vector3d w, v;
      f >> frame >> w.x() >> w.y() >> w.z() >> v.x() >> v.y() >> v.z();
      const auto& cam = rec.cameras[static_cast<std::size_t>(frame - 1)];  // Blender frame 1 = 0
      worst = std::max({worst, (w - cam.rs_angular).cwiseAbs().maxCoeff(),
                        (v - cam.rs_linear).cwiseAbs().maxCoeff()});
      ++motions;
    }
  }
  std::printf("Blender rolling-shutter properties: %d frames, worst motion difference %.2e\n",
              motions, worst);
  CHECK(have_readout);
  CHECK(motions == 6);
  CHECK(worst < 1e-6);
}
