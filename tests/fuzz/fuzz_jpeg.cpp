// libFuzzer harness: the JPEG path — the TurboJPEG wrapper (hal/io/jpeg_codec.cpp: header, gray
// decode with warnings as errors), the format-sniffing GrayImageDecoder, and the JPEG marker walk
// that splits MJPEG streams (hal/replay/jpeg_stream.cpp). Invariants: a header is within the
// readers' limits; both decode paths agree; a view of the wrong size is refused; a complete JPEG
// measured by the marker walk ends with EOI inside the data; the SOI search stays in bounds.
#include <string>

#include "algo/image/image.hpp"
#include "hal/io/image_codec.hpp"
#include "hal/replay/jpeg_stream.hpp"
#include "tests/fuzz/fuzz_support.hpp"

namespace hal = epitrack::hal;
using epitrack::Image;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  // The marker walk on any bytes.
  std::size_t length = 0;
  const hal::JpegExtent extent = hal::measureJpeg(data, size, length);
  if (extent == hal::JpegExtent::kComplete) {
    FUZZ_CHECK(length >= 4 && length <= size);
    FUZZ_CHECK(data[length - 2] == 0xFF && data[length - 1] == 0xD9);
  }
  for (std::size_t from = 0, count = 0; from < size && count < 64; ++count) {
    const std::size_t start = hal::findJpegStart(data, size, from);
    FUZZ_CHECK(start <= size);
    if (start == size) break;
    FUZZ_CHECK(start + 3 <= size && data[start] == 0xFF && data[start + 1] == 0xD8 &&
               data[start + 2] == 0xFF);
    from = start + 1;
  }

  // One decoder for all inputs, as a replay source keeps one for a clip.
  static hal::JpegDecoder decoder;
  FUZZ_CHECK(decoder.valid());
  hal::ImageHeader header;
  std::string error;
  if (!decoder.readHeader(data, size, header, error)) {
    FUZZ_CHECK(!error.empty());
    return 0;
  }
  FUZZ_CHECK(header.width >= 1 && header.width <= hal::kMaxImageDimension);
  FUZZ_CHECK(header.height >= 1 && header.height <= hal::kMaxImageDimension);
  FUZZ_CHECK(header.format == hal::ImageFormat::kJpeg);
  if (!epitrack::fuzz::smallEnough(header.width, header.height)) return 0;

  Image<uint8_t> direct(header.width, header.height);
  const bool decoded = decoder.decodeGray(data, size, direct.view(), error);
  if (!decoded) FUZZ_CHECK(!error.empty());

  if (hal::sniffImageFormat(data, size) == hal::ImageFormat::kJpeg) {
    static hal::GrayImageDecoder gray_decoder;
    Image<uint8_t> sniffed;
    std::string sniff_error;
    FUZZ_CHECK(gray_decoder.decode(data, size, sniffed, sniff_error) == decoded);
    if (decoded) FUZZ_CHECK(epitrack::fuzz::sameView(direct.constView(), sniffed.constView()));
  }

  Image<uint8_t> wrong(header.width, header.height + 1);
  FUZZ_CHECK(!decoder.decodeGray(data, size, wrong.view(), error));
  return 0;
}
