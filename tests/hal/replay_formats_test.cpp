// Y4M and MJPEG replay against the synthetic renderer's frames: Y4M luma exactly for every chroma
// layout (and from a pipe), JPEG within a stated error; truncated and foreign files give clear
// messages.
#include <catch2/catch.hpp>

#include <chrono>
#include <cstdio>
#include <thread>

#include <unistd.h>

#include "hal/frame_source.hpp"
#include "hal/io/file_util.hpp"
#include "hal/io/image_codec.hpp"
#include "hal/replay/jpeg_stream.hpp"
#include "hal/replay/y4m_source.hpp"
#include "tests/hal/replay_test_helpers.hpp"
#include "tests/support/test_support.hpp"

using epitrack::Image;
using epitrack::test::sameImage;
namespace hal = epitrack::hal;

namespace {

bool writeBytes(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::string err;
  return hal::writeFileAtomic(path, bytes.data(), bytes.size(), err);
}

}  // namespace

TEST_CASE("Y4M replays the exact luma for every chroma layout", "[hal][replay][y4m]") {
  const auto frames = epitrack::test::syntheticFrames(97, 71, 3);  // odd size: chroma rounds up
  epitrack::test::TempDir dir("y4m");
  for (const char* chroma : {"420jpeg", "420paldv", "420mpeg2", "420", "411", "422", "444",
                             "444alpha", "mono", "420p10", "422p12", "444p16", "mono16"}) {
    CAPTURE(chroma);
    const std::string path = dir.file(std::string("clip-") + chroma + ".y4m");
    REQUIRE(writeBytes(path, epitrack::test::makeY4m(frames, chroma, 30000, 1001)));
    std::string err;
    auto src = hal::openFrameSource(path, {}, err);
    REQUIRE(src);
    CHECK(src->info().width == 97);
    CHECK(src->info().height == 71);
    CHECK(src->info().fps == Approx(29.97).epsilon(1e-3));
    CHECK(src->info().pixel_format == std::string("Y4M ") + chroma);
    CHECK_FALSE(src->info().real_timestamps);
    hal::Frame f;
    for (int i = 0; i < 3; ++i) {
      REQUIRE(src->next(f) == hal::FrameStatus::kOk);
      CHECK(f.index == i);
      CHECK(f.timestamp_s == Approx(i * 1001.0 / 30000.0));
      REQUIRE(sameImage(f.luma, frames[static_cast<std::size_t>(i)].constView()));
    }
    REQUIRE(src->next(f) == hal::FrameStatus::kEndOfStream);
    REQUIRE(src->next(f) == hal::FrameStatus::kEndOfStream);
  }
}

TEST_CASE("Y4M without a C tag is 420jpeg and the frame count of a file is known",
          "[hal][replay][y4m]") {
  hal::Y4mHeader h;
  std::string err;
  REQUIRE(hal::parseY4mHeader("YUV4MPEG2 W4 H2 F25:1", h, err));
  CHECK(h.chroma == "420jpeg");
  CHECK(h.other_plane_bytes == 2 * 2 * 1);
  REQUIRE_FALSE(hal::parseY4mHeader("YUV4MPEG2 W4 F25:1", h, err));
  CHECK(err.find("W and H") != std::string::npos);
  REQUIRE_FALSE(hal::parseY4mHeader("YUV4MPEG2 W4 H4 Cxyz", h, err));
  CHECK(err.find("Cxyz") != std::string::npos);
  REQUIRE_FALSE(hal::parseY4mHeader("YUV4MPEG W4 H4", h, err));
  CHECK(err.find("signature") != std::string::npos);

  epitrack::test::TempDir dir("y4m-count");
  const auto frames = epitrack::test::syntheticFrames(32, 24, 4);
  auto bytes = epitrack::test::makeY4m(frames, "420jpeg");
  // makeY4m writes tags on odd frames; rewrite plain for the count.
  std::vector<uint8_t> plain;
  {
    const std::string head = "YUV4MPEG2 W32 H24 F25:1\n";
    plain.assign(head.begin(), head.end());
    for (const auto& f : frames) {
      const std::string fr = "FRAME\n";
      plain.insert(plain.end(), fr.begin(), fr.end());
      for (int y = 0; y < 24; ++y) plain.insert(plain.end(), f.row(y), f.row(y) + 32);
      plain.insert(plain.end(), 2 * 16 * 12, 128);
    }
  }
  REQUIRE(writeBytes(dir.file("plain.y4m"), plain));
  auto src = hal::openFrameSource(dir.file("plain.y4m"), {}, err);
  REQUIRE(src);
  CHECK(src->info().frame_count == 4);
}

