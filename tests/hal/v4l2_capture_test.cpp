// The production V4L2 capture code on the fake driver: the full streaming path for GREY, YUYV and
// MJPEG at several sizes, negotiation, and every injected fault with its promised status, with
// the buffers unmapped and the device closed afterwards.
#include "hal/v4l2/v4l2_capture_source.hpp"

#include <catch2/catch.hpp>

#include <linux/videodev2.h>

#include "hal/io/image_codec.hpp"
#include "tests/hal/fake_v4l2_driver.hpp"
#include "tests/hal/replay_test_helpers.hpp"

using epitrack::Image;
using epitrack::test::FakeV4l2Config;
using epitrack::test::FakeV4l2Driver;
using epitrack::test::sameImage;
namespace hal = epitrack::hal;

namespace {

FakeV4l2Config allFormats() {
  FakeV4l2Config c;
  c.formats = {V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_GREY};
  c.sizes = {{160, 120}, {320, 240}, {96, 64}};
  return c;
}

std::unique_ptr<hal::FrameSource> open(FakeV4l2Driver& driver, const std::string& input,
                                       std::string& error) {
  return hal::openV4l2Source(input, driver, {}, error);
}

/// The driver has everything back: device closed, nothing mapped, not streaming, no buffers.
void requireReleased(const FakeV4l2Driver& driver) {
  CHECK(driver.openFds() == 0);
  CHECK(driver.mappedBuffers() == 0);
  CHECK_FALSE(driver.streaming());
  CHECK(driver.allocatedBuffers() == 0);
  CHECK(driver.protocolErrors() == 0);
}

}  // namespace

TEST_CASE("V4L2 capture runs the full streaming path for each format and size", "[hal][v4l2]") {
  struct Case {
    const char* format;
    uint32_t fourcc;
    int width;
    int height;
    int padding;
  };
  const Case cases[] = {
      {"grey", V4L2_PIX_FMT_GREY, 160, 120, 0},   {"grey", V4L2_PIX_FMT_GREY, 96, 64, 32},
      {"yuyv", V4L2_PIX_FMT_YUYV, 320, 240, 0},   {"yuyv", V4L2_PIX_FMT_YUYV, 96, 64, 16},
      {"mjpeg", V4L2_PIX_FMT_MJPEG, 160, 120, 0}, {"mjpeg", V4L2_PIX_FMT_MJPEG, 320, 240, 0},
  };
  for (const Case& c : cases) {
    CAPTURE(c.format, c.width, c.height, c.padding);
    FakeV4l2Config config = allFormats();
    config.row_padding = c.padding;
    FakeV4l2Driver driver(config);
    {
      std::string err;
      auto src = open(driver,
                      "v4l2:/dev/video0?width=" + std::to_string(c.width) +
                          "&height=" + std::to_string(c.height) + "&fps=25&format=" + c.format,
                      err);
      REQUIRE(src);
      CHECK(driver.currentFourcc() == c.fourcc);
      CHECK(src->info().width == c.width);
      CHECK(src->info().height == c.height);
      CHECK(src->info().fps == Approx(25.0));
      CHECK(src->info().real_timestamps);
      CHECK(src->info().pixel_format == hal::fourccName(c.fourcc));
      CHECK(driver.mappedBuffers() == 4);
      CHECK(driver.streaming());
      hal::JpegDecoder decoder;
      Image<uint8_t> expected(c.width, c.height);
      hal::Frame f;
      for (int i = 0; i < 8; ++i) {  // twice round the 4 buffers
        REQUIRE(src->next(f) == hal::FrameStatus::kOk);
        CHECK(f.index == i);
        CHECK(f.timestamp_s == Approx(i / 25.0).margin(1e-6));
        if (c.fourcc == V4L2_PIX_FMT_MJPEG) {
          const auto& jpeg = driver.jpegFrame(i);
          REQUIRE(f.encoded_size == jpeg.size());
          REQUIRE(std::equal(jpeg.begin(), jpeg.end(), f.encoded));
          REQUIRE(decoder.decodeGray(jpeg.data(), jpeg.size(), expected.view(), err));
          REQUIRE(sameImage(f.luma, expected.constView()));
          const auto d = epitrack::test::imageDifference(f.luma, driver.sceneFrame(i).constView());
          CHECK(d.mean_abs < 3.0);  // quality 90 on the noisy synthetic scene: measured 2.6
        } else {
          CHECK(f.encoded == nullptr);
          REQUIRE(sameImage(f.luma, driver.sceneFrame(i).constView()));
        }
      }
    }
    requireReleased(driver);
  }
}

