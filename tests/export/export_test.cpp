#include <catch2/catch.hpp>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "hal/io/file_util.hpp"
#include "hal/io/text_formats.hpp"
#include "tests/export/export_fixture.hpp"
#include "tests/support/test_support.hpp"
#include "tools/export/colmap_text.hpp"
#include "tools/export/export_geometry.hpp"
#include "tools/export/output_writers.hpp"

using epitrack::CameraIntrinsics;
using namespace epitrack::io;
namespace et = epitrack::test;

namespace {

double rotationAngleDeg(const Eigen::Matrix3d& A, const Eigen::Matrix3d& B) {
  const Eigen::AngleAxisd d(A.transpose() * B);
  return std::abs(d.angle()) * 180.0 / std::numbers::pi;
}

int solvedCount(const Reconstruction& rec) {
  int n = 0;
  for (const auto& c : rec.cameras) n += c.solved ? 1 : 0;
  return n;
}

// COLMAP's camera models applied to normalized coordinates (u, v), in COLMAP's pixel convention.
Eigen::Vector2d colmapProject(const ColmapCamera& cam, const Eigen::Vector3d& xc) {
  const double u = xc.x() / xc.z();
  const double v = xc.y() / xc.z();
  const double r2 = u * u + v * v;
  const auto& p = cam.params;
  if (cam.model == "PINHOLE") return {p[0] * u + p[2], p[1] * v + p[3]};
  if (cam.model == "SIMPLE_RADIAL") {
    const double d = 1.0 + p[3] * r2;
    return {p[0] * u * d + p[1], p[0] * v * d + p[2]};
  }
  if (cam.model == "RADIAL") {
    const double d = 1.0 + p[3] * r2 + p[4] * r2 * r2;
    return {p[0] * u * d + p[1], p[0] * v * d + p[2]};
  }
  REQUIRE(cam.model == "OPENCV");
  const double d = 1.0 + p[4] * r2 + p[5] * r2 * r2;  // p1 = p2 = 0 written
  return {p[0] * u * d + p[2], p[1] * v * d + p[3]};
}

bool haveCommand(const std::string& name) {
  return et::run("command -v " + name + " > /dev/null 2>&1") == 0;
}

}  // namespace

TEST_CASE("writeAllOutputs writes every file of the contract", "[export]") {
  const Reconstruction rec = et::makeReconstruction();
  et::TempDir dir("export");
  std::string error;
  REQUIRE(writeAllOutputs(rec, dir.path() + "/out", error));
  for (const char* name :
       {"cameras.tum", "intrinsics.txt", "points.ply", "summary.json", "colmap/cameras.txt",
        "colmap/images.txt", "colmap/points3D.txt", "blender_camera.py", "camera.chan"}) {
    std::string text;
    INFO(name);
    REQUIRE(epitrack::hal::readTextFile(dir.path() + "/out/" + std::string(name), text, error));
    CHECK(!text.empty());
  }
  // No temporary file left behind.
  CHECK(et::run("ls -a '" + dir.path() + "/out' '" + dir.path() +
                "/out/colmap' | grep -q '[.]tmp-'") == 1);
}

TEST_CASE("cameras.tum holds T_wc of the solved frames only", "[export]") {
  Reconstruction rec = et::makeReconstruction(12, 5);
  std::vector<epitrack::hal::TrajectoryEntry> entries;
  std::string error;
  REQUIRE(epitrack::hal::parseTrajectory(formatCamerasTum(rec), entries, error));
  REQUIRE(static_cast<int>(entries.size()) == solvedCount(rec));
  std::size_t e = 0;
  for (const auto& c : rec.cameras) {
    if (!c.solved) continue;
    CHECK(entries[e].t == static_cast<double>(c.frame));
    CHECK((entries[e].position - c.p_wc).norm() < 1e-8);
    CHECK(rotationAngleDeg(entries[e].rotation.toRotationMatrix(), c.R_wc) < 1e-6);
    ++e;
  }
  rec.has_timestamps = true;
  REQUIRE(epitrack::hal::parseTrajectory(formatCamerasTum(rec), entries, error));
  CHECK(entries[1].t == Approx(0.04));
}