TEST_CASE("Y4M streams from a pipe", "[hal][replay][y4m]") {
  const auto frames = epitrack::test::syntheticFrames(64, 48, 5);
  const auto bytes = epitrack::test::makeY4m(frames, "422");
  int fds[2];
  REQUIRE(::pipe(fds) == 0);
  std::thread writer([&] {
    // Dribble the stream in small, uneven pieces, as a pipe from ffmpeg does.
    std::size_t done = 0;
    std::size_t piece = 1;
    while (done < bytes.size()) {
      const std::size_t n = std::min(piece, bytes.size() - done);
      const ssize_t w = ::write(fds[1], bytes.data() + done, n);
      if (w <= 0) break;
      done += static_cast<std::size_t>(w);
      piece = piece * 3 % 5000 + 1;
    }
    ::close(fds[1]);
  });
  std::FILE* stream = ::fdopen(fds[0], "rb");
  REQUIRE(stream != nullptr);
  hal::Y4mSource src(stream, true, "pipe", {});
  REQUIRE(src.ok());
  CHECK(src.info().frame_count == -1);
  hal::Frame f;
  int n = 0;
  while (src.next(f) == hal::FrameStatus::kOk) {
    REQUIRE(sameImage(f.luma, frames[static_cast<std::size_t>(n)].constView()));
    ++n;
  }
  writer.join();
  CHECK(n == 5);
}

TEST_CASE("A truncated Y4M gives its good frames, then a corrupt frame naming the offset",
          "[hal][replay][y4m]") {
  const auto frames = epitrack::test::syntheticFrames(40, 30, 3);
  auto bytes = epitrack::test::makeY4m(frames, "420jpeg");
  bytes.resize(bytes.size() - 700);  // cut inside the third frame
  epitrack::test::TempDir dir("y4m-trunc");
  REQUIRE(writeBytes(dir.file("cut.y4m"), bytes));
  std::string err;
  auto src = hal::openFrameSource(dir.file("cut.y4m"), {}, err);
  REQUIRE(src);
  hal::Frame f;
  REQUIRE(src->next(f) == hal::FrameStatus::kOk);
  REQUIRE(src->next(f) == hal::FrameStatus::kOk);
  REQUIRE(src->next(f) == hal::FrameStatus::kCorruptFrame);
  CHECK(src->lastError().find("frame 2 truncated at byte") != std::string::npos);
  CHECK(src->lastError().find("cut.y4m") != std::string::npos);
  REQUIRE(src->next(f) == hal::FrameStatus::kEndOfStream);
}

TEST_CASE("A Y4M whose frame marker is damaged stops with an error", "[hal][replay][y4m]") {
  const auto frames = epitrack::test::syntheticFrames(16, 8, 2);
  auto bytes = epitrack::test::makeY4m(frames, "mono");
  const std::size_t second = bytes.size() - (16 * 8 + 11);  // "FRAME Ixyz\n" + luma
  bytes[second] = 'X';
  epitrack::test::TempDir dir("y4m-marker");
  REQUIRE(writeBytes(dir.file("bad.y4m"), bytes));
  std::string err;
  auto src = hal::openFrameSource(dir.file("bad.y4m"), {}, err);
  REQUIRE(src);
  hal::Frame f;
  REQUIRE(src->next(f) == hal::FrameStatus::kOk);
  REQUIRE(src->next(f) == hal::FrameStatus::kError);
  CHECK(src->lastError().find("bad frame marker at byte " + std::to_string(second)) !=
        std::string::npos);
}

