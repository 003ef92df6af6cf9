#include "hal/replay/jpeg_stream.hpp"

#include <cstring>

namespace epitrack::hal {

std::size_t findJpegStart(const uint8_t* data, std::size_t size, std::size_t from) {
  while (from + 3 <= size) {
    const void* hit = std::memchr(data + from, 0xFF, size - from - 2);
    if (hit == nullptr) return size;
    const auto at = static_cast<std::size_t>(static_cast<const uint8_t*>(hit) - data);
    if (data[at + 1] == 0xD8 && data[at + 2] == 0xFF) return at;
    from = at + 1;
  }
  return size;
}

JpegExtent measureJpeg(const uint8_t* data, std::size_t size, std::size_t& length) {
  if (size < 2) return JpegExtent::kTruncated;
  if (data[0] != 0xFF || data[1] != 0xD8) return JpegExtent::kMalformed;
  std::size_t pos = 2;
  for (;;) {
    // A marker: one or more FF fill bytes, then the code.
    if (pos >= size) return JpegExtent::kTruncated;
    if (data[pos] != 0xFF) return JpegExtent::kMalformed;
    while (pos < size && data[pos] == 0xFF) ++pos;
    if (pos >= size) return JpegExtent::kTruncated;
    const uint8_t code = data[pos++];
    if (code == 0xD9) {  // EOI
      length = pos;
      return JpegExtent::kComplete;
    }
    if (code == 0x00 || code == 0xD8) return JpegExtent::kMalformed;
    if (code == 0x01 || (code >= 0xD0 && code <= 0xD7)) continue;  // TEM, RSTn: no length
    if (pos + 2 > size) return JpegExtent::kTruncated;
    const std::size_t segment = (static_cast<std::size_t>(data[pos]) << 8) | data[pos + 1];
    if (segment < 2) return JpegExtent::kMalformed;
    pos += segment;
    if (pos > size) return JpegExtent::kTruncated;
    if (code != 0xDA) continue;  // not SOS
    // Entropy-coded data up to the next marker that is not stuffing (FF 00) or RSTn.
    for (;;) {
      const void* hit = pos < size ? std::memchr(data + pos, 0xFF, size - pos) : nullptr;
      if (hit == nullptr) return JpegExtent::kTruncated;
      pos = static_cast<std::size_t>(static_cast<const uint8_t*>(hit) - data);
      std::size_t next = pos + 1;
      while (next < size && data[next] == 0xFF) ++next;  // fill bytes
      if (next >= size) return JpegExtent::kTruncated;
      const uint8_t c = data[next];
      if (c == 0x00 || (c >= 0xD0 && c <= 0xD7)) {
        pos = next + 1;
        continue;
      }
      pos = next - 1;  // the marker's last FF; the outer loop reads the code
      break;
    }
  }
}

}  // namespace epitrack::hal
