// Per-frame allocation of the HAL sources: after the first frames, `next` allocates nothing
// (Y4M file and pipe, V4L2 GREY/YUYV through the fake driver). MJPEG decoding allocates only
// inside libjpeg (its per-image memory pool), a fixed number of blocks per frame.
#include <catch2/catch.hpp>

#include <linux/videodev2.h>

#include "hal/frame_source.hpp"
#include "hal/io/file_util.hpp"
#include "hal/v4l2/v4l2_capture_source.hpp"
#include "tests/alloc/counting_allocator.hpp"
#include "tests/hal/fake_v4l2_driver.hpp"
#include "tests/hal/replay_test_helpers.hpp"
#include "tests/support/test_support.hpp"

using epitrack::test::AllocationScope;
namespace hal = epitrack::hal;

TEST_CASE("Y4M replay allocates nothing per frame", "[alloc][hal]") {
  epitrack::test::TempDir dir("alloc-y4m");
  const auto frames = epitrack::test::syntheticFrames(64, 48, 3);
  std::vector<epitrack::Image<uint8_t>> many;
  for (int i = 0; i < 12; ++i) {
    many.emplace_back(64, 48);
    epitrack::copyPixels(frames[static_cast<std::size_t>(i % 3)].constView(), many.back().view());
  }
  for (const char* chroma : {"420jpeg", "444p10"}) {
    const auto bytes = epitrack::test::makeY4m(many, chroma);
    std::string err;
    REQUIRE(hal::writeFileAtomic(dir.file("a.y4m"), bytes.data(), bytes.size(), err));
    auto src = hal::openFrameSource(dir.file("a.y4m"), {}, err);
    REQUIRE(src);
    hal::Frame f;
    REQUIRE(src->next(f) == hal::FrameStatus::kOk);
    AllocationScope scope;
    int n = 0;
    while (src->next(f) == hal::FrameStatus::kOk) ++n;
    CHECK(n == 11);
    CHECK(scope.count() == 0);
  }
}

TEST_CASE("V4L2 GREY and YUYV capture allocate nothing per frame", "[alloc][hal][v4l2]") {
  for (const char* format : {"grey", "yuyv"}) {
    epitrack::test::FakeV4l2Config config;
    config.formats = {V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_YUYV};
    config.sizes = {{160, 120}};
    epitrack::test::FakeV4l2Driver driver(config);
    std::string err;
    auto src =
        hal::openV4l2Source(std::string("v4l2:/dev/video0?format=") + format, driver, {}, err);
    REQUIRE(src);
    hal::Frame f;
    REQUIRE(src->next(f) == hal::FrameStatus::kOk);
    AllocationScope scope;
    for (int i = 0; i < 20; ++i) REQUIRE(src->next(f) == hal::FrameStatus::kOk);
    CHECK(scope.count() == 0);
  }
}

TEST_CASE("MJPEG decoding allocates a fixed amount per frame, all inside libjpeg",
          "[alloc][hal][mjpeg]") {
  epitrack::test::FakeV4l2Config config;
  config.formats = {V4L2_PIX_FMT_MJPEG};
  config.sizes = {{160, 120}};
  epitrack::test::FakeV4l2Driver driver(config);
  std::string err;
  auto src = hal::openV4l2Source("v4l2:/dev/video0", driver, {}, err);
  REQUIRE(src);
  hal::Frame f;
  REQUIRE(src->next(f) == hal::FrameStatus::kOk);
  AllocationScope one;
  REQUIRE(src->next(f) == hal::FrameStatus::kOk);
  const std::size_t per_frame = one.count();
  AllocationScope ten;
  for (int i = 0; i < 10; ++i) REQUIRE(src->next(f) == hal::FrameStatus::kOk);
  CHECK(ten.count() == 10 * per_frame);  // no growth: our buffers are sized at open
  std::printf("MJPEG decode: %zu allocations per frame (libjpeg pool)\n", per_frame);
}
