// PGM/PPM (Netpbm) reading and writing. Formats: P2/P5 gray, P3/P6 colour, maxval 1..65535
// (two bytes per sample, big-endian, above 255), per the Netpbm specification.
#include <cstring>
#include <string>

#include "hal/io/image_codec.hpp"

namespace epitrack::hal {
namespace {

// Skips white space and '#' comments; returns false at the end of the data.
bool skipSpace(const uint8_t* d, std::size_t n, std::size_t& i) {
  while (i < n) {
    if (d[i] == '#') {
      while (i < n && d[i] != '\n' && d[i] != '\r') ++i;
    } else if (d[i] == ' ' || d[i] == '\t' || d[i] == '\n' || d[i] == '\r' || d[i] == '\v' ||
               d[i] == '\f') {
      ++i;
    } else {
      return true;
    }
  }
  return false;
}

bool readUnsigned(const uint8_t* d, std::size_t n, std::size_t& i, long& value) {
  if (!skipSpace(d, n, i) || d[i] < '0' || d[i] > '9') return false;
  value = 0;
  while (i < n && d[i] >= '0' && d[i] <= '9') {
    value = value * 10 + (d[i] - '0');
    if (value > 1000000) return false;
    ++i;
  }
  return true;
}

uint8_t scaleSample(long v, long maxval) {
  if (v > maxval) v = maxval;
  return static_cast<uint8_t>((v * 255 + maxval / 2) / maxval);
}

}  // namespace

bool parsePnmHeader(const uint8_t* data, std::size_t size, ImageHeader& header,
                    std::size_t& data_offset, std::string& error) {
  if (size < 2 || data[0] != 'P' ||
      (data[1] != '2' && data[1] != '3' && data[1] != '5' && data[1] != '6')) {
    error = "not a PGM/PPM file (no P2/P3/P5/P6 magic)";
    return false;
  }
  std::size_t i = 2;
  long w = 0;
  long h = 0;
  long maxval = 0;
  if (!readUnsigned(data, size, i, w) || !readUnsigned(data, size, i, h) ||
      !readUnsigned(data, size, i, maxval)) {
    error = "truncated or malformed PNM header";
    return false;
  }
  if (w <= 0 || h <= 0 || w > kMaxImageDimension || h > kMaxImageDimension) {
    error = "PNM size " + std::to_string(w) + "x" + std::to_string(h) + " outside 1.." +
            std::to_string(kMaxImageDimension);
    return false;
  }
  if (maxval < 1 || maxval > 65535) {
    error = "PNM maxval " + std::to_string(maxval) + " outside 1..65535";
    return false;
  }
  if (i >= size) {
    error = "PNM file has no pixel data";
    return false;
  }
  ++i;  // exactly one white-space byte ends the header
  header.width = static_cast<int>(w);
  header.height = static_cast<int>(h);
  header.channels = (data[1] == '3' || data[1] == '6') ? 3 : 1;
  header.format = ImageFormat::kPnm;
  data_offset = i;
  return true;
}

bool decodePnm(const uint8_t* data, std::size_t size, ImageView<uint8_t> out, std::string& error) {
  ImageHeader hdr;
  std::size_t off = 0;
  if (!parsePnmHeader(data, size, hdr, off, error)) return false;
  if (hdr.width != out.width || hdr.height != out.height) {
    error = "PNM is " + std::to_string(hdr.width) + "x" + std::to_string(hdr.height) +
            ", expected " + std::to_string(out.width) + "x" + std::to_string(out.height);
    return false;
  }
  long maxval = 0;
  {
    std::size_t i = 2;
    long dummy = 0;
    readUnsigned(data, size, i, dummy);
    readUnsigned(data, size, i, dummy);
    readUnsigned(data, size, i, maxval);
  }
  const bool ascii = data[1] == '2' || data[1] == '3';
  const int c = hdr.channels;
  if (ascii) {
    std::size_t i = off;
    for (int y = 0; y < hdr.height; ++y) {
      uint8_t* row = out.row(y);
      for (int x = 0; x < hdr.width; ++x) {
        long s[3] = {0, 0, 0};
        for (int k = 0; k < c; ++k) {
          if (!readUnsigned(data, size, i, s[k])) {
            error = "truncated ASCII PNM data at row " + std::to_string(y);
            return false;
          }
        }
        row[x] = c == 1 ? scaleSample(s[0], maxval)
                        : rgbToLuma(scaleSample(s[0], maxval), scaleSample(s[1], maxval),
                                    scaleSample(s[2], maxval));
      }
    }
    return true;
  }
  const std::size_t bps = maxval > 255 ? 2 : 1;
  const std::size_t need = static_cast<std::size_t>(hdr.width) *
                           static_cast<std::size_t>(hdr.height) * static_cast<std::size_t>(c) * bps;
  if (size - off < need) {
    error = "truncated PNM: " + std::to_string(size - off) + " of " + std::to_string(need) +
            " pixel bytes";
    return false;
  }
  const uint8_t* p = data + off;
  for (int y = 0; y < hdr.height; ++y) {
    uint8_t* row = out.row(y);
    if (c == 1 && bps == 1 && maxval == 255) {
      std::memcpy(row, p, static_cast<std::size_t>(hdr.width));
      p += hdr.width;
      continue;
    }
    for (int x = 0; x < hdr.width; ++x) {
      long s[3] = {0, 0, 0};
      for (int k = 0; k < c; ++k) {
        s[k] = bps == 1 ? p[0] : (static_cast<long>(p[0]) << 8 | p[1]);
        p += bps;
      }
      row[x] = c == 1 ? scaleSample(s[0], maxval)
                      : rgbToLuma(scaleSample(s[0], maxval), scaleSample(s[1], maxval),
                                  scaleSample(s[2], maxval));
    }
  }
  return true;
}

void encodePgm(ImageView<const uint8_t> image, std::vector<uint8_t>& out) {
  const std::string header =
      "P5\n" + std::to_string(image.width) + " " + std::to_string(image.height) + "\n255\n";
  out.resize(header.size() +
             static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height));
  std::memcpy(out.data(), header.data(), header.size());
  uint8_t* p = out.data() + header.size();
  for (int y = 0; y < image.height; ++y) {
    std::memcpy(p, image.row(y), static_cast<std::size_t>(image.width));
    p += image.width;
  }
}

void encodePpm(const uint8_t* rgb, int width, int height, std::ptrdiff_t stride_bytes,
               std::vector<uint8_t>& out) {
  const std::string header =
      "P6\n" + std::to_string(width) + " " + std::to_string(height) + "\n255\n";
  const std::size_t row = static_cast<std::size_t>(width) * 3;
  out.resize(header.size() + row * static_cast<std::size_t>(height));
  std::memcpy(out.data(), header.data(), header.size());
  for (int y = 0; y < height; ++y) {
    std::memcpy(out.data() + header.size() + row * static_cast<std::size_t>(y),
                rgb + stride_bytes * y, row);
  }
}

}  // namespace epitrack::hal