TEST_CASE("intrinsics.txt parses back", "[export]") {
  const Reconstruction rec = et::makeReconstruction(4, 0, -0.12, 0.03);
  CameraIntrinsics k;
  std::string error;
  REQUIRE(epitrack::hal::parseIntrinsics(formatIntrinsicsFile(rec), k, error));
  CHECK(k.fx == 500.0);
  CHECK(k.cx == 319.5);
  CHECK(k.width == 640);
  CHECK(k.k1 == Approx(-0.12));
  CHECK(k.k2 == Approx(0.03));
}

TEST_CASE("points.ply is binary little-endian x y z + gray as rgb", "[export]") {
  Reconstruction rec = et::makeReconstruction();
  rec.points[3].X.x() = std::numeric_limits<double>::quiet_NaN();  // skipped
  const std::vector<uint8_t> ply = formatPointsPly(rec);
  const std::string head(ply.begin(), ply.begin() + 400);
  const auto end = head.find("end_header\n");
  REQUIRE(end != std::string::npos);
  CHECK(head.rfind("ply\nformat binary_little_endian 1.0\n", 0) == 0);
  const std::size_t count = rec.points.size() - 1;
  CHECK(head.find("element vertex " + std::to_string(count) + "\n") != std::string::npos);
  const std::size_t body = end + std::strlen("end_header\n");
  REQUIRE(ply.size() == body + count * 15);
  std::size_t v = 0;
  for (std::size_t i = 0; i < rec.points.size(); ++i) {
    if (i == 3) continue;
    const uint8_t* p = ply.data() + body + v * 15;
    for (int a = 0; a < 3; ++a) {
      uint32_t bits = 0;
      for (int b = 0; b < 4; ++b) bits |= static_cast<uint32_t>(p[4 * a + b]) << (8 * b);
      float f = 0.0F;
      std::memcpy(&f, &bits, 4);
      CHECK(f == static_cast<float>(rec.points[i].X[a]));
    }
    CHECK(p[12] == rec.points[i].gray);
    CHECK(p[13] == rec.points[i].gray);
    CHECK(p[14] == rec.points[i].gray);
    ++v;
  }
}

TEST_CASE("summary.json has the contract fields and never NaN", "[export]") {
  Reconstruction rec = et::makeReconstruction();
  rec.cameras[2].mean_reproj_px = std::numeric_limits<double>::quiet_NaN();
  rec.seconds.stages.emplace_back("weird \"stage\"\n", std::numeric_limits<double>::infinity());
  rec.focal_estimates.push_back({0, 8, 501.5, true});
  rec.focal_estimates.push_back({2, 10, std::numeric_limits<double>::quiet_NaN(), false});
  const std::string json = formatSummaryJson(rec);
  for (const char* key :
       {"\"frames\": 12", "\"solved_frames\": 10", "\"focal_px\": 500",
        "\"focal_source\": "
        "\"self-calibrated\"",
        "\"focal_observable\": true", "\"motion\": \"general\"",
        "\"mean_reproj_px\": ", "\"median_reproj_px\": ", "\"points\": 25", "\"status\": \"ok\"",
        "\"seconds\": {", "\"total\": 0.75", "\"tracking\": 0.5"}) {
    INFO(key);
    CHECK(json.find(key) != std::string::npos);
  }
  CHECK(json.find("nan") == std::string::npos);
  CHECK(json.find("inf") == std::string::npos);
  CHECK(json.find("\"weird \\\"stage\\\"\\n\": null") != std::string::npos);
  // Residuals 0.1 * (id % 5) over ids 3, 5, ..., 51: mean and median from the observations.
  double mean_px = 0.0;
  double median_px = 0.0;
  reprojectionStatistics(rec, mean_px, median_px);
  CHECK(mean_px == Approx(0.2 * 5.0 / 5.0 * 1.0).epsilon(0.05));
  CHECK(median_px == Approx(0.2));
}

TEST_CASE("summary.json with NaN and infinite values parses with python3's JSON parser",
          "[export]") {
  // Its own test case: the skip (python3 missing) comes before anything is asserted.
  if (!haveCommand("python3")) {
    std::printf("EPITRACK-SKIP: python3 missing, summary.json not validated by a JSON parser\n");
    return;
  }
  Reconstruction rec = et::makeReconstruction();
  rec.cameras[2].mean_reproj_px = std::numeric_limits<double>::quiet_NaN();
  rec.seconds.stages.emplace_back("weird \"stage\"\n", std::numeric_limits<double>::infinity());
  rec.focal_estimates.push_back({2, 10, std::numeric_limits<double>::quiet_NaN(), false});
  et::TempDir dir("json");
  std::string error;
  REQUIRE(epitrack::hal::writeTextAtomic(dir.file("summary.json"), formatSummaryJson(rec), error));
  CHECK(et::run("python3 -c 'import json,sys; json.load(open(sys.argv[1]))' '" +
                dir.file("summary.json") + "'") == 0);
}