TEST_CASE("MJPEG replays JPEG frames within the codec's error", "[hal][replay][mjpeg]") {
  const auto frames = epitrack::test::syntheticFrames(160, 120, 6);
  epitrack::test::TempDir dir("mjpeg");
  std::vector<std::size_t> offsets;
  const auto bytes = epitrack::test::makeMjpeg(frames, 95, &offsets);
  REQUIRE(writeBytes(dir.file("clip.mjpeg"), bytes));
  std::string err;
  hal::SourceOptions opts;
  opts.default_fps = 15.0;
  auto src = hal::openFrameSource(dir.file("clip.mjpeg"), opts, err);
  REQUIRE(src);
  CHECK(src->info().width == 160);
  CHECK(src->info().height == 120);
  CHECK(src->info().frame_count == 6);
  CHECK(src->info().pixel_format == "MJPEG");
  hal::Frame f;
  hal::JpegDecoder reference;
  Image<uint8_t> decoded(160, 120);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    REQUIRE(src->next(f) == hal::FrameStatus::kOk);
    CHECK(f.index == static_cast<int64_t>(i));
    CHECK(f.timestamp_s == Approx(static_cast<double>(i) / 15.0));
    // The compressed bytes are handed out unchanged (for bit-identical re-recording) ...
    const std::size_t end = i + 1 < offsets.size() ? offsets[i + 1] : bytes.size();
    REQUIRE(f.encoded != static_cast<const uint8_t*>(nullptr));
    CHECK(f.encoded_size == end - offsets[i]);
    // ... the luma is exactly what TurboJPEG makes of them ...
    REQUIRE(reference.decodeGray(bytes.data() + offsets[i], end - offsets[i], decoded.view(), err));
    REQUIRE(sameImage(f.luma, decoded.constView()));
    // ... and within the JPEG error of the rendered frame (noise sigma 1) at quality 95.
    const auto d = epitrack::test::imageDifference(f.luma, frames[i].constView());
    CHECK(d.mean_abs < 2.0);
    CHECK(d.max_abs <= 16);
    if (i == 0)
      std::printf("MJPEG q95 160x120: mean |error| %.3f, max %d\n", d.mean_abs, d.max_abs);
  }
  REQUIRE(src->next(f) == hal::FrameStatus::kEndOfStream);
}

TEST_CASE("MJPEG: a damaged frame is corrupt and replay goes on: a cut file ends cleanly",
          "[hal][replay][mjpeg]") {
  const auto frames = epitrack::test::syntheticFrames(64, 48, 4);
  std::vector<std::size_t> offsets;
  auto bytes = epitrack::test::makeMjpeg(frames, 90, &offsets);
  // Frame 1: keep its headers, drop the second half of its data (and its EOI).
  std::vector<uint8_t> damaged(bytes.begin(), bytes.begin() + static_cast<long>(offsets[1]));
  const std::size_t half = (offsets[2] - offsets[1]) / 2;
  damaged.insert(damaged.end(), bytes.begin() + static_cast<long>(offsets[1]),
                 bytes.begin() + static_cast<long>(offsets[1] + half));
  damaged.insert(damaged.end(), bytes.begin() + static_cast<long>(offsets[2]), bytes.end());
  damaged.resize(damaged.size() - 100);  // and frame 3 is cut by the end of the file
  epitrack::test::TempDir dir("mjpeg-bad");
  REQUIRE(writeBytes(dir.file("bad.mjpg"), damaged));
  std::string err;
  auto src = hal::openFrameSource(dir.file("bad.mjpg"), {}, err);
  REQUIRE(src);
  CHECK(src->info().frame_count == 4);
  hal::Frame f;
  REQUIRE(src->next(f) == hal::FrameStatus::kOk);
  REQUIRE(src->next(f) == hal::FrameStatus::kCorruptFrame);
  CHECK(src->lastError().find("frame 1 at byte " + std::to_string(offsets[1])) !=
        std::string::npos);
  REQUIRE(src->next(f) == hal::FrameStatus::kOk);
  CHECK(f.index == 2);
  REQUIRE(src->next(f) == hal::FrameStatus::kCorruptFrame);
  CHECK(src->lastError().find("truncated") != std::string::npos);
  REQUIRE(src->next(f) == hal::FrameStatus::kEndOfStream);
}

TEST_CASE("MJPEG: a frame of another size is an error naming it", "[hal][replay][mjpeg]") {
  auto a = epitrack::test::makeMjpeg(epitrack::test::syntheticFrames(32, 24, 1), 90);
  const auto b = epitrack::test::makeMjpeg(epitrack::test::syntheticFrames(48, 24, 1), 90);
  a.insert(a.end(), b.begin(), b.end());
  epitrack::test::TempDir dir("mjpeg-size");
  REQUIRE(writeBytes(dir.file("mixed.mjpeg"), a));
  std::string err;
  auto src = hal::openFrameSource(dir.file("mixed.mjpeg"), {}, err);
  REQUIRE(src);
  hal::Frame f;
  REQUIRE(src->next(f) == hal::FrameStatus::kOk);
  REQUIRE(src->next(f) == hal::FrameStatus::kError);
  CHECK(src->lastError().find("frame 1") != std::string::npos);
  CHECK(src->lastError().find("48x24") != std::string::npos);
}

