// Regression tests of the reader bugs the fuzzers of tests/fuzz found (README, "Bugs found and
// fixed"), so that the ordinary and the sanitizer builds keep them fixed. The inputs are the crash
// files kept in the fuzz corpora (tests/fuzz/corpus/TARGET/regression_*).
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <linux/videodev2.h>
#include <sys/resource.h>

#include "hal/io/file_util.hpp"
#include "hal/io/image_codec.hpp"
#include "hal/io/text_formats.hpp"
#include "hal/io/tracks_csv.hpp"
#include "hal/replay/y4m_source.hpp"
#include "hal/v4l2/v4l2_capture_source.hpp"
#include "tests/hal/fake_v4l2_driver.hpp"
#include "tests/hal/replay_test_helpers.hpp"

using epitrack::Image;
namespace hal = epitrack::hal;

namespace {

std::vector<uint8_t> corpusFile(const std::string& target, const std::string& name) {
  std::vector<uint8_t> bytes;
  std::string error;
  const std::string path =
      std::string(EPITRACK_SOURCE_DIR) + "/tests/fuzz/corpus/" + target + "/" + name;
  REQUIRE(hal::readFileInto(path, bytes, error));
  return bytes;
}

/// The seed generator's gradient (tests/fuzz/make_seed_corpus.py, gradient()) for one channel.
int seedGradient(int x, int y, int w, int h, int maxval) {
  return std::min(maxval, ((x * 37 + y * 23) * maxval) / (37 * w + 23 * h + 61 * 3));
}

long peakRssKb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss;
}

}  // namespace

TEST_CASE("An interlaced PNG whose rows are not a multiple of 8 bytes decodes", "[hal][fuzz]") {
  // Found by UBSan on the seed corpus: the row pointers were stored after the pixels, at an
  // address misaligned for pointers whenever width * height was not a multiple of 8.
  const std::vector<uint8_t> png = corpusFile("png", "gray8_interlaced_7x5.png");
  hal::GrayImageDecoder decoder;
  Image<uint8_t> image;
  std::string error;
  REQUIRE(decoder.decode(png.data(), png.size(), image, error));
  REQUIRE(image.width() == 7);
  REQUIRE(image.height() == 5);
  for (int y = 0; y < 5; ++y) {
    for (int x = 0; x < 7; ++x) CHECK(image.constView()(x, y) == seedGradient(x, y, 7, 5, 255));
  }
}

TEST_CASE("A PNG chunk claiming 1 GB does not make the reader allocate it", "[hal][fuzz]") {
  // Found by fuzz_png (a timeout): 126 bytes whose sPLT chunk claims 1096055002 bytes; libpng
  // allocated and cleared that much before finding the data missing.
  const std::vector<uint8_t> png = corpusFile("png", "regression_splt_1gb_length.png");
  const long before_kb = peakRssKb();
  hal::ImageHeader header;
  std::string error;
  hal::readPngHeader(png.data(), png.size(), header, error);
  Image<uint8_t> image(5, 3);
  hal::PngScratch scratch;
  CHECK_FALSE(hal::decodePng(png.data(), png.size(), image.view(), scratch, error));
  CHECK(error.find("bad PNG") == 0);
  CHECK(peakRssKb() - before_kb < 256 * 1024);  // far below the 1 GB claimed
}

TEST_CASE("Trajectory and tracks.csv writers keep huge values on their line", "[hal][fuzz]") {
  // Found by fuzz_text_formats: "%.9f" of 2.8e262 is longer than the 256-byte line buffer, so the
  // line was cut (losing the quaternion and the newline) and the written file did not parse.
  const std::vector<uint8_t> text =
      corpusFile("text_formats", "regression_huge_value_line_cut.txt");
  std::vector<hal::TrajectoryEntry> entries;
  std::string error;
  REQUIRE(hal::parseTrajectory(std::string(text.begin(), text.end()), entries, error));
  REQUIRE(entries.size() == 1);
  entries.push_back(entries.front());
  entries.back().t = 1e300;
  entries.back().position = Eigen::Vector3d(-1e300, 2.5, 1e-300);
  std::vector<hal::TrajectoryEntry> again;
  REQUIRE(hal::parseTrajectory(hal::formatTrajectory(entries), again, error));
  REQUIRE(again.size() == 2);
  for (std::size_t i = 0; i < 2; ++i) {
    CHECK(again[i].t == entries[i].t);
    CHECK(again[i].position.x() == entries[i].position.x());
    CHECK(again[i].position.z() == Approx(entries[i].position.z()).margin(1e-9));
    CHECK(again[i].rotation.coeffs().isApprox(entries[i].rotation.coeffs(), 1e-8));
  }

  const std::vector<hal::TrackRow> rows = {{0, 1, 1e300, -2.5}, {1, 2, 3.25, -1e200}};
  std::vector<hal::TrackRow> rows_again;
  REQUIRE(hal::parseTracksCsv(hal::formatTracksCsv(rows), rows_again, error));
  REQUIRE(rows_again.size() == 2);
  CHECK(rows_again[0].x == 1e300);
  CHECK(rows_again[1].y == -1e200);
  CHECK(rows_again[1].track_id == 2);
}

