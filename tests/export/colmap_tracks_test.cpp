// COLMAP model and epitrack-solve's own accounting agree: the tracks hold exactly the
// observations behind the ERROR column and summary.json (the outliers the summary leaves out are
// left out of the tracks too, issue 25 item 4); `colmap model_analyzer` counts what summary.json
// says; images.txt names the input frame files (item 3), so that `colmap image_undistorter` finds
// every image. The tests that run COLMAP skip visibly without it.

#include <catch2/catch.hpp>

#include <dirent.h>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "tests/export/export_fixture.hpp"
#include "tests/support/test_support.hpp"
#include "tools/export/colmap_text.hpp"
#include "tools/export/output_writers.hpp"
#include "tools/export/reprojection_errors.hpp"

using namespace epitrack::io;
namespace et = epitrack::test;

namespace {

constexpr double kOutlierPx = 2.0;

/// The fixture with every 7th observation moved 6 px off (outliers at a 2 px threshold) and the
/// residuals computed as epitrack-solve computes them.
Reconstruction reconstructionWithOutliers() {
  Reconstruction rec = et::makeReconstruction(12, 5);
  for (std::size_t i = 0; i < rec.observations.size(); i += 7) rec.observations[i].x += 6.0;
  computeReprojectionErrors(rec, kOutlierPx);
  return rec;
}

bool haveColmap() {
  if (et::run("command -v colmap > /dev/null 2>&1") == 0) return true;
  std::printf(
      "EPITRACK-SKIP: colmap not installed (tools/deps.sh clients), COLMAP itself not run\n");
  return false;
}

/// "Name: value" lines of `colmap model_analyzer` (e.g. "Observations: 10848").
std::map<std::string, double> analyzerValues(const std::string& log) {
  std::map<std::string, double> values;
  std::istringstream in(log);
  std::string line;
  while (std::getline(in, line)) {
    const auto colon = line.find(": ");
    if (colon == std::string::npos) continue;
    std::size_t start = line.find_last_of(']', colon);  // after a glog prefix, if any
    start = start == std::string::npos ? 0 : start + 1;
    while (start < colon && line[start] == ' ') ++start;
    values[line.substr(start, colon - start)] = std::strtod(line.c_str() + colon + 2, nullptr);
  }
  return values;
}

/// The `"colmap": {...}` object of summary.json.
std::string colmapObject(const std::string& summary) {
  const auto at = summary.find("\"colmap\"");
  if (at == std::string::npos) return {};
  return summary.substr(at, summary.find('}', at) - at);
}

/// A solve of a rendered orbit whose frames are named shot_0100.pgm... (not the frame index):
/// DIR/frames and DIR/out.
void solveRenamedClip(const et::TempDir& dir) {
  const std::string clip = dir.file("clip");
  REQUIRE(et::run(et::binaryPath("tools/synth/epitrack-synth") +
                  " --scene orbit --frames 30 --size 320x240 --focal 300 --target-wander 0.5"
                  " --quiet --out '" +
                  clip + "'") == 0);
  REQUIRE(et::run("mkdir -p '" + dir.file("frames") + "' && cd '" + clip +
                  "/frames' && for f in *.pgm; do n=${f%.pgm}; mv \"$f\" \"" + dir.file("frames") +
                  "/shot_$(printf %04d $(expr $n + 100)).pgm\"; done") == 0);
  REQUIRE(et::run(et::binaryPath("tools/solve/epitrack-solve") + " '" + dir.file("frames") +
                  "' --out '" + dir.file("out") + "' --intrinsics '" + clip +
                  "/intrinsics.txt' --quiet") == 0);
}

}  // namespace

