#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "algo/image/image.hpp"
#include "algo/image/image_view.hpp"

namespace epitrack::hal {

enum class ImageFormat { kUnknown, kPnm, kPng, kJpeg };

/// Largest accepted width or height of a decoded image (larger headers are refused before any
/// pixel memory is touched).
inline constexpr int kMaxImageDimension = 16384;

struct ImageHeader {
  int width = 0;
  int height = 0;
  int channels = 0;  ///< 1 gray, 3 colour (after palette expansion, alpha ignored)
  ImageFormat format = ImageFormat::kUnknown;
};

/// The format from the first bytes (magic numbers), kUnknown when none matches.
ImageFormat sniffImageFormat(const uint8_t* data, std::size_t size);
const char* imageFormatName(ImageFormat format);

/// BT.601 luma of an 8-bit RGB triple, 16-bit fixed point: Y = (19595 R + 38470 G + 7471 B
/// + 2^15) >> 16 (the weights 0.299, 0.587, 0.114 sum exactly to 2^16).
[[nodiscard]] inline uint8_t rgbToLuma(uint32_t r, uint32_t g, uint32_t b) {
  return static_cast<uint8_t>((19595u * r + 38470u * g + 7471u * b + 32768u) >> 16);
}

// -- PNM (pnm.cpp) -----------------------------------------------------------------------------
/// Parses a PGM/PPM header (P2, P3, P5, P6; maxval up to 65535). `data_offset` receives the first
/// pixel byte (binary) or sample (ASCII) position.
bool parsePnmHeader(const uint8_t* data, std::size_t size, ImageHeader& header,
                    std::size_t& data_offset, std::string& error);
/// Decodes a PGM/PPM into `out` (which must have the header's size), colour to luma.
bool decodePnm(const uint8_t* data, std::size_t size, ImageView<uint8_t> out, std::string& error);
/// Encodes 8-bit gray as binary PGM (P5).
void encodePgm(ImageView<const uint8_t> image, std::vector<uint8_t>& out);
/// Encodes interleaved 8-bit RGB as binary PPM (P6); `stride_bytes` between rows.
void encodePpm(const uint8_t* rgb, int width, int height, std::ptrdiff_t stride_bytes,
               std::vector<uint8_t>& out);

// -- PNG (png_codec.cpp, libpng) -----------------------------------------------------------------
bool readPngHeader(const uint8_t* data, std::size_t size, ImageHeader& header, std::string& error);
/// What decodePng keeps between calls, so that decoding frames of one size stops allocating.
struct PngScratch {
  /// One row of the widest layout (colour), or the whole image when it is interlaced.
  std::vector<uint8_t> pixels;
  /// Interlaced images only: the start of each row in `pixels` (libpng's png_bytep array; a
  /// vector of the pointer type rather than pointers stored in the byte buffer, which would need
  /// a cast to a more aligned type).
  std::vector<uint8_t*> rows;
};
/// Decodes a PNG (any bit depth, gray/RGB/palette, alpha dropped, 16 bits reduced to 8) into
/// `out` (the header's size), with buffers from `scratch` (resized as needed).
bool decodePng(const uint8_t* data, std::size_t size, ImageView<uint8_t> out, PngScratch& scratch,
               std::string& error);

// -- JPEG (jpeg_codec.cpp, libjpeg-turbo's TurboJPEG API) ----------------------------------------
/// TurboJPEG decompressor created once and reused; JPEG decodes straight to gray (the Y plane).
class JpegDecoder {
 public:
  JpegDecoder();
  ~JpegDecoder();
  JpegDecoder(const JpegDecoder&) = delete;
  JpegDecoder& operator=(const JpegDecoder&) = delete;

  [[nodiscard]] bool valid() const { return handle_ != nullptr; }
  bool readHeader(const uint8_t* data, std::size_t size, ImageHeader& header, std::string& error);
  /// Decodes into `out` (the header's size). A corrupt or truncated stream (TurboJPEG error or
  /// warning) is an error.
  bool decodeGray(const uint8_t* data, std::size_t size, ImageView<uint8_t> out,
                  std::string& error);

 private:
  void* handle_ = nullptr;
};

/// TurboJPEG compressor with an output buffer that grows only for a larger image.
class JpegEncoder {
 public:
  JpegEncoder();
  ~JpegEncoder();
  JpegEncoder(const JpegEncoder&) = delete;
  JpegEncoder& operator=(const JpegEncoder&) = delete;

  /// Encodes 8-bit gray; the result stays valid until the next call (`data()`, `size()`).
  bool encodeGray(ImageView<const uint8_t> image, int quality, std::string& error);
  /// Encodes interleaved RGB (4:2:0 chroma).
  bool encodeRgb(const uint8_t* rgb, int width, int height, std::ptrdiff_t stride_bytes,
                 int quality, std::string& error);
  [[nodiscard]] const uint8_t* data() const { return buffer_; }
  [[nodiscard]] std::size_t size() const { return size_; }

 private:
  bool ensureCapacity(int width, int height, int subsampling, std::string& error);
  void* handle_ = nullptr;
  uint8_t* buffer_ = nullptr;
  std::size_t capacity_ = 0;
  std::size_t size_ = 0;
};

// -- any format
// ------------------------------------------------------------------------------------
/// Decodes PGM/PPM, PNG and JPEG to 8-bit luma with reusable state (one TurboJPEG handle, one
/// file buffer, one row buffer): after the first frames of a clip it no longer allocates.
class GrayImageDecoder {
 public:
  bool readHeader(const uint8_t* data, std::size_t size, ImageHeader& header, std::string& error);
  /// Decodes into `out`, which must have the image's size; a different size is an error.
  bool decodeInto(const uint8_t* data, std::size_t size, ImageView<uint8_t> out,
                  std::string& error);
  /// Decodes into `out`, sizing it to the image.
  bool decode(const uint8_t* data, std::size_t size, Image<uint8_t>& out, std::string& error);
  /// Reads and decodes a file; error messages name the file.
  bool decodeFile(const std::string& path, Image<uint8_t>& out, std::string& error);
  /// Reads a file into the internal buffer and returns its header (for sizing before decoding).
  bool readFileHeader(const std::string& path, ImageHeader& header, std::string& error);
  /// Decodes the file last read by readFileHeader into `out`.
  bool decodeLastFile(ImageView<uint8_t> out, std::string& error);

 private:
  JpegDecoder jpeg_;
  std::vector<uint8_t> file_bytes_;
  PngScratch png_scratch_;
  std::string last_path_;
};

// -- writing
// -----------------------------------------------------------------------------------------
/// Writes binary PGM atomically (temporary file, then rename).
bool writePgm(const std::string& path, ImageView<const uint8_t> image, std::string& error);
/// Writes a gray JPEG atomically.
bool writeJpegGray(const std::string& path, ImageView<const uint8_t> image, int quality,
                   std::string& error);
/// Writes an RGB JPEG atomically.
bool writeJpegRgb(const std::string& path, const uint8_t* rgb, int width, int height,
                  std::ptrdiff_t stride_bytes, int quality, std::string& error);

}  // namespace epitrack::hal
