#include "hal/io/text_formats.hpp"

#include <catch2/catch.hpp>

namespace hal = epitrack::hal;

TEST_CASE("Trajectory files parse, round-trip and reject malformed lines", "[hal][formats]") {
  const std::string text =
      "# comment\n\n0 1 2 3 0 0 0 1\n1 1.5 2 3 0 0 0.7071067811865476 0.7071067811865476\n";
  std::vector<hal::TrajectoryEntry> e;
  std::string err;
  REQUIRE(hal::parseTrajectory(text, e, err));
  REQUIRE(e.size() == 2);
  REQUIRE(e[1].position.x() == Approx(1.5));
  REQUIRE(e[1].rotation.z() == Approx(0.70710678));
  std::vector<hal::TrajectoryEntry> back;
  REQUIRE(hal::parseTrajectory(hal::formatTrajectory(e), back, err));
  REQUIRE(back.size() == 2);
  REQUIRE(back[1].t == 1.0);
  REQUIRE(back[1].rotation.w() == Approx(e[1].rotation.w()).margin(1e-9));
  REQUIRE_FALSE(hal::parseTrajectory("0 1 2 3 0 0 0\n", e, err));
  REQUIRE(err.find("line 1") != std::string::npos);
  REQUIRE_FALSE(hal::parseTrajectory("0 1 2 3 0 0 0 0\n", e, err));
  REQUIRE_FALSE(hal::parseTrajectory("0 1 2 nan 0 0 0 1\n", e, err));
  REQUIRE_FALSE(hal::parseTrajectory("0 1 2 3x 0 0 0 1\n", e, err));
}

TEST_CASE("Intrinsics files parse with and without distortion", "[hal][formats]") {
  epitrack::CameraIntrinsics k;
  std::string err;
  REQUIRE(hal::parseIntrinsics(
      "# fx fy cx cy w h\n718.856 718.856 607.19 185.21 1241 376\n# more\n", k, err));
  REQUIRE(k.fx == Approx(718.856));
  REQUIRE(k.width == 1241);
  REQUIRE_FALSE(k.hasDistortion());
  REQUIRE(hal::parseIntrinsics("600 600 351.5 287.5 704 576 -0.1 0.02", k, err));
  REQUIRE(k.k1 == Approx(-0.1));
  REQUIRE(k.k2 == Approx(0.02));
  epitrack::CameraIntrinsics back;
  REQUIRE(hal::parseIntrinsics(hal::formatIntrinsics(k), back, err));
  REQUIRE(back.k1 == Approx(-0.1));
  REQUIRE(back.cx == Approx(351.5));
  REQUIRE_FALSE(hal::parseIntrinsics("600 600 351.5 287.5 704", k, err));
  REQUIRE_FALSE(hal::parseIntrinsics("-600 600 351.5 287.5 704 576", k, err));
  REQUIRE_FALSE(hal::parseIntrinsics("600 600 351.5 287.5 704.5 576", k, err));
  REQUIRE_FALSE(hal::parseIntrinsics("# nothing\n", k, err));
}