TEST_CASE("COLMAP text model parses back, consistent and reprojecting", "[export]") {
  struct Case {
    double k1, k2;
    const char* model;
  };
  for (const Case& cs :
       {Case{0.0, 0.0, "PINHOLE"}, Case{-0.1, 0.0, "SIMPLE_RADIAL"}, Case{-0.1, 0.02, "RADIAL"}}) {
    INFO(cs.model);
    Reconstruction rec = et::makeReconstruction(12, 5, cs.k1, cs.k2);
    // Observations of an unsolved frame and of a missing point must be dropped.
    rec.observations.push_back({4, 3, 10.0, 10.0, 0.0});
    rec.observations.push_back({0, 9999, 10.0, 10.0, 0.0});
    rec.frame_names.assign(3, "");
    rec.frame_names[1] = "custom_name.jpg";
    et::TempDir dir("colmap");
    std::string error;
    REQUIRE(writeAllOutputs(rec, dir.path(), error));
    ColmapModel model;
    REQUIRE(readColmapModel(dir.path() + "/colmap", model, error));
    INFO(error);
    REQUIRE(checkColmapConsistency(model, error));
    REQUIRE(model.cameras.size() == 1);
    CHECK(model.cameras[0].model == cs.model);
    CHECK(model.cameras[0].width == 640);
    CHECK(model.cameras[0].height == 480);
    REQUIRE(static_cast<int>(model.images.size()) == solvedCount(rec));
    REQUIRE(model.points.size() == rec.points.size());
    std::map<int64_t, Eigen::Vector3d> points;
    for (const auto& p : model.points) points[p.id] = p.X;
    for (const auto& p : rec.points) {
      REQUIRE(points.count(p.id) == 1);
      CHECK((points[p.id] - p.X).norm() < 1e-9);
    }
    std::size_t i = 0;
    double max_px = 0.0;
    for (const auto& c : rec.cameras) {
      if (!c.solved) continue;
      const ColmapImage& im = model.images[i++];
      CHECK(im.id == c.frame + 1);
      CHECK(im.name ==
            (c.frame == 1 ? std::string("custom_name.jpg")
                          : (c.frame < 10 ? "00000" : "0000") + std::to_string(c.frame) + ".png"));
      const Eigen::Matrix3d R_cw = im.q_cw.normalized().toRotationMatrix();
      CHECK(rotationAngleDeg(R_cw.transpose(), c.R_wc) < 1e-7);
      CHECK((-R_cw.transpose() * im.t_cw - c.p_wc).norm() < 1e-8);
      CHECK(im.points.size() == rec.points.size());
      for (const auto& p2 : im.points) {
        const Eigen::Vector2d xy =
            colmapProject(model.cameras[0], R_cw * points[p2.point3d_id] + im.t_cw);
        max_px = std::max(max_px, (xy - Eigen::Vector2d(p2.x, p2.y)).norm());
      }
    }
    CHECK(max_px < 1e-5);  // COLMAP's own model reproduces our observations (+0.5 px origin)
    // Mean track length: every point in every solved frame.
    for (const auto& p : model.points) CHECK(static_cast<int>(p.track.size()) == solvedCount(rec));
  }
}

TEST_CASE("COLMAP export keeps tracks of length >= 2 and one observation per image", "[export]") {
  Reconstruction rec = et::makeReconstruction(6, 0);
  ScenePoint lonely;  // seen in one frame only: COLMAP's bundle adjuster would assert
  lonely.id = 1000;
  lonely.X = Eigen::Vector3d(0.1, 0.2, 0.3);
  rec.points.push_back(lonely);
  rec.observations.push_back({2, 1000, 100.0, 100.0, 0.0});
  rec.observations.push_back({1, 1000, 100.0, 100.0, 0.0});          // frame 1 below
  rec.observations.push_back({3, rec.points[0].id, 5.0, 5.0, 0.0});  // repeated in frame 3
  rec.cameras[1].solved = false;
  ColmapModel model;
  std::string error;
  REQUIRE(parseColmapImages(formatColmapImages(rec, ExportOptions{}), model.images, error));
  REQUIRE(parseColmapPoints3D(formatColmapPoints3D(rec), model.points, error));
  REQUIRE(parseColmapCameras(formatColmapCameras(rec), model.cameras, error));
  REQUIRE(checkColmapConsistency(model, error));
  CHECK(model.points.size() == rec.points.size() - 1);
  for (const auto& p : model.points) {
    CHECK(p.id != 1000);
    CHECK(p.track.size() == 5);
  }
  for (const auto& im : model.images) CHECK(im.points.size() == rec.points.size() - 1);
}

