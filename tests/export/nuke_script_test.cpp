// camera.nk and camera.chan read back and projected with Nuke's camera model (rotation order ZXY,
// Y-up world, the camera looking down -Z; NukeLens in output_writers.hpp): on a camera with
// fx != fy and an off-centre principal point, camera.nk's Camera2 projects every point where
// cameras.tum + intrinsics.txt do (issue 25 item 5), and its keys are camera.chan's. The .chan
// alone (vertical field of view, no principal point) cannot: the test measures by how much, the
// figure docs/exports.md quotes. Nuke itself is not available to the tests (commercial).

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "hal/io/text_formats.hpp"
#include "tests/export/export_fixture.hpp"
#include "tests/support/test_support.hpp"
#include "tools/export/export_geometry.hpp"
#include "tools/export/output_writers.hpp"

using namespace epitrack::io;
using epitrack::CameraIntrinsics;
namespace et = epitrack::test;

namespace {

constexpr double kRad = std::numbers::pi / 180.0;

/// The knobs of one node of a .nk script: name -> raw text after the name (one line each, as
/// formatNukeScript writes them; a `{...}` value may hold nested braces).
using NukeNode = std::map<std::string, std::string>;

std::map<std::string, NukeNode> parseNukeScript(const std::string& text) {
  std::map<std::string, NukeNode> nodes;
  std::istringstream in(text);
  std::string line;
  std::string current;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    if (line.size() > 2 && line.substr(line.size() - 2) == " {") {
      current = line.substr(0, line.size() - 2);
      nodes[current];
      continue;
    }
    if (line == "}") {
      current.clear();
      continue;
    }
    if (current.empty() || line[0] != ' ') continue;
    const auto space = line.find(' ', 1);
    nodes[current][line.substr(1, space - 1)] =
        space == std::string::npos ? std::string() : line.substr(space + 1);
  }
  return nodes;
}

/// The three `{curve x<frame> <value> ...}` of an animated XYZ knob: frame -> value per axis.
std::vector<std::map<int, double>> parseCurves(const std::string& knob) {
  std::vector<std::map<int, double>> axes;
  std::size_t at = 0;
  while ((at = knob.find("{curve", at)) != std::string::npos) {
    const std::size_t end = knob.find('}', at);
    std::istringstream in(knob.substr(at + 6, end - at - 6));
    std::map<int, double> keys;
    std::string frame;
    double value = 0.0;
    while (in >> frame >> value) keys[std::stoi(frame.substr(1))] = value;
    axes.push_back(keys);
    at = end;
  }
  return axes;
}

double number(const NukeNode& node, const std::string& knob) {
  const auto it = node.find(knob);
  return it == node.end() ? std::nan("") : std::strtod(it->second.c_str(), nullptr);
}

/// Nuke's pinhole (NukeLens): camera-space point -> our pixel (centre of the top-left pixel).
Eigen::Vector2d nukeProject(const Eigen::Vector3d& P, double focal, double haperture, double u0,
                            double v0, double pixel_aspect, int width, int height) {
  const double ndc_x = 2.0 * focal / haperture * P.x() / -P.z() + u0;
  const double ndc_y = 2.0 * focal / haperture * P.y() / -P.z() + v0;
  const double x = (ndc_x + 1.0) * 0.5 * width;                        // from the left edge
  const double y = ndc_y * 0.5 * width * pixel_aspect + 0.5 * height;  // from the bottom edge
  return {x - 0.5, height - y - 0.5};
}

}  // namespace