TEST_CASE("V4L2 negotiation prefers GREY, then YUYV, then MJPEG, near 640x480", "[hal][v4l2]") {
  struct Case {
    std::vector<uint32_t> offered;
    uint32_t chosen;
  };
  const Case cases[] = {
      {{V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_GREY}, V4L2_PIX_FMT_GREY},
      {{V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_YUYV}, V4L2_PIX_FMT_YUYV},
      {{v4l2_fourcc('N', 'V', '1', '2'), V4L2_PIX_FMT_MJPEG}, V4L2_PIX_FMT_MJPEG},
  };
  for (const Case& c : cases) {
    FakeV4l2Config config;
    config.formats = c.offered;
    config.sizes = {{320, 240}, {640, 480}, {1280, 720}};
    config.distinct_frames = 1;
    FakeV4l2Driver driver(config);
    std::string err;
    {
      auto src = open(driver, "v4l2:/dev/video0", err);
      REQUIRE(src);
      CHECK(driver.currentFourcc() == c.chosen);
      CHECK(src->info().width == 640);
      CHECK(src->info().height == 480);
      CHECK(src->info().fps == Approx(30.0));  // the driver's rate, not changed
      hal::Frame f;
      REQUIRE(src->next(f) == hal::FrameStatus::kOk);
    }
    requireReleased(driver);
  }
}

TEST_CASE("V4L2 open failures give clear messages and release the device", "[hal][v4l2]") {
  std::string err;
  SECTION("missing device (fake)") {
    FakeV4l2Driver driver(allFormats());
    REQUIRE_FALSE(open(driver, "v4l2:/dev/video7", err));
    CHECK(err.find("cannot open camera '/dev/video7'") != std::string::npos);
    CHECK(err.find("No such file") != std::string::npos);
  }
  SECTION("missing device (real kernel calls)") {
    REQUIRE_FALSE(hal::openFrameSource("v4l2:/dev/epitrack-no-such-video", {}, err));
    CHECK(err.find("cannot open camera '/dev/epitrack-no-such-video'") != std::string::npos);
  }
  SECTION("not a V4L2 device (real kernel calls)") {
    REQUIRE_FALSE(hal::openFrameSource("v4l2:/dev/null", {}, err));
    CHECK(err.find("not a V4L2 device") != std::string::npos);
  }
  SECTION("format not offered") {
    FakeV4l2Config config = allFormats();
    config.formats = {V4L2_PIX_FMT_YUYV};
    FakeV4l2Driver driver(config);
    REQUIRE_FALSE(open(driver, "v4l2:/dev/video0?format=mjpeg", err));
    CHECK(err.find("does not offer format MJPG (it offers: YUYV)") != std::string::npos);
    requireReleased(driver);
  }
  SECTION("no usable format") {
    FakeV4l2Config config = allFormats();
    config.formats = {v4l2_fourcc('N', 'V', '1', '2')};
    FakeV4l2Driver driver(config);
    REQUIRE_FALSE(open(driver, "v4l2:/dev/video0", err));
    CHECK(err.find("offers no format epitrack reads") != std::string::npos);
    CHECK(err.find("NV12") != std::string::npos);
  }
  SECTION("driver refuses the format (substitutes another)") {
    FakeV4l2Config config = allFormats();
    config.faults.refuse_fourcc = V4L2_PIX_FMT_GREY;
    FakeV4l2Driver driver(config);
    REQUIRE_FALSE(open(driver, "v4l2:/dev/video0", err));
    CHECK(err.find("refused format GREY (the driver set MJPG)") != std::string::npos);
    requireReleased(driver);
  }
  SECTION("driver changes the negotiated size in S_FMT") {
    FakeV4l2Config config = allFormats();
    config.faults.change_size = true;
    FakeV4l2Driver driver(config);
    REQUIRE_FALSE(open(driver, "v4l2:/dev/video0?width=320&height=240", err));
    CHECK(err.find("changed the negotiated size 320x240 to 160x120") != std::string::npos);
    requireReleased(driver);
  }
  SECTION("driver reports another size in G_FMT") {
    FakeV4l2Config config = allFormats();
    config.faults.change_size_on_get = true;
    FakeV4l2Driver driver(config);
    REQUIRE_FALSE(open(driver, "v4l2:/dev/video0?width=160&height=120", err));
    CHECK(err.find("changed the negotiated size 160x120 to 160x136") != std::string::npos);
    requireReleased(driver);
  }
  SECTION("not a capture device, no streaming") {
    FakeV4l2Config config = allFormats();
    config.capabilities = V4L2_CAP_VIDEO_OUTPUT | V4L2_CAP_STREAMING;
    FakeV4l2Driver out(config);
    REQUIRE_FALSE(open(out, "v4l2:/dev/video0", err));
    CHECK(err.find("is not a video capture device") != std::string::npos);
    config.capabilities = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_READWRITE;
    FakeV4l2Driver rw(config);
    REQUIRE_FALSE(open(rw, "v4l2:/dev/video0", err));
    CHECK(err.find("does not support streaming") != std::string::npos);
    CHECK(rw.openFds() == 0);
  }
  SECTION("too few buffers") {
    FakeV4l2Config config = allFormats();
    config.max_buffers = 1;
    FakeV4l2Driver driver(config);
    REQUIRE_FALSE(open(driver, "v4l2:/dev/video0", err));
    CHECK(err.find("granted 1 buffers") != std::string::npos);
    requireReleased(driver);
  }
}

