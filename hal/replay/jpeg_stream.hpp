#pragma once

#include <cstddef>
#include <cstdint>

namespace epitrack::hal {

/// Outcome of measuring one JPEG inside a byte stream.
enum class JpegExtent {
  kComplete,   ///< `length` bytes from SOI to EOI inclusive
  kTruncated,  ///< the data ends before EOI
  kMalformed,  ///< no SOI at the start, or a marker segment that cannot be parsed
};

/// Measures the JPEG that starts at `data` (which should hold FF D8): walks the marker segments by
/// their lengths (so an embedded EXIF thumbnail does not end the frame early) and the
/// entropy-coded data of each scan (FF 00 stuffing, RSTn, fill bytes) until EOI (ITU-T T.81
/// §B.1.1). `length` receives the byte count of a complete JPEG.
JpegExtent measureJpeg(const uint8_t* data, std::size_t size, std::size_t& length);

/// Offset of the next SOI (FF D8 FF) at or after `from`, or `size` when there is none.
std::size_t findJpegStart(const uint8_t* data, std::size_t size, std::size_t from);

}  // namespace epitrack::hal