TEST_CASE("camera.nk reprojects like cameras.tum in Nuke's camera model", "[export][nuke]") {
  Reconstruction rec = et::makeReconstruction(12, 5);
  rec.intrinsics.fy = 530.0;
  rec.intrinsics.cx = 347.25;
  rec.intrinsics.cy = 203.5;
  rec.fps = 25.0;
  rec.frames_dir = "/data/shot";
  for (int i = 0; i < rec.frames; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "plate.%04d.png", 1001 + i);
    rec.frame_names.emplace_back(name);
  }
  et::TempDir dir("nuke");
  std::string error;
  ExportOptions options;
  REQUIRE(writeAllOutputs(rec, dir.path(), options, error));
  CameraIntrinsics k;
  REQUIRE(epitrack::hal::readIntrinsicsFile(dir.file("intrinsics.txt"), k, error));
  std::vector<epitrack::hal::TrajectoryEntry> tum;
  REQUIRE(epitrack::hal::readTrajectoryFile(dir.file("cameras.tum"), tum, error));
  REQUIRE(tum.size() == 10);

  const auto nodes = parseNukeScript(et::readWholeFile(dir.file("camera.nk")));
  REQUIRE(nodes.count("Root") == 1);
  REQUIRE(nodes.count("Read") == 1);
  REQUIRE(nodes.count("Camera2") == 1);
  const NukeNode& root = nodes.at("Root");
  const NukeNode& read = nodes.at("Read");
  const NukeNode& cam = nodes.at("Camera2");
  // The whole clip (Nuke frame = index + nuke_frame_offset), its rate and format.
  CHECK(number(root, "first_frame") == 0);
  CHECK(number(root, "last_frame") == 11);
  CHECK(number(root, "fps") == 25);
  CHECK(root.at("format") == "\"640 480 0 0 640 480 1.06 epitrack_format\"");
  // The plate: the numbered frame files, the first at the first frame.
  CHECK(read.at("file") == "\"/data/shot/plate.%04d.png\"");
  CHECK(number(read, "first") == 1001);
  CHECK(number(read, "last") == 1012);
  CHECK(read.at("frame_mode") == "\"start at\"");
  CHECK(read.at("frame") == "\"0\"");

  CHECK(cam.at("rot_order") == "ZXY");
  const double focal = number(cam, "focal");
  const double haperture = number(cam, "haperture");
  const double vaperture = number(cam, "vaperture");
  CHECK(haperture == options.sensor_width_mm);
  std::istringstream win(cam.at("win_translate").substr(1));
  double u0 = 0.0, v0 = 0.0;
  REQUIRE(static_cast<bool>(win >> u0 >> v0));
  const double pixel_aspect = k.fy / k.fx;
  // vaperture: the film back height for the same focal, so that focal / vaperture * H = fy.
  CHECK(focal / vaperture * k.height == Approx(k.fy).epsilon(1e-8));
  const auto translate = parseCurves(cam.at("translate"));
  const auto rotate = parseCurves(cam.at("rotate"));
  REQUIRE(translate.size() == 3);
  REQUIRE(rotate.size() == 3);

  // camera.chan: the same keys.
  std::istringstream chan(et::readWholeFile(dir.file("camera.chan")));
  const Eigen::Matrix3d W = ourWorldToNukeWorld();
  double worst_nk_px = 0.0;
  double worst_chan_px = 0.0;
  double worst_key = 0.0;
  for (const auto& pose : tum) {
    const int f = static_cast<int>(pose.t) + options.nuke_frame_offset;
    REQUIRE(translate[0].count(f) == 1);
    const Eigen::Vector3d t(translate[0].at(f), translate[1].at(f), translate[2].at(f));
    const Eigen::Vector3d r(rotate[0].at(f), rotate[1].at(f), rotate[2].at(f));
    double cf = 0, vfov = 0;
    Eigen::Vector3d ct, cr;
    REQUIRE(static_cast<bool>(chan >> cf >> ct.x() >> ct.y() >> ct.z() >> cr.x() >> cr.y() >>
                              cr.z() >> vfov));
    CHECK(cf == f);
    worst_key =
        std::max({worst_key, (ct - t).cwiseAbs().maxCoeff(), (cr - r).cwiseAbs().maxCoeff()});
    const Eigen::Matrix3d R = rotationFromNukeZxy(r.x() * kRad, r.y() * kRad, r.z() * kRad);
    // A .chan-only camera: square pixels, centred, the vertical field of view of the file.
    const double chan_f = 0.5 * k.height / std::tan(0.5 * vfov * kRad);
    for (const auto& p : rec.points) {
      const Eigen::Vector3d P = R.transpose() * (W * p.X - t);
      const Eigen::Vector2d nuke =
          nukeProject(P, focal, haperture, u0, v0, pixel_aspect, k.width, k.height);
      const Eigen::Vector3d xc =
          pose.rotation.toRotationMatrix().transpose() * (p.X - pose.position);
      const Eigen::Vector2d ours(k.fx * xc.x() / xc.z() + k.cx, k.fy * xc.y() / xc.z() + k.cy);
      worst_nk_px = std::max(worst_nk_px, (nuke - ours).norm());
      const Eigen::Vector2d chan_only(chan_f * P.x() / -P.z() + 0.5 * (k.width - 1),
                                      -chan_f * P.y() / -P.z() + 0.5 * (k.height - 1));
      worst_chan_px = std::max(worst_chan_px, (chan_only - ours).norm());
    }
  }
  std::printf(
      "Nuke model, %zu frames: camera.nk worst %.2e px; camera.chan alone (fx %.0f, fy %.0f, "
      "principal point (%.2f, %.2f) on 640x480) worst %.1f px; .chan vs .nk keys %.1e\n",
      tum.size(), worst_nk_px, k.fx, k.fy, k.cx, k.cy, worst_chan_px, worst_key);
  CHECK(worst_nk_px < 1e-5);
  CHECK(worst_key < 1e-6);
  CHECK(worst_chan_px > 10.0);  // what .chan cannot carry (docs/exports.md)
}

TEST_CASE("camera.nk reads a video plate and leaves out a gapped sequence", "[export][nuke]") {
  Reconstruction rec = et::makeReconstruction(6, 0);
  rec.input_movie = "/data/clip.y4m";
  std::string nk = formatNukeScript(rec, ExportOptions{});
  CHECK(nk.find("file \"/data/clip.y4m\"") != std::string::npos);
  rec.input_movie.clear();
  rec.frames_dir = "/data/shot";
  rec.frame_names = {"a_01.png", "a_02.png", "a_04.png", "a_05.png", "a_06.png", "a_07.png"};
  nk = formatNukeScript(rec, ExportOptions{});
  CHECK(nk.find("Read {") == std::string::npos);
  CHECK(nk.find("not one consecutively numbered sequence") != std::string::npos);
}
