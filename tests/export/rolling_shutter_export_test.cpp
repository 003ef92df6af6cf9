// Issue 27: what the exports say of a rolling-shutter solve. rolling_shutter.txt carries the
// readout and every solved frame's motion over it; every format with room for a comment says
// that its poses are the middle row's; a global-shutter solve's exports are unchanged (no file,
// no note). The scene frame moves the motions with the poses.

#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "algo/geometry/pose.hpp"
#include "hal/io/file_util.hpp"
#include "hal/io/text_formats.hpp"
#include "tests/export/export_fixture.hpp"
#include "tests/support/test_support.hpp"
#include "tools/export/colmap_text.hpp"
#include "tools/export/output_writers.hpp"
#include "tools/export/reconstruction_scene_frame.hpp"

using namespace epitrack::io;
namespace et = epitrack::test;

namespace {

Reconstruction rollingShutterReconstruction() {
  Reconstruction rec = et::makeReconstruction(12, 5);
  rec.fps = 30.0;
  rec.readout_ms = 30.0;
  rec.readout_frames = 0.9;
  rec.readout_source = ReadoutSource::kGiven;
  rec.readout_reference_row = 0.5 * (rec.intrinsics.height - 1);
  for (std::size_t i = 0; i < rec.cameras.size(); ++i) {
    const double s = 0.003 * static_cast<double>(i + 1);
    rec.cameras[i].rs_angular = Eigen::Vector3d(s, -2.0 * s, 0.5 * s);
    rec.cameras[i].rs_linear = Eigen::Vector3d(-s, 0.3 * s, 3.0 * s);
  }
  return rec;
}

std::string read(const std::string& path) {
  std::string text, error;
  REQUIRE(epitrack::hal::readTextFile(path, text, error));
  return text;
}

}  // namespace

TEST_CASE("rolling_shutter.txt holds the readout and every solved frame's motion",
          "[export][rolling-shutter]") {
  const Reconstruction rec = rollingShutterReconstruction();
  std::istringstream in(formatRollingShutter(rec));
  std::string line;
  bool have_readout = false;
  std::size_t next = 0;
  int lines = 0;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream f(line);
    if (line.rfind("readout ", 0) == 0) {
      std::string word;
      double readout = 0, rows = 0, row = 0, ms = 0, fps = 0;
      f >> word >> readout >> rows >> row >> ms >> fps;
      CHECK(readout == 0.9);
      CHECK(rows == 480);
      CHECK(row == 239.5);
      CHECK(ms == 30.0);
      CHECK(fps == 30.0);
      have_readout = true;
      continue;
    }
    double t = 0;
    Eigen::Vector3d w, v;
    f >> t >> w.x() >> w.y() >> w.z() >> v.x() >> v.y() >> v.z();
    REQUIRE_FALSE(f.fail());
    while (!rec.cameras[next].solved) ++next;  // unsolved frames are left out
    const SolvedCamera& c = rec.cameras[next++];
    CHECK(t == static_cast<double>(c.frame));
    CHECK((w - c.rs_angular).norm() < 1e-12);
    CHECK((v - c.rs_linear).norm() < 1e-12);
    ++lines;
  }
  CHECK(have_readout);
  int solved = 0;
  for (const auto& c : rec.cameras) solved += c.solved ? 1 : 0;
  CHECK(lines == solved);
}

TEST_CASE("every export of a rolling-shutter solve says its poses are the middle row's",
          "[export][rolling-shutter]") {
  const Reconstruction rs = rollingShutterReconstruction();
  const Reconstruction gs = et::makeReconstruction(12, 5);
  et::TempDir dir("export-rs");
  std::string error;
  REQUIRE(writeAllOutputs(rs, dir.file("rs"), error));
  REQUIRE(writeAllOutputs(gs, dir.file("gs"), error));
  const std::string note = "every pose is the middle row's (row 239.5) of a 30 ms readout";
  for (const char* name : {"cameras.tum", "colmap/images.txt", "camera.nk", "blender_camera.py"}) {
    INFO(name);
    CHECK(read(dir.file("rs/") + name).find(note) != std::string::npos);
    CHECK(read(dir.file("gs/") + name).find("rolling shutter") == std::string::npos);
  }
  CHECK(read(dir.file("rs/points.ply")).find("comment rolling shutter") != std::string::npos);
  CHECK(read(dir.file("gs/points.ply")).find("rolling shutter") == std::string::npos);
  CHECK(std::filesystem::exists(dir.file("rs/rolling_shutter.txt")));
  CHECK_FALSE(std::filesystem::exists(dir.file("gs/rolling_shutter.txt")));
  CHECK(read(dir.file("rs/summary.json")).find("\"rolling_shutter.txt\"") != std::string::npos);
  // The notes are comments: the files read back as before.
  std::vector<epitrack::hal::TrajectoryEntry> entries;
  CHECK(epitrack::hal::parseTrajectory(read(dir.file("rs/cameras.tum")), entries, error));
  ColmapModel model;
  REQUIRE(readColmapModel(dir.file("rs/colmap"), model, error));
  CHECK(checkColmapConsistency(model, error));
  if (et::run("command -v python3 > /dev/null 2>&1") == 0)
    CHECK(et::run("python3 -m py_compile '" + dir.file("rs/blender_camera.py") + "'") == 0);
}

TEST_CASE("the scene frame moves a rolling-shutter motion with the poses",
          "[export][rolling-shutter]") {
  Reconstruction rec = rollingShutterReconstruction();
  const Reconstruction before = rec;
  epitrack::SceneFrameOptions options;
  const epitrack::SceneFrame frame = applySceneFrame(rec, options);
  const epitrack::Similarity3& S = frame.world_to_scene;
  REQUIRE(std::abs(S.scale - 1.0) + (S.R - Eigen::Matrix3d::Identity()).norm() > 1e-3);
  double worst = 0.0;
  for (std::size_t i = 0; i < rec.cameras.size(); ++i) {
    const SolvedCamera& a = before.cameras[i];
    const SolvedCamera& b = rec.cameras[i];
    for (const double tau : {-0.45, 0.3}) {
      // The row's centre and rotation, moved to the scene frame, against the scene's row pose.
      const Eigen::Vector3d centre = S.apply(a.p_wc + a.rs_linear * tau);
      const Eigen::Matrix3d R = S.R * a.R_wc * epitrack::expSo3(a.rs_angular * tau);
      worst = std::max(worst, (centre - (b.p_wc + b.rs_linear * tau)).norm());
      worst = std::max(worst, (R - b.R_wc * epitrack::expSo3(b.rs_angular * tau)).norm());
    }
  }
  CHECK(worst < 1e-12);
}