TEST_CASE("V4L2 INPUT strings are parsed strictly", "[hal][v4l2]") {
  hal::V4l2Options o;
  std::string err;
  REQUIRE(
      hal::parseV4l2Input("v4l2:/dev/video2?width=1280&height=720&fps=29.97&format=yuyv"
                          "&buffers=6&timeout_ms=500",
                          o, err));
  CHECK(o.device == "/dev/video2");
  CHECK(o.width == 1280);
  CHECK(o.height == 720);
  CHECK(o.fps == Approx(29.97));
  CHECK(o.fourcc == V4L2_PIX_FMT_YUYV);
  CHECK(o.buffers == 6);
  CHECK(o.timeout_ms == 500);
  REQUIRE(hal::parseV4l2Input("v4l2:/dev/video0", o, err));
  CHECK(o.buffers == 4);
  CHECK(o.fourcc == 0);
  REQUIRE_FALSE(hal::parseV4l2Input("v4l2:", o, err));
  CHECK(err.find("no device path") != std::string::npos);
  REQUIRE_FALSE(hal::parseV4l2Input("v4l2:/dev/video0?zoom=2", o, err));
  CHECK(err.find("unknown option 'zoom'") != std::string::npos);
  REQUIRE_FALSE(hal::parseV4l2Input("v4l2:/dev/video0?format=h264", o, err));
  CHECK(err.find("bad value in 'format=h264'") != std::string::npos);
  REQUIRE_FALSE(hal::parseV4l2Input("v4l2:/dev/video0?width=640", o, err));
  CHECK(err.find("width and height together") != std::string::npos);
  REQUIRE_FALSE(hal::parseV4l2Input("v4l2:/dev/video0?fps=-3", o, err));
}

