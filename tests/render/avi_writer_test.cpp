#include "tools/render/avi_writer.hpp"

#include <catch2/catch.hpp>

#include <cstring>

#include <unistd.h>

#include "algo/image/image.hpp"
#include "hal/io/file_util.hpp"
#include "hal/io/image_codec.hpp"
#include "hal/io/text_formats.hpp"
#include "tests/support/test_support.hpp"

namespace {

uint32_t le32(const std::vector<uint8_t>& b, std::size_t at) {
  return static_cast<uint32_t>(b[at]) | static_cast<uint32_t>(b[at + 1]) << 8 |
         static_cast<uint32_t>(b[at + 2]) << 16 | static_cast<uint32_t>(b[at + 3]) << 24;
}
bool tag(const std::vector<uint8_t>& b, std::size_t at, const char* t) {
  return std::memcmp(b.data() + at, t, 4) == 0;
}

}  // namespace

TEST_CASE("The MJPEG AVI has a consistent RIFF structure and index", "[render][avi]") {
  epitrack::test::TempDir dir("avi");
  const std::string path = dir.file("clip.avi");
  epitrack::render::MjpegAviWriter avi;
  std::string err;
  REQUIRE(avi.open(path, 96, 64, 25.0, err));
  epitrack::hal::JpegEncoder enc;
  std::vector<std::vector<uint8_t>> jpegs;
  for (int i = 0; i < 5; ++i) {
    epitrack::Image<uint8_t> img(96, 64);
    epitrack::test::fillRandom(img.view(), static_cast<uint32_t>(i));
    std::vector<uint8_t> rgb(96 * 64 * 3);
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 96; ++x)
        for (int c = 0; c < 3; ++c)
          rgb[static_cast<std::size_t>((y * 96 + x) * 3 + c)] =
              static_cast<uint8_t>(img(x, y) / (c + 1));
    REQUIRE(enc.encodeRgb(rgb.data(), 96, 64, 96 * 3, 80, err));
    jpegs.emplace_back(enc.data(), enc.data() + enc.size());
    REQUIRE(avi.addFrame(enc.data(), enc.size(), err));
  }
  REQUIRE(::access((path + ".tmp").c_str(), F_OK) == 0);  // written under a temporary name ...
  REQUIRE(::access(path.c_str(), F_OK) != 0);
  REQUIRE(avi.finish(err));
  REQUIRE(::access(path.c_str(), F_OK) == 0);  // ... and renamed when complete
  std::vector<uint8_t> b;
  REQUIRE(epitrack::hal::readFileInto(path, b, err));
  REQUIRE(tag(b, 0, "RIFF"));
  REQUIRE(le32(b, 4) == b.size() - 8);
  REQUIRE(tag(b, 8, "AVI "));
  REQUIRE(tag(b, 12, "LIST"));
  REQUIRE(tag(b, 20, "hdrl"));
  REQUIRE(tag(b, 24, "avih"));
  REQUIRE(le32(b, 32) == 40000);  // microseconds per frame at 25 fps
  REQUIRE(le32(b, 48) == 5);      // total frames
  REQUIRE(le32(b, 64) == 96);
  REQUIRE(le32(b, 68) == 64);
  const std::size_t hdrl_end = 20 + le32(b, 16);
  REQUIRE(tag(b, hdrl_end, "LIST"));
  REQUIRE(tag(b, hdrl_end + 8, "movi"));
  const std::size_t movi = hdrl_end + 8;
  const std::size_t idx1 = movi + le32(b, hdrl_end + 4);
  REQUIRE(tag(b, idx1, "idx1"));
  REQUIRE(le32(b, idx1 + 4) == 5 * 16);
  REQUIRE(idx1 + 8 + 5 * 16 == b.size());
  for (std::size_t i = 0; i < 5; ++i) {
    const std::size_t e = idx1 + 8 + 16 * i;
    REQUIRE(tag(b, e, "00dc"));
    const std::size_t chunk = movi + le32(b, e + 8);
    REQUIRE(tag(b, chunk, "00dc"));
    REQUIRE(le32(b, chunk + 4) == jpegs[i].size());
    REQUIRE(le32(b, e + 12) == jpegs[i].size());
    REQUIRE(std::memcmp(b.data() + chunk + 8, jpegs[i].data(), jpegs[i].size()) == 0);
  }
  // ffprobe, when installed, must read every frame as MJPEG.
  if (epitrack::test::run("command -v ffprobe >/dev/null 2>&1") == 0) {
    REQUIRE(epitrack::test::run("ffprobe -v error -count_frames -select_streams v:0 -show_entries "
                                "stream=codec_name,width,height,nb_read_frames -of csv=p=0 " +
                                path + " > " + dir.file("probe.txt")) == 0);
    std::string probe;
    REQUIRE(epitrack::hal::readTextFile(dir.file("probe.txt"), probe, err));
    REQUIRE(probe.find("mjpeg,96,64,5") != std::string::npos);
  } else {
    WARN("ffprobe not installed: AVI checked structurally only");
  }
}

TEST_CASE("An unfinished AVI leaves no file behind", "[render][avi]") {
  epitrack::test::TempDir dir("avi-abort");
  const std::string path = dir.file("clip.avi");
  {
    epitrack::render::MjpegAviWriter avi;
    std::string err;
    REQUIRE(avi.open(path, 16, 16, 30.0, err));
    const uint8_t fake[4] = {0xFF, 0xD8, 0xFF, 0xD9};
    REQUIRE(avi.addFrame(fake, 4, err));
  }  // destroyed without finish()
  REQUIRE(::access(path.c_str(), F_OK) != 0);
  REQUIRE(::access((path + ".tmp").c_str(), F_OK) != 0);
}
