#include "hal/replay/image_directory_source.hpp"

#include <catch2/catch.hpp>

#include "hal/io/file_util.hpp"
#include "tests/support/test_support.hpp"

using epitrack::Image;
namespace hal = epitrack::hal;

TEST_CASE("A frame directory replays in name order, bit-exactly, then ends", "[hal][replay]") {
  epitrack::test::TempDir dir("replay");
  std::string err;
  Image<uint8_t> img(33, 21);
  for (int i : {2, 0, 1}) {  // written out of order
    img.fill(static_cast<uint8_t>(10 * i));
    img(i, i) = 255;
    char name[16];
    std::snprintf(name, sizeof(name), "f%d.pgm",
                  i);  // (GCC 12 -Wrestrict false positive on string +)
    REQUIRE(hal::writePgm(dir.file(name), img.constView(), err));
  }
  REQUIRE(hal::writeTextAtomic(dir.file("notes.txt"), "ignored\n", err));
  auto src = hal::openFrameSource(dir.path(), {}, err);
  REQUIRE(src);
  REQUIRE(src->info().width == 33);
  REQUIRE(src->info().height == 21);
  REQUIRE(src->info().frame_count == 3);
  hal::Frame f;
  for (int i = 0; i < 3; ++i) {
    REQUIRE(src->next(f) == hal::FrameStatus::kOk);
    REQUIRE(f.index == i);
    REQUIRE(f.luma(0, 20) == 10 * i);
    REQUIRE(f.luma(i, i) == 255);
  }
  REQUIRE(src->next(f) == hal::FrameStatus::kEndOfStream);
}

TEST_CASE("A frame of another size is an error that names the file", "[hal][replay]") {
  epitrack::test::TempDir dir("replay-size");
  std::string err;
  Image<uint8_t> a(20, 10);
  a.fill(1);
  Image<uint8_t> b(21, 10);
  b.fill(2);
  REQUIRE(hal::writePgm(dir.file("000.pgm"), a.constView(), err));
  REQUIRE(hal::writePgm(dir.file("001.pgm"), b.constView(), err));
  auto src = hal::openFrameSource(dir.path(), {}, err);
  REQUIRE(src);
  hal::Frame f;
  REQUIRE(src->next(f) == hal::FrameStatus::kOk);
  REQUIRE(src->next(f) == hal::FrameStatus::kError);
  REQUIRE(src->lastError().find("001.pgm") != std::string::npos);
  REQUIRE(src->lastError().find("21x10") != std::string::npos);
}

TEST_CASE("A corrupt frame is reported as such and replay goes on", "[hal][replay]") {
  epitrack::test::TempDir dir("replay-corrupt");
  std::string err;
  Image<uint8_t> a(20, 10);
  a.fill(1);
  REQUIRE(hal::writePgm(dir.file("000.pgm"), a.constView(), err));
  REQUIRE(hal::writeTextAtomic(dir.file("001.pgm"), "P5 20 10 255\nshort", err));
  REQUIRE(hal::writePgm(dir.file("002.pgm"), a.constView(), err));
  auto src = hal::openFrameSource(dir.path(), {}, err);
  REQUIRE(src);
  hal::Frame f;
  REQUIRE(src->next(f) == hal::FrameStatus::kOk);
  REQUIRE(src->next(f) == hal::FrameStatus::kCorruptFrame);
  REQUIRE(src->lastError().find("001.pgm") != std::string::npos);
  REQUIRE(src->next(f) == hal::FrameStatus::kOk);
  REQUIRE(f.index == 2);
}

TEST_CASE("Opening a missing or empty directory gives a clear message", "[hal][replay]") {
  std::string err;
  REQUIRE_FALSE(hal::openFrameSource("/nonexistent/dir", {}, err));
  REQUIRE(err.find("/nonexistent/dir") != std::string::npos);
  epitrack::test::TempDir dir("replay-empty");
  REQUIRE_FALSE(hal::openFrameSource(dir.path(), {}, err));
  REQUIRE(err.find("no frames") != std::string::npos);
}

TEST_CASE("The real KITTI excerpt replays through the directory source", "[hal][replay][data]") {
  if (!epitrack::test::haveSharedSequence("kitti_highway_excerpt")) return;
  std::string err;
  auto src = hal::openFrameSource(epitrack::test::sharedDataDir() + "/kitti_highway_excerpt/frames",
                                  {}, err);
  REQUIRE(src);
  REQUIRE(src->info().width == 1241);
  REQUIRE(src->info().frame_count == 51);
  hal::Frame f;
  int n = 0;
  while (src->next(f) == hal::FrameStatus::kOk) ++n;
  REQUIRE(n == 51);
}
