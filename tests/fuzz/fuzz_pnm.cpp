// libFuzzer harness: the PGM/PPM reader (hal/io/pnm.cpp), directly and through the format-sniffing
// GrayImageDecoder. Invariants: a parsed header is within the readers' limits and points inside
// the data; both decode paths agree; a binary 8-bit PGM decodes to its own bytes; a view of the
// wrong size is refused.
#include <string>
#include <vector>

#include "algo/image/image.hpp"
#include "hal/io/image_codec.hpp"
#include "tests/fuzz/fuzz_support.hpp"

namespace hal = epitrack::hal;
using epitrack::Image;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  hal::ImageHeader header;
  std::size_t data_offset = 0;
  std::string error;
  const bool parsed = hal::parsePnmHeader(data, size, header, data_offset, error);
  if (!parsed) {
    FUZZ_CHECK(!error.empty());
    return 0;
  }
  FUZZ_CHECK(header.width >= 1 && header.width <= hal::kMaxImageDimension);
  FUZZ_CHECK(header.height >= 1 && header.height <= hal::kMaxImageDimension);
  FUZZ_CHECK(header.channels == 1 || header.channels == 3);
  FUZZ_CHECK(data_offset <= size);
  if (!epitrack::fuzz::smallEnough(header.width, header.height)) return 0;

  Image<uint8_t> direct(header.width, header.height);
  const bool decoded = hal::decodePnm(data, size, direct.view(), error);

  hal::GrayImageDecoder decoder;
  Image<uint8_t> sniffed;
  std::string sniff_error;
  const bool sniff_decoded = decoder.decode(data, size, sniffed, sniff_error);
  FUZZ_CHECK(decoded == sniff_decoded);
  if (decoded) FUZZ_CHECK(epitrack::fuzz::sameView(direct.constView(), sniffed.constView()));

  // The writer round-trips what the reader produced (encodePgm, then decodePnm).
  if (decoded) {
    std::vector<uint8_t> encoded;
    hal::encodePgm(direct.constView(), encoded);
    Image<uint8_t> again(header.width, header.height);
    FUZZ_CHECK(hal::decodePnm(encoded.data(), encoded.size(), again.view(), error));
    FUZZ_CHECK(epitrack::fuzz::sameView(direct.constView(), again.constView()));
  }

  // A view of another size is refused, never written past.
  Image<uint8_t> wrong(header.width + 1, header.height);
  FUZZ_CHECK(!hal::decodePnm(data, size, wrong.view(), error));
  return 0;
}