TEST_CASE("A quaternion with huge components is normalised, not zeroed", "[hal][fuzz]") {
  // Found by fuzz_text_formats: qw = 2.8e262 made the plain norm overflow to infinity, and the
  // division turned the rotation into four zeros, accepted as a pose.
  const std::vector<uint8_t> text =
      corpusFile("text_formats", "regression_quaternion_norm_overflow.txt");
  std::vector<hal::TrajectoryEntry> entries;
  std::string error;
  if (hal::parseTrajectory(std::string(text.begin(), text.end()), entries, error)) {
    for (const hal::TrajectoryEntry& e : entries) CHECK(e.rotation.norm() == Approx(1.0));
  }
  REQUIRE(hal::parseTrajectory("0 0 0 0 0 0 3e200 4e200\n", entries, error));
  CHECK(entries[0].rotation.z() == Approx(0.6));
  CHECK(entries[0].rotation.w() == Approx(0.8));
  CHECK_FALSE(hal::parseTrajectory("0 0 0 0 1e308 1e308 1e308 1e308\n", entries, error));
  CHECK(error.find("quaternion") != std::string::npos);
}

TEST_CASE("Y4M planes larger than the skip chunk are skipped exactly", "[hal][fuzz]") {
  // The chroma and alpha planes are now skipped 64 KB at a time instead of through one scratch
  // buffer of their full size (a large 444alpha p16 header asked for 1.6 GB).
  const std::vector<Image<uint8_t>> frames = epitrack::test::syntheticFrames(160, 120, 3);
  const std::vector<uint8_t> stream =
      epitrack::test::makeY4m(frames, "444p16");  // 76800 B of chroma
  std::FILE* file = ::fmemopen(const_cast<uint8_t*>(stream.data()), stream.size(), "rb");
  REQUIRE(file != nullptr);
  hal::Y4mSource source(file, /*owns_stream=*/true, "memory", hal::SourceOptions{});
  REQUIRE(source.ok());
  hal::Frame frame;
  for (int i = 0; i < 3; ++i) {
    REQUIRE(source.next(frame) == hal::FrameStatus::kOk);
    CHECK(epitrack::test::sameImage(frame.luma, frames[static_cast<std::size_t>(i)].constView()));
  }
  CHECK(source.next(frame) == hal::FrameStatus::kEndOfStream);
}

namespace {

/// Passes every call to the fake driver, but claims more bytes than the buffer holds on DQBUF.
class OverclaimingDriver final : public hal::V4l2Syscalls {
 public:
  explicit OverclaimingDriver(epitrack::test::FakeV4l2Driver& driver) : driver_(driver) {}
  int open(const char* path, int flags) override { return driver_.open(path, flags); }
  int close(int fd) override { return driver_.close(fd); }
  void* mmap(void* addr, std::size_t length, int prot, int flags, int fd, off_t offset) override {
    return driver_.mmap(addr, length, prot, flags, fd, offset);
  }
  int munmap(void* addr, std::size_t length) override { return driver_.munmap(addr, length); }
  int poll(struct pollfd* fds, nfds_t count, int timeout_ms) override {
    return driver_.poll(fds, count, timeout_ms);
  }
  int ioctl(int fd, unsigned long request, void* arg) override {
    const int rc = driver_.ioctl(fd, request, arg);
    if (rc == 0 && request == VIDIOC_DQBUF) {
      auto* buf = static_cast<v4l2_buffer*>(arg);
      buf->bytesused = buf->length + 1;
    }
    return rc;
  }

 private:
  epitrack::test::FakeV4l2Driver& driver_;
};

}  // namespace

TEST_CASE("A V4L2 buffer claiming more bytes than it holds is a corrupt frame", "[hal][fuzz]") {
  // Found by fuzz_v4l2_capture: an MJPEG buffer whose bytesused exceeded its length was copied
  // by that length (reading past the mapping) into a copy grown to 3 GB.
  for (const uint32_t fourcc : {V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_GREY}) {
    epitrack::test::FakeV4l2Config config;
    config.formats = {fourcc};
    config.sizes = {{64, 48}};
    epitrack::test::FakeV4l2Driver driver(config);
    {
      OverclaimingDriver overclaiming(driver);
      std::string error;
      const auto source = hal::openV4l2Source("v4l2:/dev/video0", overclaiming, {}, error);
      REQUIRE(source != nullptr);
      hal::Frame frame;
      CHECK(source->next(frame) == hal::FrameStatus::kCorruptFrame);
      CHECK(source->lastError().find("claims") != std::string::npos);
    }
    CHECK(driver.openFds() == 0);
    CHECK(driver.mappedBuffers() == 0);
  }
}

TEST_CASE("A V4L2 driver offering an empty frame size is refused", "[hal][fuzz]") {
  epitrack::test::FakeV4l2Config config;
  config.formats = {V4L2_PIX_FMT_GREY};
  config.sizes = {{0, 0}};
  epitrack::test::FakeV4l2Driver driver(config);
  std::string error;
  CHECK(hal::openV4l2Source("v4l2:/dev/video0", driver, {}, error) == nullptr);
  CHECK(error.find("no usable frame size") != std::string::npos);
  CHECK(driver.openFds() == 0);
}
