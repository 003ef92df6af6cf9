#include <cstring>
#include <string>

#include "hal/io/file_util.hpp"
#include "hal/io/image_codec.hpp"

namespace epitrack::hal {

ImageFormat sniffImageFormat(const uint8_t* data, std::size_t size) {
  if (size >= 8 && std::memcmp(data, "\x89PNG\r\n\x1a\n", 8) == 0) return ImageFormat::kPng;
  if (size >= 3 && data[0] == 0xFF && data[1] == 0xD8 && data[2] == 0xFF) return ImageFormat::kJpeg;
  if (size >= 2 && data[0] == 'P' &&
      (data[1] == '2' || data[1] == '3' || data[1] == '5' || data[1] == '6')) {
    return ImageFormat::kPnm;
  }
  return ImageFormat::kUnknown;
}

const char* imageFormatName(ImageFormat format) {
  switch (format) {
    case ImageFormat::kPnm:
      return "PNM";
    case ImageFormat::kPng:
      return "PNG";
    case ImageFormat::kJpeg:
      return "JPEG";
    case ImageFormat::kUnknown:
      break;
  }
  return "unknown";
}

bool GrayImageDecoder::readHeader(const uint8_t* data, std::size_t size, ImageHeader& header,
                                  std::string& error) {
  switch (sniffImageFormat(data, size)) {
    case ImageFormat::kPnm: {
      std::size_t off = 0;
      return parsePnmHeader(data, size, header, off, error);
    }
    case ImageFormat::kPng:
      return readPngHeader(data, size, header, error);
    case ImageFormat::kJpeg:
      return jpeg_.readHeader(data, size, header, error);
    case ImageFormat::kUnknown:
      break;
  }
  error = size == 0 ? "empty file" : "not an image (no PNG, JPEG or PGM/PPM signature)";
  return false;
}

bool GrayImageDecoder::decodeInto(const uint8_t* data, std::size_t size, ImageView<uint8_t> out,
                                  std::string& error) {
  switch (sniffImageFormat(data, size)) {
    case ImageFormat::kPnm:
      return decodePnm(data, size, out, error);
    case ImageFormat::kPng:
      return decodePng(data, size, out, png_scratch_, error);
    case ImageFormat::kJpeg:
      return jpeg_.decodeGray(data, size, out, error);
    case ImageFormat::kUnknown:
      break;
  }
  error = size == 0 ? "empty file" : "not an image (no PNG, JPEG or PGM/PPM signature)";
  return false;
}

bool GrayImageDecoder::decode(const uint8_t* data, std::size_t size, Image<uint8_t>& out,
                              std::string& error) {
  ImageHeader header;
  if (!readHeader(data, size, header, error)) return false;
  if (!out.allocate(header.width, header.height)) {
    error = "cannot allocate a " + std::to_string(header.width) + "x" +
            std::to_string(header.height) + " image";
    return false;
  }
  return decodeInto(data, size, out.view(), error);
}

bool GrayImageDecoder::readFileHeader(const std::string& path, ImageHeader& header,
                                      std::string& error) {
  last_path_ = path;
  if (!readFileInto(path, file_bytes_, error)) return false;
  if (!readHeader(file_bytes_.data(), file_bytes_.size(), header, error)) {
    error = "'" + path + "': " + error;
    return false;
  }
  return true;
}

bool GrayImageDecoder::decodeLastFile(ImageView<uint8_t> out, std::string& error) {
  if (!decodeInto(file_bytes_.data(), file_bytes_.size(), out, error)) {
    error = "'" + last_path_ + "': " + error;
    return false;
  }
  return true;
}

bool GrayImageDecoder::decodeFile(const std::string& path, Image<uint8_t>& out,
                                  std::string& error) {
  ImageHeader header;
  if (!readFileHeader(path, header, error)) return false;
  if (!out.allocate(header.width, header.height)) {
    error = "'" + path + "': cannot allocate the image";
    return false;
  }
  return decodeLastFile(out.view(), error);
}

bool writePgm(const std::string& path, ImageView<const uint8_t> image, std::string& error) {
  std::vector<uint8_t> bytes;
  encodePgm(image, bytes);
  return writeFileAtomic(path, bytes.data(), bytes.size(), error);
}

bool writeJpegGray(const std::string& path, ImageView<const uint8_t> image, int quality,
                   std::string& error) {
  JpegEncoder enc;
  return enc.encodeGray(image, quality, error) &&
         writeFileAtomic(path, enc.data(), enc.size(), error);
}

bool writeJpegRgb(const std::string& path, const uint8_t* rgb, int width, int height,
                  std::ptrdiff_t stride_bytes, int quality, std::string& error) {
  JpegEncoder enc;
  return enc.encodeRgb(rgb, width, height, stride_bytes, quality, error) &&
         writeFileAtomic(path, enc.data(), enc.size(), error);
}

}  // namespace epitrack::hal
