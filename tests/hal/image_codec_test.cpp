#include "hal/io/image_codec.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>

#include "hal/io/file_util.hpp"
#include "tests/support/test_support.hpp"
#include "tools/synth/synthetic_sequence.hpp"

using epitrack::Image;
namespace hal = epitrack::hal;

namespace {

// Hand-made PNGs (Python zlib + struct): 4x3 8-bit gray and 2x2 8-bit RGB, no filter.
const uint8_t kGrayPng[] = {
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52,
    0x00, 0x00, 0x00, 0x04, 0x00, 0x00, 0x00, 0x03, 0x08, 0x00, 0x00, 0x00, 0x00, 0x91, 0x9f, 0xf1,
    0x1a, 0x00, 0x00, 0x00, 0x17, 0x49, 0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0x60, 0x10, 0x6c, 0xf8,
    0xcf, 0xc0, 0xc8, 0xc4, 0xcc, 0xc2, 0xf0, 0x2b, 0xc5, 0x48, 0x12, 0x00, 0x17, 0xb8, 0x03, 0x44,
    0x89, 0x01, 0x19, 0x5d, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};
const uint8_t kGrayPixels[3][4] = {{0, 17, 128, 255}, {1, 2, 3, 4}, {250, 100, 50, 25}};
const uint8_t kRgbPng[] = {
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52,
    0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x02, 0x08, 0x02, 0x00, 0x00, 0x00, 0xfd, 0xd4, 0x9a,
    0x73, 0x00, 0x00, 0x00, 0x13, 0x49, 0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0xf8, 0xcf, 0xc0, 0xc0,
    0x00, 0xc2, 0x0c, 0xff, 0xb9, 0x44, 0xe4, 0x00, 0x1a, 0x58, 0x03, 0x3a, 0x56, 0x63, 0xa2, 0x3c,
    0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};

Image<uint8_t> syntheticFrame(int w, int h) {
  epitrack::synth::SynthOptions o;
  o.width = w;
  o.height = h;
  o.focal = 0.85 * w;
  o.frames = 1;
  const epitrack::synth::SyntheticSequence seq(o);
  epitrack::synth::FrameRenderer r(seq);
  Image<uint8_t> img;
  r.render(0, img);
  return img;
}

}  // namespace

TEST_CASE("A hand-made gray PNG decodes exactly", "[hal][png]") {
  hal::GrayImageDecoder dec;
  Image<uint8_t> img;
  std::string err;
  REQUIRE(dec.decode(kGrayPng, sizeof(kGrayPng), img, err));
  REQUIRE(img.width() == 4);
  REQUIRE(img.height() == 3);
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 4; ++x) REQUIRE(img(x, y) == kGrayPixels[y][x]);
}

TEST_CASE("An RGB PNG decodes to BT.601 luma", "[hal][png]") {
  hal::GrayImageDecoder dec;
  Image<uint8_t> img;
  std::string err;
  REQUIRE(dec.decode(kRgbPng, sizeof(kRgbPng), img, err));
  REQUIRE(img.width() == 2);
  REQUIRE(img(0, 0) == 76);   // 0.299 * 255
  REQUIRE(img(1, 0) == 150);  // 0.587 * 255
  REQUIRE(img(0, 1) == 29);   // 0.114 * 255
  REQUIRE(img(1, 1) == hal::rgbToLuma(10, 20, 30));
  REQUIRE(img(1, 1) == 18);
}

TEST_CASE("PGM round-trips exactly and binary/ASCII PNM variants decode", "[hal][pnm]") {
  Image<uint8_t> frame = syntheticFrame(97, 61);
  std::vector<uint8_t> bytes;
  hal::encodePgm(frame.constView(), bytes);
  hal::GrayImageDecoder dec;
  Image<uint8_t> back;
  std::string err;
  REQUIRE(dec.decode(bytes.data(), bytes.size(), back, err));
  for (int y = 0; y < 61; ++y)
    for (int x = 0; x < 97; ++x) REQUIRE(back(x, y) == frame(x, y));

  const std::string ascii = "P2\n# comment\n3 2\n255\n0 1 2\n253 254 255\n";
  REQUIRE(dec.decode(reinterpret_cast<const uint8_t*>(ascii.data()), ascii.size(), back, err));
  REQUIRE(back(2, 1) == 255);
  REQUIRE(back(1, 0) == 1);
  const std::string p6 = std::string("P6 1 1 255\n") + std::string("\xff\x00\x00", 3);
  REQUIRE(dec.decode(reinterpret_cast<const uint8_t*>(p6.data()), p6.size(), back, err));
  REQUIRE(back(0, 0) == 76);
  const std::string p5_16 = std::string("P5 1 1 65535\n") + std::string("\x80\x00", 2);
  REQUIRE(dec.decode(reinterpret_cast<const uint8_t*>(p5_16.data()), p5_16.size(), back, err));
  REQUIRE(back(0, 0) == 128);
}