TEST_CASE("The JPEG marker walk skips embedded thumbnails and stuffed bytes", "[hal][mjpeg]") {
  const auto jpeg = epitrack::test::makeMjpeg(epitrack::test::syntheticFrames(24, 16, 1), 80);
  // An APP1 segment holding a whole JPEG (as EXIF thumbnails do) after SOI.
  std::vector<uint8_t> outer = {0xFF, 0xD8, 0xFF, 0xE1};
  const std::size_t seg = jpeg.size() + 2;
  outer.push_back(static_cast<uint8_t>(seg >> 8));
  outer.push_back(static_cast<uint8_t>(seg & 0xFF));
  outer.insert(outer.end(), jpeg.begin(), jpeg.end());
  outer.insert(outer.end(), jpeg.begin() + 2, jpeg.end());  // the real image after the APP1
  std::size_t length = 0;
  REQUIRE(hal::measureJpeg(outer.data(), outer.size(), length) == hal::JpegExtent::kComplete);
  CHECK(length == outer.size());
  REQUIRE(hal::measureJpeg(jpeg.data(), jpeg.size() - 1, length) == hal::JpegExtent::kTruncated);
  const uint8_t not_jpeg[] = {0x00, 0x01, 0x02};
  REQUIRE(hal::measureJpeg(not_jpeg, 3, length) == hal::JpegExtent::kMalformed);
  CHECK(hal::findJpegStart(outer.data(), outer.size(), 1) == 6);
}

TEST_CASE("Foreign, missing, empty and cut inputs give clear messages", "[hal][replay]") {
  epitrack::test::TempDir dir("replay-errors");
  std::string err;
  REQUIRE_FALSE(hal::openFrameSource(dir.file("nothing.y4m"), {}, err));
  CHECK(err.find("nothing.y4m") != std::string::npos);
  CHECK(err.find("No such file") != std::string::npos);

  REQUIRE(hal::writeTextAtomic(dir.file("notes.txt"), "hello, not a video\n", err));
  REQUIRE_FALSE(hal::openFrameSource(dir.file("notes.txt"), {}, err));
  CHECK(err.find("not a frame directory, a Y4M file or an MJPEG file") != std::string::npos);

  REQUIRE(hal::writeTextAtomic(dir.file("fake.y4m"), "hello, not a video\n", err));
  REQUIRE_FALSE(hal::openFrameSource(dir.file("fake.y4m"), {}, err));
  CHECK(err.find("fake.y4m") != std::string::npos);
  CHECK(err.find("no YUV4MPEG2 signature") != std::string::npos);

  REQUIRE(hal::writeTextAtomic(dir.file("empty.mjpeg"), "", err));
  REQUIRE_FALSE(hal::openFrameSource(dir.file("empty.mjpeg"), {}, err));
  CHECK(err.find("empty") != std::string::npos);

  REQUIRE(hal::writeTextAtomic(dir.file("text.mjpeg"), "hello, not a video\n", err));
  REQUIRE_FALSE(hal::openFrameSource(dir.file("text.mjpeg"), {}, err));
  CHECK(err.find("no JPEG signature") != std::string::npos);

  REQUIRE(hal::writeTextAtomic(dir.file("head.y4m"), "YUV4MPEG2 W16", err));
  REQUIRE_FALSE(hal::openFrameSource(dir.file("head.y4m"), {}, err));
  CHECK(err.find("no complete header line") != std::string::npos);

  REQUIRE(hal::writeTextAtomic(dir.file("zero.y4m"), "YUV4MPEG2 W16 H16\n", err));
  auto src = hal::openFrameSource(dir.file("zero.y4m"), {}, err);
  REQUIRE(src);  // a header and no frames: an empty clip
  hal::Frame f;
  CHECK(src->next(f) == hal::FrameStatus::kEndOfStream);
}

TEST_CASE("Realtime replay paces at the nominal rate", "[hal][replay]") {
  const auto frames = epitrack::test::syntheticFrames(16, 16, 4);
  epitrack::test::TempDir dir("pace");
  REQUIRE(writeBytes(dir.file("p.y4m"), epitrack::test::makeY4m(frames, "mono", 50, 1)));
  std::string err;
  hal::SourceOptions opts;
  opts.realtime = true;
  auto src = hal::openFrameSource(dir.file("p.y4m"), opts, err);
  REQUIRE(src);
  hal::Frame f;
  const auto t0 = std::chrono::steady_clock::now();
  while (src->next(f) == hal::FrameStatus::kOk) {
  }
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  CHECK(s >= 3.0 / 50.0 - 0.002);  // frames 1..3 wait 20 ms each
  CHECK(s < 1.0);
}
