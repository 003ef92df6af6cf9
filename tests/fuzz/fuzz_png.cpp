// libFuzzer harness: the PNG reader (hal/io/png_codec.cpp, libpng from memory: header, any bit
// depth, gray/RGB/palette, alpha dropped, interlaced) directly and through GrayImageDecoder.
// Mutated chunks would almost always fail libpng's CRC check before reaching the decoder, so the
// harness decodes a copy whose chunk CRCs are recomputed (the reader itself is unchanged).
// Invariants: a header is within the readers' limits; both decode paths agree; a view of the
// wrong size is refused; decoding twice with the same scratch buffer gives the same image.
#include <cstring>
#include <string>
#include <vector>

#include <zlib.h>

#include "algo/image/image.hpp"
#include "hal/io/image_codec.hpp"
#include "tests/fuzz/fuzz_support.hpp"

namespace hal = epitrack::hal;
using epitrack::Image;

namespace {

uint32_t readBigEndian32(const uint8_t* p) {
  return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | uint32_t{p[3]};
}

/// Rewrites the CRC of every complete chunk (length, type, data, CRC) after the signature.
void fixChunkCrcs(std::vector<uint8_t>& png) {
  std::size_t pos = 8;
  while (pos + 12 <= png.size()) {
    const uint32_t length = readBigEndian32(png.data() + pos);
    if (length > png.size() - pos - 12) break;
    const uLong crc = crc32(crc32(0L, Z_NULL, 0), png.data() + pos + 4, length + 4);
    uint8_t* out = png.data() + pos + 8 + length;
    out[0] = static_cast<uint8_t>(crc >> 24);
    out[1] = static_cast<uint8_t>(crc >> 16);
    out[2] = static_cast<uint8_t>(crc >> 8);
    out[3] = static_cast<uint8_t>(crc);
    pos += 12 + length;
  }
}

void decodeAndCheck(const uint8_t* data, std::size_t size) {
  hal::ImageHeader header;
  std::string error;
  if (!hal::readPngHeader(data, size, header, error)) {
    FUZZ_CHECK(!error.empty());
    return;
  }
  FUZZ_CHECK(header.width >= 1 && header.width <= hal::kMaxImageDimension);
  FUZZ_CHECK(header.height >= 1 && header.height <= hal::kMaxImageDimension);
  FUZZ_CHECK(header.channels == 1 || header.channels == 3);
  if (!epitrack::fuzz::smallEnough(header.width, header.height)) return;

  static hal::PngScratch scratch;  // reused across calls, as GrayImageDecoder does
  Image<uint8_t> direct(header.width, header.height);
  const bool decoded = hal::decodePng(data, size, direct.view(), scratch, error);
  if (!decoded) FUZZ_CHECK(!error.empty());

  static hal::GrayImageDecoder gray_decoder;
  Image<uint8_t> sniffed;
  std::string sniff_error;
  FUZZ_CHECK(gray_decoder.decode(data, size, sniffed, sniff_error) == decoded);
  if (decoded) FUZZ_CHECK(epitrack::fuzz::sameView(direct.constView(), sniffed.constView()));

  Image<uint8_t> wrong(header.width + 1, header.height + 1);
  FUZZ_CHECK(!hal::decodePng(data, size, wrong.view(), scratch, error));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  decodeAndCheck(data, size);  // as given (CRC errors included)
  if (size < 8 || std::memcmp(data, "\x89PNG\r\n\x1a\n", 8) != 0) return 0;
  std::vector<uint8_t> fixed(data, data + size);
  fixChunkCrcs(fixed);
  if (std::memcmp(fixed.data(), data, size) != 0) decodeAndCheck(fixed.data(), fixed.size());
  return 0;
}