TEST_CASE("COLMAP tracks hold exactly the observations behind ERROR and summary.json",
          "[export][colmap]") {
  const Reconstruction rec = reconstructionWithOutliers();
  int64_t inliers = 0, outliers = 0;
  for (const auto& o : rec.observations) {
    outliers += o.outlier ? 1 : 0;
    inliers += !o.outlier && std::isfinite(o.residual_px) ? 1 : 0;  // unsolved frames: NaN
  }
  REQUIRE(outliers > 20);
  et::TempDir dir("colmap-tracks");
  std::string error;
  REQUIRE(writeAllOutputs(rec, dir.path(), error));
  ColmapModel model;
  REQUIRE(readColmapModel(dir.file("colmap"), model, error));
  REQUIRE(checkColmapConsistency(model, error));

  std::map<int64_t, const ColmapImage*> images;
  for (const auto& im : model.images) images[im.id] = &im;
  std::map<int64_t, const ScenePoint*> points;
  for (const auto& p : rec.points) points[p.id] = &p;
  int64_t observations = 0;
  double worst_residual = 0.0;
  double worst_error_difference = 0.0;
  for (const ColmapPoint3D& p : model.points) {
    REQUIRE(points.count(p.id) == 1);
    double sum = 0.0;
    for (const auto& [image_id, idx] : p.track) {
      const ColmapImage& im = *images.at(image_id);
      const SolvedCamera& camera = rec.cameras[static_cast<std::size_t>(image_id - 1)];
      Eigen::Vector2d projected;
      REQUIRE(projectPoint(rec.intrinsics, camera, p.X, projected));
      const ColmapPoint2D& xy = im.points[static_cast<std::size_t>(idx)];
      const double r = (projected - Eigen::Vector2d(xy.x - 0.5, xy.y - 0.5)).norm();
      worst_residual = std::max(worst_residual, r);
      sum += r;
    }
    observations += static_cast<int64_t>(p.track.size());
    worst_error_difference = std::max(
        worst_error_difference, std::abs(sum / static_cast<double>(p.track.size()) - p.error));
  }
  // No outlier in a track, and ERROR is the mean over exactly the track.
  CHECK(worst_residual <= kOutlierPx);
  CHECK(worst_error_difference < 1e-5);
  CHECK(observations == inliers);
  const std::string summary = et::readWholeFile(dir.file("summary.json"));
  CHECK(et::jsonNumber(summary, "outlier_observations") == static_cast<double>(outliers));
  const std::string colmap = colmapObject(summary);
  CHECK(et::jsonNumber(colmap, "observations") == static_cast<double>(observations));
  CHECK(et::jsonNumber(colmap, "points") == static_cast<double>(model.points.size()));
  CHECK(et::jsonNumber(colmap, "images") == static_cast<double>(model.images.size()));
}

TEST_CASE("colmap model_analyzer counts what summary.json says", "[export][colmap]") {
  if (!haveColmap()) return;
  const Reconstruction rec = reconstructionWithOutliers();
  et::TempDir dir("colmap-analyzer");
  std::string error;
  REQUIRE(writeAllOutputs(rec, dir.path(), error));
  REQUIRE(et::run("colmap model_analyzer --path '" + dir.file("colmap") + "' > '" +
                  dir.file("analyzer.log") + "' 2>&1") == 0);
  const auto values = analyzerValues(et::readWholeFile(dir.file("analyzer.log")));
  const std::string summary = et::readWholeFile(dir.file("summary.json"));
  const std::string colmap = colmapObject(summary);
  REQUIRE(values.count("Registered images") == 1);
  REQUIRE(values.count("Points") == 1);
  REQUIRE(values.count("Observations") == 1);
  REQUIRE(values.count("Mean reprojection error") == 1);
  CHECK(values.at("Registered images") == et::jsonNumber(summary, "solved_frames"));
  CHECK(values.at("Registered images") == et::jsonNumber(colmap, "images"));
  CHECK(values.at("Points") == et::jsonNumber(colmap, "points"));
  CHECK(values.at("Observations") == et::jsonNumber(colmap, "observations"));
  CHECK(values.at("Mean reprojection error") ==
        Approx(et::jsonNumber(colmap, "mean_error_px")).margin(1e-5));
}

TEST_CASE("epitrack-solve names the COLMAP images after the input frame files",
          "[export][colmap][cli]") {
  et::TempDir dir("colmap-names");
  solveRenamedClip(dir);
  ColmapModel model;
  std::string error;
  REQUIRE(readColmapModel(dir.file("out/colmap"), model, error));
  REQUIRE(model.images.size() >= 25);
  for (const ColmapImage& im : model.images) {
    char expected[32];
    std::snprintf(expected, sizeof(expected), "shot_%04d.pgm", static_cast<int>(im.id - 1 + 100));
    CHECK(im.name == expected);
  }
}

TEST_CASE("colmap image_undistorter finds and writes every image of a solve's export",
          "[export][colmap][cli]") {
  if (!haveColmap()) return;
  et::TempDir dir("colmap-undistort");
  solveRenamedClip(dir);
  ColmapModel model;
  std::string error;
  REQUIRE(readColmapModel(dir.file("out/colmap"), model, error));
  // COLMAP exits 0 even when it cannot read an image: the log and the written files tell.
  REQUIRE(et::run("colmap image_undistorter --image_path '" + dir.file("frames") +
                  "' --input_path '" + dir.file("out/colmap") + "' --output_path '" +
                  dir.file("undistorted") + "' > '" + dir.file("undistort.log") + "' 2>&1") == 0);
  const std::string log = et::readWholeFile(dir.file("undistort.log"));
  CHECK(log.find("Cannot read") == std::string::npos);
  int written = 0;
  for (const ColmapImage& im : model.images) {
    std::ifstream f(dir.file("undistorted/images/" + im.name));
    written += f.good() ? 1 : 0;
  }
  CHECK(written == static_cast<int>(model.images.size()));
}