TEST_CASE("V4L2 faults give the promised statuses", "[hal][v4l2][faults]") {
  FakeV4l2Config config = allFormats();
  std::string input = "v4l2:/dev/video0?width=96&height=64&format=grey";
  std::string err;
  hal::Frame f;

  SECTION("EAGAIN bursts and EINTR are retried") {
    config.faults.eagain_at = 1;
    config.faults.eagain_count = 20;
    config.faults.eintr_at = 2;
    config.faults.eintr_count = 6;
    FakeV4l2Driver driver(config);
    {
      auto src = open(driver, input, err);
      REQUIRE(src);
      for (int i = 0; i < 4; ++i) {
        REQUIRE(src->next(f) == hal::FrameStatus::kOk);
        CHECK(f.index == i);
        REQUIRE(sameImage(f.luma, driver.sceneFrame(i).constView()));
      }
    }
    requireReleased(driver);
  }
  SECTION("an endless EAGAIN is a timeout") {
    config.faults.eagain_at = 1;
    config.faults.eagain_count = 1000;
    FakeV4l2Driver driver(config);
    auto src = open(driver, input, err);
    REQUIRE(src);
    REQUIRE(src->next(f) == hal::FrameStatus::kOk);
    REQUIRE(src->next(f) == hal::FrameStatus::kTimeout);
    CHECK(src->lastError().find("EAGAIN") != std::string::npos);
  }
  SECTION("EIO is counted and retried a bounded number of times") {
    config.faults.eio_at = 2;
    config.faults.eio_count = hal::V4l2CaptureSource::kMaxEioRetries;
    FakeV4l2Driver driver(config);
    {
      auto src = open(driver, input, err);
      REQUIRE(src);
      auto* capture = dynamic_cast<hal::V4l2CaptureSource*>(src.get());
      REQUIRE(capture != nullptr);
      for (int i = 0; i < 4; ++i) REQUIRE(src->next(f) == hal::FrameStatus::kOk);
      CHECK(capture->eioCount() == hal::V4l2CaptureSource::kMaxEioRetries);
    }
    requireReleased(driver);
  }
  SECTION("persistent EIO is an error") {
    config.faults.eio_at = 1;
    config.faults.eio_count = 100;
    FakeV4l2Driver driver(config);
    {
      auto src = open(driver, input, err);
      REQUIRE(src);
      REQUIRE(src->next(f) == hal::FrameStatus::kOk);
      REQUIRE(src->next(f) == hal::FrameStatus::kError);
      CHECK(src->lastError().find("EIO") != std::string::npos);
    }
    requireReleased(driver);
  }
  SECTION("unplugging mid-stream is device_lost, for good") {
    config.faults.unplug_at = 3;
    FakeV4l2Driver driver(config);
    {
      auto src = open(driver, input, err);
      REQUIRE(src);
      for (int i = 0; i < 3; ++i) REQUIRE(src->next(f) == hal::FrameStatus::kOk);
      REQUIRE(src->next(f) == hal::FrameStatus::kDeviceLost);
      CHECK(src->lastError().find("device lost") != std::string::npos);
      REQUIRE(src->next(f) == hal::FrameStatus::kDeviceLost);
    }
    requireReleased(driver);
  }
  SECTION("a short bytesused is a corrupt frame, and capture goes on") {
    config.faults.short_bytesused_at = 2;
    FakeV4l2Driver driver(config);
    {
      auto src = open(driver, "v4l2:/dev/video0?width=96&height=64&format=yuyv", err);
      REQUIRE(src);
      REQUIRE(src->next(f) == hal::FrameStatus::kOk);
      REQUIRE(src->next(f) == hal::FrameStatus::kOk);
      REQUIRE(src->next(f) == hal::FrameStatus::kCorruptFrame);
      CHECK(src->lastError().find("frame 2 is short (6144 of 12288 bytes)") != std::string::npos);
      REQUIRE(src->next(f) == hal::FrameStatus::kOk);
      CHECK(f.index == 3);
      REQUIRE(sameImage(f.luma, driver.sceneFrame(3).constView()));
    }
    requireReleased(driver);
  }
  SECTION("corrupt JPEG data is a corrupt frame, and capture goes on") {
    config.faults.corrupt_jpeg_at = 1;
    FakeV4l2Driver driver(config);
    {
      auto src = open(driver, "v4l2:/dev/video0?width=160&height=120&format=mjpeg", err);
      REQUIRE(src);
      REQUIRE(src->next(f) == hal::FrameStatus::kOk);
      REQUIRE(src->next(f) == hal::FrameStatus::kCorruptFrame);
      CHECK(src->lastError().find("frame 1") != std::string::npos);
      REQUIRE(src->next(f) == hal::FrameStatus::kOk);
      CHECK(f.index == 2);
    }
    requireReleased(driver);
  }
  SECTION("a buffer flagged as damaged is a corrupt frame") {
    config.faults.error_flag_at = 0;
    FakeV4l2Driver driver(config);
    auto src = open(driver, input, err);
    REQUIRE(src);
    REQUIRE(src->next(f) == hal::FrameStatus::kCorruptFrame);
    REQUIRE(src->next(f) == hal::FrameStatus::kOk);
    CHECK(f.index == 1);
  }
  SECTION("a poll timeout is a timeout, and capture goes on") {
    config.faults.poll_timeout_at = 1;
    config.faults.poll_timeout_count = 2;
    FakeV4l2Driver driver(config);
    auto src = open(driver, input + "&timeout_ms=50", err);
    REQUIRE(src);
    REQUIRE(src->next(f) == hal::FrameStatus::kOk);
    REQUIRE(src->next(f) == hal::FrameStatus::kTimeout);
    CHECK(src->lastError().find("no frame within 50 ms") != std::string::npos);
    REQUIRE(src->next(f) == hal::FrameStatus::kTimeout);
    REQUIRE(src->next(f) == hal::FrameStatus::kOk);
    CHECK(f.index == 1);
  }
}