TEST_CASE("JPEG round-trips within a stated error (q95: mean |e| < 2, max < 16)", "[hal][jpeg]") {
  Image<uint8_t> frame = syntheticFrame(160, 120);
  hal::JpegEncoder enc;
  std::string err;
  REQUIRE(enc.encodeGray(frame.constView(), 95, err));
  hal::GrayImageDecoder dec;
  Image<uint8_t> back;
  REQUIRE(dec.decode(enc.data(), enc.size(), back, err));
  REQUIRE(back.width() == 160);
  double sum = 0;
  int worst = 0;
  for (int y = 0; y < 120; ++y) {
    for (int x = 0; x < 160; ++x) {
      const int e = std::abs(back(x, y) - frame(x, y));
      sum += e;
      worst = std::max(worst, e);
    }
  }
  const double mean = sum / (160.0 * 120.0);
  INFO("mean " << mean << " max " << worst);
  std::printf("JPEG q95 round trip: mean |e| %.3f, max %d\n", mean, worst);
  REQUIRE(mean < 2.0);  // measured 1.63 on this sharp-edged texture
  REQUIRE(worst < 16);  // measured 9

  // Colour JPEG decodes straight to luma.
  std::vector<uint8_t> rgb(static_cast<std::size_t>(160 * 120 * 3));
  for (int y = 0; y < 120; ++y)
    for (int x = 0; x < 160; ++x)
      for (int c = 0; c < 3; ++c)
        rgb[static_cast<std::size_t>((y * 160 + x) * 3 + c)] = frame(x, y);
  REQUIRE(enc.encodeRgb(rgb.data(), 160, 120, 160 * 3, 95, err));
  REQUIRE(dec.decode(enc.data(), enc.size(), back, err));
  sum = 0;
  for (int y = 0; y < 120; ++y)
    for (int x = 0; x < 160; ++x) sum += std::abs(back(x, y) - frame(x, y));
  REQUIRE(sum / (160.0 * 120.0) < 2.0);
}

TEST_CASE("Truncated and non-image data give clear errors", "[hal][errors]") {
  hal::GrayImageDecoder dec;
  Image<uint8_t> img;
  std::string err;
  SECTION("truncated PNG") {
    REQUIRE_FALSE(dec.decode(kGrayPng, 50, img, err));
    REQUIRE(err.find("PNG") != std::string::npos);
  }
  SECTION("truncated PGM") {
    const std::string p = "P5 10 10 255\n" + std::string(50, 'a');
    REQUIRE_FALSE(dec.decode(reinterpret_cast<const uint8_t*>(p.data()), p.size(), img, err));
    REQUIRE(err.find("truncated") != std::string::npos);
  }
  SECTION("truncated JPEG") {
    Image<uint8_t> frame = syntheticFrame(64, 48);
    hal::JpegEncoder enc;
    REQUIRE(enc.encodeGray(frame.constView(), 90, err));
    REQUIRE_FALSE(dec.decode(enc.data(), enc.size() / 2, img, err));
    REQUIRE(err.find("JPEG") != std::string::npos);
  }
  SECTION("text file") {
    const std::string t = "hello, I am not an image\n";
    REQUIRE_FALSE(dec.decode(reinterpret_cast<const uint8_t*>(t.data()), t.size(), img, err));
    REQUIRE(err.find("not an image") != std::string::npos);
  }
  SECTION("empty") {
    REQUIRE_FALSE(dec.decode(kGrayPng, 0, img, err));
    REQUIRE(err.find("empty") != std::string::npos);
  }
  SECTION("absurd PNM size") {
    const std::string p = "P5 99999 99999 255\n";
    REQUIRE_FALSE(dec.decode(reinterpret_cast<const uint8_t*>(p.data()), p.size(), img, err));
    REQUIRE(err.find("outside") != std::string::npos);
  }
  SECTION("missing file names the file") {
    REQUIRE_FALSE(dec.decodeFile("/nonexistent/frame.png", img, err));
    REQUIRE(err.find("/nonexistent/frame.png") != std::string::npos);
  }
}

// One test case per sequence: a missing sequence skips only its own case.
TEST_CASE("Real sequences decode: KITTI PNG", "[hal][data]") {
  if (!epitrack::test::haveSharedSequence("kitti_seq06_excerpt")) return;
  hal::GrayImageDecoder dec;
  Image<uint8_t> img;
  std::string err;
  REQUIRE(dec.decodeFile(epitrack::test::sharedDataDir() + "/kitti_seq06_excerpt/frames/000000.png",
                         img, err));
  REQUIRE(img.width() == 1226);
  REQUIRE(img.height() == 370);
}

TEST_CASE("Real sequences decode: TUM JPEG", "[hal][data]") {
  if (!epitrack::test::haveSharedSequence("tum_fr3_cabinet_keyframes")) return;
  hal::GrayImageDecoder dec;
  Image<uint8_t> img;
  std::string err;
  REQUIRE(dec.decodeFile(
      epitrack::test::sharedDataDir() + "/tum_fr3_cabinet_keyframes/frames/000000.jpg", img, err));
  REQUIRE(img.width() == 640);
  REQUIRE(img.height() == 480);
  double mean = 0;
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x) mean += img(x, y);
  mean /= 640.0 * 480.0;
  REQUIRE(mean > 20.0);  // a real picture, not a black buffer
  REQUIRE(mean < 235.0);
}