TEST_CASE("COLMAP uses OPENCV for non-square pixels with distortion", "[export]") {
  Reconstruction rec = et::makeReconstruction(3, 0, 0.05, 0.0);
  rec.intrinsics.fy = 510.0;
  std::vector<ColmapCamera> cams;
  std::string error;
  REQUIRE(parseColmapCameras(formatColmapCameras(rec), cams, error));
  REQUIRE(cams.size() == 1);
  CHECK(cams[0].model == "OPENCV");
  REQUIRE(cams[0].params.size() == 8);
  CHECK(cams[0].params[1] == 510.0);
  CHECK(cams[0].params[2] == 320.0);  // cx + 0.5
}

TEST_CASE("the COLMAP consistency check catches broken references", "[export]") {
  const Reconstruction rec = et::makeReconstruction(6, 0);
  ColmapModel model;
  std::string error;
  REQUIRE(parseColmapCameras(formatColmapCameras(rec), model.cameras, error));
  REQUIRE(parseColmapImages(formatColmapImages(rec, ExportOptions{}), model.images, error));
  REQUIRE(parseColmapPoints3D(formatColmapPoints3D(rec), model.points, error));
  REQUIRE(checkColmapConsistency(model, error));
  ColmapModel broken = model;
  broken.points[0].track[0].second += 1;
  CHECK_FALSE(checkColmapConsistency(broken, error));
  broken = model;
  broken.images[0].points[0].point3d_id = broken.points[1].id;
  CHECK_FALSE(checkColmapConsistency(broken, error));
  broken = model;
  broken.images[1].camera_id = 7;
  CHECK_FALSE(checkColmapConsistency(broken, error));
}

TEST_CASE("camera.chan angles give back R_wc in Nuke's conventions", "[export]") {
  const Reconstruction rec = et::makeReconstruction(12, 5);
  const std::string chan = formatNukeChan(rec, ExportOptions{});
  std::istringstream in(chan);
  const Eigen::Matrix3d W = ourWorldToNukeWorld();
  const double vfov = 2.0 * std::atan(240.0 / 500.0) * 180.0 / std::numbers::pi;
  std::size_t lines = 0;
  double worst_deg = 0.0;
  for (const auto& c : rec.cameras) {
    if (!c.solved) continue;
    double f = 0, tx = 0, ty = 0, tz = 0, rx = 0, ry = 0, rz = 0, fov = 0;
    REQUIRE(static_cast<bool>(in >> f >> tx >> ty >> tz >> rx >> ry >> rz >> fov));
    ++lines;
    CHECK(f == static_cast<double>(c.frame));
    // Nuke's world is Y up: our (x, y, z) is (x, z, -y) there.
    CHECK((Eigen::Vector3d(tx, -tz, ty) - c.p_wc).norm() < 1e-8);
    constexpr double kRad = std::numbers::pi / 180.0;
    const Eigen::Matrix3d R_nuke =
        rotationY(ry * kRad) * rotationX(rx * kRad) * rotationZ(rz * kRad);
    // Back to our camera convention: undo the world rotation and the GL camera axes.
    const Eigen::Matrix3d R_wc = W.transpose() * R_nuke * cameraToGlAxes();
    worst_deg = std::max(worst_deg, rotationAngleDeg(R_wc, c.R_wc));
    // The Nuke camera looks down its -Z: that is our optical axis.
    CHECK((R_nuke * Eigen::Vector3d(0, 0, -1) - W * c.R_wc.col(2)).norm() < 1e-7);
    CHECK(fov == Approx(vfov).epsilon(1e-9));
  }
  CHECK(worst_deg < 1e-6);
  CHECK(lines == static_cast<std::size_t>(solvedCount(rec)));
}

