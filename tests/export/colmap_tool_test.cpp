// The COLMAP export read by COLMAP itself (skipped visibly when the `colmap` command is absent):
// the model converts to COLMAP's binary format and back unchanged, and COLMAP's bundle adjuster,
// run on exact observations with the intrinsics fixed, leaves every pose and point where it was,
// which it would not if a convention (pixel origin, quaternion order, pose direction, distortion
// model) disagreed with COLMAP's.

#include <catch2/catch.hpp>

#include <map>
#include <string>

#include <Eigen/Geometry>

#include "tests/export/export_fixture.hpp"
#include "tests/support/test_support.hpp"
#include "tools/export/colmap_text.hpp"
#include "tools/export/output_writers.hpp"

using namespace epitrack::io;
namespace et = epitrack::test;

namespace {

bool haveColmap() {
  if (et::run("command -v colmap > /dev/null 2>&1") == 0) return true;
  std::printf(
      "EPITRACK-SKIP: colmap not installed (tools/deps.sh clients), COLMAP itself not run\n");
  return false;
}

struct Difference {
  double pose = 0.0;   // largest camera centre / rotation difference
  double point = 0.0;  // largest point difference
  bool tracks_equal = true;
};

Difference compare(const ColmapModel& a, const ColmapModel& b) {
  Difference d;
  std::map<int64_t, const ColmapImage*> images;
  for (const auto& im : b.images) images[im.id] = &im;
  for (const auto& im : a.images) {
    REQUIRE(images.count(im.id) == 1);
    const ColmapImage& other = *images[im.id];
    d.pose = std::max(d.pose, (im.t_cw - other.t_cw).norm());
    d.pose = std::max(d.pose, im.q_cw.angularDistance(other.q_cw));
    d.tracks_equal =
        d.tracks_equal && im.points.size() == other.points.size() && im.name == other.name;
  }
  std::map<int64_t, const ColmapPoint3D*> points;
  for (const auto& p : b.points) points[p.id] = &p;
  for (const auto& p : a.points) {
    REQUIRE(points.count(p.id) == 1);
    d.point = std::max(d.point, (p.X - points[p.id]->X).norm());
    d.tracks_equal = d.tracks_equal && p.track.size() == points[p.id]->track.size();
  }
  return d;
}

}  // namespace

TEST_CASE("COLMAP reads, converts and bundle-adjusts the export unchanged", "[export][colmap]") {
  if (!haveColmap()) return;
  for (const double k1 : {0.0, -0.08}) {
    INFO("k1 " << k1);
    const Reconstruction rec = et::makeReconstruction(10, 4, k1, k1 != 0.0 ? 0.01 : 0.0);
    et::TempDir dir("colmap-tool");
    std::string error;
    REQUIRE(writeAllOutputs(rec, dir.path(), error));
    ColmapModel ours;
    REQUIRE(readColmapModel(dir.path() + "/colmap", ours, error));
    const std::string quiet = " > '" + dir.file("colmap.log") + "' 2>&1";
    // Text -> binary -> text through COLMAP.
    REQUIRE(et::run("mkdir -p '" + dir.file("bin") + "' '" + dir.file("txt") + "'") == 0);
    REQUIRE(et::run("colmap model_converter --input_path '" + dir.path() +
                    "/colmap' --output_path '" + dir.file("bin") + "' --output_type BIN" + quiet) ==
            0);
    REQUIRE(et::run("colmap model_converter --input_path '" + dir.file("bin") +
                    "' --output_path '" + dir.file("txt") + "' --output_type TXT" + quiet) == 0);
    ColmapModel converted;
    REQUIRE(readColmapModel(dir.file("txt"), converted, error));
    REQUIRE(checkColmapConsistency(converted, error));
    REQUIRE(converted.images.size() == ours.images.size());
    REQUIRE(converted.points.size() == ours.points.size());
    Difference d = compare(ours, converted);
    CHECK(d.pose < 1e-9);
    CHECK(d.point < 1e-9);
    CHECK(d.tracks_equal);
    CHECK(converted.cameras[0].model == ours.cameras[0].model);

    // COLMAP's bundle adjustment on exact observations: nothing may move.
    REQUIRE(et::run("mkdir -p '" + dir.file("ba") + "'") == 0);
    REQUIRE(et::run("colmap bundle_adjuster --input_path '" + dir.file("bin") +
                    "' --output_path '" + dir.file("ba") +
                    "' --BundleAdjustment.refine_focal_length 0"
                    " --BundleAdjustment.refine_principal_point 0"
                    " --BundleAdjustment.refine_extra_params 0" +
                    quiet) == 0);
    REQUIRE(et::run("colmap model_converter --input_path '" + dir.file("ba") + "' --output_path '" +
                    dir.file("txt") + "' --output_type TXT" + quiet) == 0);
    ColmapModel adjusted;
    REQUIRE(readColmapModel(dir.file("txt"), adjusted, error));
    d = compare(ours, adjusted);
    CHECK(d.pose < 1e-5);
    CHECK(d.point < 1e-5);
  }
}
