// Executes blender_camera.py with a stand-in `bpy` module (tests/export/fake_bpy) and checks that
// the camera it builds reproduces our projections: Blender's camera model (horizontal sensor fit,
// lens shift in units of the width, camera looking down -Z with +Y up) applied to the recorded
// keyframes must give the pixel coordinates of epitrack's pinhole model.

#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "tests/export/export_fixture.hpp"
#include "tests/support/test_support.hpp"
#include "tools/export/output_writers.hpp"

using namespace epitrack::io;
namespace et = epitrack::test;

TEST_CASE("blender_camera.py builds a camera that reprojects like ours", "[export][blender]") {
  if (et::run("command -v python3 > /dev/null 2>&1") != 0) {
    std::printf("EPITRACK-SKIP: python3 missing, blender_camera.py not executed\n");
    return;
  }
  Reconstruction rec = et::makeReconstruction(12, 5);
  rec.intrinsics.cx = 330.25;  // off-centre principal point exercises the lens shift
  rec.intrinsics.cy = 201.5;
  rec.intrinsics.fy = 530.0;  // non-square pixels: the vertical shift depends on the pixel aspect
  rec.has_timestamps = true;  // fixture: 0.04 s per frame, 25 fps
  rec.cameras.back().solved = false;  // the scene still spans the whole clip
  et::TempDir dir("blender-run");
  std::string error;
  ExportOptions options;
  options.sensor_width_mm = 24.0;
  REQUIRE(writeAllOutputs(rec, dir.path(), options, error));
  const std::string out = dir.file("bpy_record.txt");
  const std::string cmd = "cd '" + dir.path() + "' && EPITRACK_FAKE_BPY_OUT='" + out +
                          "' PYTHONPATH='" + EPITRACK_SOURCE_DIR +
                          "/tests/export/fake_bpy' python3 blender_camera.py > /dev/null";
  REQUIRE(et::run(cmd) == 0);

  std::ifstream in(out);
  REQUIRE(in.good());
  std::string line;
  int width = 0, height = 0, percent = 0;
  double aspect_x = 0.0, aspect_y = 0.0;
  int frame_start = 0, frame_end = 0, fps = 0;
  double fps_base = 0.0;
  std::string mode, fit;
  double sensor = 0, lens = 0, shift_x = 0, shift_y = 0, clip_end = 0;
  std::map<int, Eigen::Vector3d> locations;
  std::map<int, Eigen::Quaterniond> rotations;
  std::vector<Eigen::Vector3d> vertices;
  while (std::getline(in, line)) {
    std::istringstream f(line);
    std::string what;
    f >> what;
    if (what == "render") {
      f >> width >> height >> percent >> aspect_x >> aspect_y;
    } else if (what == "frames") {
      f >> frame_start >> frame_end;
    } else if (what == "fps") {
      f >> fps >> fps_base;
    } else if (what == "camera") {
      f >> mode >> fit >> sensor >> lens >> shift_x >> shift_y >> clip_end;
    } else if (what == "location") {
      int frame = 0;
      Eigen::Vector3d p;
      f >> frame >> p.x() >> p.y() >> p.z();
      locations[frame] = p;
    } else if (what == "rotation_quaternion") {
      int frame = 0;
      double w = 0, x = 0, y = 0, z = 0;
      f >> frame >> w >> x >> y >> z;
      rotations[frame] = Eigen::Quaterniond(w, x, y, z);
    } else if (what == "vertex") {
      Eigen::Vector3d v;
      f >> v.x() >> v.y() >> v.z();
      vertices.push_back(v);
    }
  }
  CHECK(width == 640);
  CHECK(height == 480);
  CHECK(percent == 100);
  CHECK(fps == 25);
  CHECK(fps_base == Approx(1.0));
  CHECK(mode == "QUATERNION");
  CHECK(fit == "HORIZONTAL");
  CHECK(sensor == 24.0);
  CHECK(lens == Approx(500.0 * 24.0 / 640.0));
  CHECK(aspect_x / aspect_y == Approx(530.0 / 500.0));
  CHECK(frame_start == 1);  // frame 0 + offset 1
  CHECK(frame_end == 12);   // frame 11 + 1, unsolved
  REQUIRE(vertices.size() == rec.points.size());
  for (std::size_t i = 0; i < vertices.size(); ++i)
    CHECK((vertices[i] - rec.points[i].X).norm() < 1e-8);

  const double f_px = lens / sensor * width;
  int keys = 0;
  double worst_px = 0.0;
  for (const auto& c : rec.cameras) {
    if (!c.solved) {
      CHECK(locations.count(static_cast<int>(c.frame) + 1) == 0);
      continue;
    }
    const int bf = static_cast<int>(c.frame) + 1;
    REQUIRE(locations.count(bf) == 1);
    REQUIRE(rotations.count(bf) == 1);
    ++keys;
    CHECK((locations[bf] - c.p_wc).norm() < 1e-8);
    const Eigen::Matrix3d R_b = rotations[bf].normalized().toRotationMatrix();
    for (const auto& p : rec.points) {
      // Blender camera space: looking down -Z, +Y up.
      const Eigen::Vector3d P = R_b.transpose() * (p.X - locations[bf]);
      const double xb = f_px * P.x() / -P.z();
      const double yb = f_px * P.y() / -P.z();
      // Blender's view plane (BKE_camera_params_compute_viewplane), in units of a pixel's width:
      // x spans [shift_x W - W/2, shift_x W + W/2]; y spans ycor H around shift_y W, a row being
      // ycor = aspect_y / aspect_x of those units. Pixel edges from the top-left, then our
      // centre-of-pixel origin.
      const double ycor = aspect_y / aspect_x;
      const double u = xb - (shift_x * width - 0.5 * width) - 0.5;
      const double v = ((shift_y * width + 0.5 * ycor * height) - yb) / ycor - 0.5;
      const Eigen::Vector2d ours = et::projectPinhole(rec.intrinsics, c, p.X);
      worst_px = std::max(worst_px, (Eigen::Vector2d(u, v) - ours).norm());
    }
  }
  CHECK(keys == 9);
  CHECK(worst_px < 1e-5);
}
