#include "tests/hal/replay_test_helpers.hpp"

#include <cstdlib>
#include <cstring>

#include "hal/io/image_codec.hpp"
#include "tools/synth/synthetic_sequence.hpp"

namespace epitrack::test {

std::vector<Image<uint8_t>> syntheticFrames(int width, int height, int count) {
  synth::SynthOptions o;
  o.width = width;
  o.height = height;
  o.focal = 0.85 * width;
  o.frames = count;
  o.noise_sigma = 1.0;
  o.seed = 7;
  const synth::SyntheticSequence seq(o);
  synth::FrameRenderer renderer(seq);
  std::vector<Image<uint8_t>> frames(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i) renderer.render(i, frames[static_cast<std::size_t>(i)]);
  return frames;
}

namespace {

void append(std::vector<uint8_t>& out, const std::string& text) {
  out.insert(out.end(), text.begin(), text.end());
}

}  // namespace

std::vector<uint8_t> makeY4m(const std::vector<Image<uint8_t>>& frames, const std::string& chroma,
                             int fps_num, int fps_den) {
  const int w = frames.front().width();
  const int h = frames.front().height();
  int depth = 8;
  const std::size_t p = chroma.rfind('p');
  if (p != std::string::npos && p + 1 < chroma.size() && chroma[p + 1] >= '0' &&
      chroma[p + 1] <= '9') {
    depth = std::atoi(chroma.c_str() + p + 1);  // 420p10, 444p16
  } else if (chroma == "mono16") {
    depth = 16;
  }
  int planes = 2;
  int sx = 1;
  int sy = 1;
  bool alpha = false;
  if (chroma.rfind("mono", 0) == 0) planes = 0;
  if (chroma.rfind("422", 0) == 0) sy = 0;
  if (chroma.rfind("444", 0) == 0) sx = sy = 0;
  if (chroma.rfind("411", 0) == 0) {
    sx = 2;
    sy = 0;
  }
  if (chroma == "444alpha") alpha = true;
  const std::size_t cw = (static_cast<std::size_t>(w) + (1u << sx) - 1) >> sx;
  const std::size_t ch = (static_cast<std::size_t>(h) + (1u << sy) - 1) >> sy;
  const std::size_t other = static_cast<std::size_t>(planes) * cw * ch +
                            (alpha ? static_cast<std::size_t>(w) * static_cast<std::size_t>(h) : 0);
  std::vector<uint8_t> out;
  append(out, "YUV4MPEG2 W" + std::to_string(w) + " H" + std::to_string(h) + " F" +
                  std::to_string(fps_num) + ":" + std::to_string(fps_den) + " Ip A1:1 C" + chroma +
                  " XYSCSS=TEST\n");
  for (std::size_t i = 0; i < frames.size(); ++i) {
    append(out, i % 2 == 0 ? "FRAME\n" : "FRAME Ixyz\n");  // frame tags are allowed
    const Image<uint8_t>& f = frames[i];
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const unsigned v = f(x, y);
        if (depth == 8) {
          out.push_back(static_cast<uint8_t>(v));
        } else {  // little-endian, the 8 bits on top plus some low bits that must be dropped
          const unsigned wide =
              (v << (depth - 8)) | ((static_cast<unsigned>(x) * 7u) & ((1u << (depth - 8)) - 1u));
          out.push_back(static_cast<uint8_t>(wide & 0xFF));
          out.push_back(static_cast<uint8_t>(wide >> 8));
        }
      }
    }
    const std::size_t bytes = other * (depth > 8 ? 2 : 1);
    for (std::size_t k = 0; k < bytes; ++k) out.push_back(static_cast<uint8_t>(k * 13 + i));
  }
  return out;
}

std::vector<uint8_t> makeMjpeg(const std::vector<Image<uint8_t>>& frames, int quality,
                               std::vector<std::size_t>* offsets) {
  hal::JpegEncoder encoder;
  std::vector<uint8_t> out;
  std::string error;
  for (const Image<uint8_t>& f : frames) {
    if (!encoder.encodeGray(f.constView(), quality, error)) std::abort();
    if (offsets != nullptr) offsets->push_back(out.size());
    out.insert(out.end(), encoder.data(), encoder.data() + encoder.size());
  }
  return out;
}

ImageDifference imageDifference(ImageView<const uint8_t> a, ImageView<const uint8_t> b) {
  ImageDifference d;
  double sum = 0.0;
  for (int y = 0; y < a.height; ++y) {
    for (int x = 0; x < a.width; ++x) {
      const int e = std::abs(static_cast<int>(a(x, y)) - static_cast<int>(b(x, y)));
      d.max_abs = std::max(d.max_abs, e);
      sum += e;
    }
  }
  d.mean_abs = sum / (static_cast<double>(a.width) * a.height);
  return d;
}

bool sameImage(ImageView<const uint8_t> a, ImageView<const uint8_t> b) {
  if (a.width != b.width || a.height != b.height) return false;
  for (int y = 0; y < a.height; ++y) {
    if (std::memcmp(a.row(y), b.row(y), static_cast<std::size_t>(a.width)) != 0) return false;
  }
  return true;
}

}  // namespace epitrack::test