TEST_CASE("camera.chan angles are continuous over a full turn", "[export]") {
  const Reconstruction rec = et::makeReconstruction(60, 0);  // 0.15 rad per frame: 8.9 rad
  std::istringstream in(formatNukeChan(rec, ExportOptions{}));
  const Eigen::Matrix3d W = ourWorldToNukeWorld();
  constexpr double kRad = std::numbers::pi / 180.0;
  Eigen::Vector3d previous = Eigen::Vector3d::Zero();
  double largest_step = 0.0;
  double worst_deg = 0.0;
  for (const auto& c : rec.cameras) {
    double f = 0, tx = 0, ty = 0, tz = 0, fov = 0;
    Eigen::Vector3d r;
    REQUIRE(static_cast<bool>(in >> f >> tx >> ty >> tz >> r.x() >> r.y() >> r.z() >> fov));
    if (c.frame > 0) largest_step = std::max(largest_step, (r - previous).cwiseAbs().maxCoeff());
    previous = r;
    const Eigen::Matrix3d R_nuke = rotationFromNukeZxy(r.x() * kRad, r.y() * kRad, r.z() * kRad);
    worst_deg =
        std::max(worst_deg, rotationAngleDeg(W.transpose() * R_nuke * cameraToGlAxes(), c.R_wc));
  }
  CHECK(largest_step < 15.0);             // about 8.6 degrees of yaw per frame
  CHECK(std::abs(previous.y()) > 360.0);  // kept winding instead of wrapping
  CHECK(worst_deg < 1e-6);
}

TEST_CASE("Nuke ZXY angles round-trip including the gimbal lock", "[export]") {
  constexpr double kPi = std::numbers::pi;
  for (int i = 0; i < 200; ++i) {
    const double rx = -kPi / 2 + kPi * static_cast<double>((i * 37) % 101) / 100.0;
    const double ry = -kPi + 2 * kPi * static_cast<double>((i * 53) % 97) / 97.0;
    const double rz = -kPi + 2 * kPi * static_cast<double>((i * 29) % 89) / 89.0;
    const Eigen::Matrix3d R = rotationFromNukeZxy(rx, ry, rz);
    const Eigen::Vector3d a = nukeZxyFromRotation(R);
    CHECK((rotationFromNukeZxy(a.x(), a.y(), a.z()) - R).norm() < 1e-7);
  }
}

TEST_CASE("blender_camera.py compiles with python3", "[export]") {
  if (!haveCommand("python3")) {
    std::printf("EPITRACK-SKIP: python3 missing, blender_camera.py not compiled\n");
    return;
  }
  const Reconstruction rec = et::makeReconstruction();
  et::TempDir dir("blender");
  std::string error;
  REQUIRE(writeAllOutputs(rec, dir.path(), error));
  CHECK(et::run("python3 -m py_compile '" + dir.file("blender_camera.py") + "'") == 0);
}

TEST_CASE("writeAllOutputs of a large 340-frame solve is consistent", "[export]") {
  // Time is printed, not asserted (speed belongs to benchmarks). 340 frames x 25 points + 3000
  // extra points each seen in 40 frames: ~130k observations.
  Reconstruction rec = et::makeReconstruction(340, 0);
  for (int i = 0; i < 3000; ++i) {
    ScenePoint p;
    p.id = 10000 + i;
    p.X = Eigen::Vector3d(0.001 * i, 0.5, 0.2);
    rec.points.push_back(p);
    for (int f = 0; f < 40; ++f) {
      rec.observations.push_back({(i + f) % 340, p.id, 100.0 + f, 50.0 + 0.01 * i, 0.3});
    }
  }
  et::TempDir dir("export-speed");
  std::string error;
  const auto start = std::chrono::steady_clock::now();
  REQUIRE(writeAllOutputs(rec, dir.path(), error));
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("writeAllOutputs: %zu cameras, %zu points, %zu observations in %.3f s\n",
              rec.cameras.size(), rec.points.size(), rec.observations.size(), seconds);
  ColmapModel model;
  REQUIRE(readColmapModel(dir.path() + "/colmap", model, error));
  CHECK(checkColmapConsistency(model, error));
  CHECK(model.points.size() == rec.points.size());
}

TEST_CASE("writeAllOutputs reports an unwritable directory", "[export]") {
  const Reconstruction rec = et::makeReconstruction(3, 0);
  et::TempDir dir("export-fail");
  std::string error;
  REQUIRE(epitrack::hal::writeTextAtomic(dir.file("a_file"), "x", error));
  CHECK_FALSE(writeAllOutputs(rec, dir.file("a_file") + "/out", error));
  CHECK(error.find("a_file") != std::string::npos);
}
