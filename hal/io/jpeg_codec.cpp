// JPEG through libjpeg-turbo's TurboJPEG API (turbojpeg.h, 2.x): one handle per direction, created
// once; decoding asks for TJPF_GRAY so the decoder skips chroma entirely.
#include <turbojpeg.h>

#include <string>

#include "hal/io/image_codec.hpp"

namespace epitrack::hal {

JpegDecoder::JpegDecoder() : handle_(tjInitDecompress()) {}
JpegDecoder::~JpegDecoder() {
  if (handle_ != nullptr) tjDestroy(static_cast<tjhandle>(handle_));
}

bool JpegDecoder::readHeader(const uint8_t* data, std::size_t size, ImageHeader& header,
                             std::string& error) {
  if (handle_ == nullptr) {
    error = "TurboJPEG decoder could not be created";
    return false;
  }
  int w = 0;
  int h = 0;
  int subsamp = 0;
  int colorspace = 0;
  if (size > static_cast<std::size_t>(UINT32_MAX) ||
      tjDecompressHeader3(static_cast<tjhandle>(handle_), data, static_cast<unsigned long>(size),
                          &w, &h, &subsamp, &colorspace) != 0) {
    error = std::string("bad JPEG header: ") + tjGetErrorStr2(static_cast<tjhandle>(handle_));
    return false;
  }
  if (w <= 0 || h <= 0 || w > kMaxImageDimension || h > kMaxImageDimension) {
    error = "JPEG size " + std::to_string(w) + "x" + std::to_string(h) + " outside 1.." +
            std::to_string(kMaxImageDimension);
    return false;
  }
  header.width = w;
  header.height = h;
  header.channels = colorspace == TJCS_GRAY ? 1 : 3;
  header.format = ImageFormat::kJpeg;
  return true;
}

bool JpegDecoder::decodeGray(const uint8_t* data, std::size_t size, ImageView<uint8_t> out,
                             std::string& error) {
  ImageHeader header;
  if (!readHeader(data, size, header, error)) return false;
  if (header.width != out.width || header.height != out.height) {
    error = "JPEG is " + std::to_string(header.width) + "x" + std::to_string(header.height) +
            ", expected " + std::to_string(out.width) + "x" + std::to_string(out.height);
    return false;
  }
  auto* h = static_cast<tjhandle>(handle_);
  // TJFLAG_STOPONWARNING: a truncated or damaged stream is an error, not a half-grey frame.
  if (tjDecompress2(h, data, static_cast<unsigned long>(size), out.data, out.width,
                    static_cast<int>(out.stride), out.height, TJPF_GRAY,
                    TJFLAG_STOPONWARNING) != 0) {
    error = std::string("corrupt JPEG data: ") + tjGetErrorStr2(h);
    return false;
  }
  return true;
}

JpegEncoder::JpegEncoder() : handle_(tjInitCompress()) {}
JpegEncoder::~JpegEncoder() {
  if (buffer_ != nullptr) tjFree(buffer_);
  if (handle_ != nullptr) tjDestroy(static_cast<tjhandle>(handle_));
}

bool JpegEncoder::ensureCapacity(int width, int height, int subsampling, std::string& error) {
  if (handle_ == nullptr) {
    error = "TurboJPEG encoder could not be created";
    return false;
  }
  const unsigned long need = tjBufSize(width, height, subsampling);
  if (need == static_cast<unsigned long>(-1)) {
    error = "JPEG size out of range";
    return false;
  }
  if (need > capacity_) {
    if (buffer_ != nullptr) tjFree(buffer_);
    buffer_ = tjAlloc(static_cast<int>(need));
    capacity_ = buffer_ != nullptr ? need : 0;
    if (buffer_ == nullptr) {
      error = "out of memory for a JPEG buffer";
      return false;
    }
  }
  return true;
}

bool JpegEncoder::encodeGray(ImageView<const uint8_t> image, int quality, std::string& error) {
  if (!ensureCapacity(image.width, image.height, TJSAMP_GRAY, error)) return false;
  unsigned long size = capacity_;
  auto* h = static_cast<tjhandle>(handle_);
  if (tjCompress2(h, image.data, image.width, static_cast<int>(image.stride), image.height,
                  TJPF_GRAY, &buffer_, &size, TJSAMP_GRAY, quality, TJFLAG_NOREALLOC) != 0) {
    error = std::string("JPEG encoding failed: ") + tjGetErrorStr2(h);
    return false;
  }
  size_ = size;
  return true;
}

bool JpegEncoder::encodeRgb(const uint8_t* rgb, int width, int height, std::ptrdiff_t stride_bytes,
                            int quality, std::string& error) {
  if (!ensureCapacity(width, height, TJSAMP_420, error)) return false;
  unsigned long size = capacity_;
  auto* h = static_cast<tjhandle>(handle_);
  if (tjCompress2(h, rgb, width, static_cast<int>(stride_bytes), height, TJPF_RGB, &buffer_, &size,
                  TJSAMP_420, quality, TJFLAG_NOREALLOC) != 0) {
    error = std::string("JPEG encoding failed: ") + tjGetErrorStr2(h);
    return false;
  }
  size_ = size;
  return true;
}

}  // namespace epitrack::hal
