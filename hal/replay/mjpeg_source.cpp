#include "hal/replay/mjpeg_source.hpp"

#include <cerrno>

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include "hal/io/file_util.hpp"
#include "hal/replay/jpeg_stream.hpp"

namespace epitrack::hal {

MjpegSource::MjpegSource(const std::string& path, const SourceOptions& options) : path_(path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    error_ = "cannot open '" + path + "': " + errnoText(errno);
    return;
  }
  std::size_t file_size = 0;
  if (!regularFileSize(fd, path, file_size, error_)) {
    ::close(fd);
    return;
  }
  if (file_size == 0) {
    error_ = "'" + path + "': empty file, no frames";
    ::close(fd);
    return;
  }
  void* map = ::mmap(nullptr, file_size, PROT_READ, MAP_PRIVATE, fd, 0);
  const int map_errno = errno;
  ::close(fd);
  if (map == MAP_FAILED) {
    error_ = "cannot map '" + path + "': " + errnoText(map_errno);
    return;
  }
  data_ = static_cast<const uint8_t*>(map);
  size_ = file_size;
  ::madvise(map, size_, MADV_SEQUENTIAL);
  if (size_ < 3 || data_[0] != 0xFF || data_[1] != 0xD8 || data_[2] != 0xFF) {
    error_ = "'" + path + "': not an MJPEG file (no JPEG signature at byte 0)";
    return;
  }
  ImageHeader header;
  if (!decoder_.readHeader(data_, size_, header, error_)) {
    error_ = "'" + path + "': first frame: " + error_;
    return;
  }
  if (!luma_.allocate(header.width, header.height)) {
    error_ = "'" + path + "': cannot allocate frames";
    return;
  }
  // Count the frames once (a marker walk, no decoding).
  std::int64_t count = 0;
  for (std::size_t p = 0; p < size_;) {
    std::size_t length = 0;
    if (measureJpeg(data_ + p, size_ - p, length) != JpegExtent::kComplete) {
      ++count;  // a damaged or truncated frame still takes a frame index
      p = findJpegStart(data_, size_, p + 2);
      continue;
    }
    ++count;
    p = findJpegStart(data_, size_, p + length);
  }
  info_.width = header.width;
  info_.height = header.height;
  info_.fps = options.default_fps;
  info_.pixel_format = "MJPEG";
  info_.real_timestamps = false;
  info_.frame_count = count;
  pacer_.configure(options.realtime, info_.fps);
  ok_ = true;
}

MjpegSource::~MjpegSource() {
  if (data_ != nullptr) ::munmap(const_cast<uint8_t*>(data_), size_);
}

FrameStatus MjpegSource::next(Frame& frame) {
  if (!ok_) return FrameStatus::kError;
  if (pos_ >= size_) return FrameStatus::kEndOfStream;
  const std::int64_t index = next_index_++;
  const std::size_t start = pos_;
  pacer_.wait(index);
  std::size_t length = 0;
  const JpegExtent extent = measureJpeg(data_ + start, size_ - start, length);
  if (extent != JpegExtent::kComplete) {
    pos_ = findJpegStart(data_, size_, start + 2);
    error_ = "'" + path_ + "': frame " + std::to_string(index) + " at byte " +
             std::to_string(start) +
             (extent == JpegExtent::kTruncated ? " is truncated (file ends before its EOI marker)"
                                               : " is not a well-formed JPEG");
    return FrameStatus::kCorruptFrame;
  }
  pos_ = findJpegStart(data_, size_, start + length);
  ImageHeader header;
  if (!decoder_.readHeader(data_ + start, length, header, error_)) {
    error_ = "'" + path_ + "': frame " + std::to_string(index) + " at byte " +
             std::to_string(start) + ": " + error_;
    return FrameStatus::kCorruptFrame;
  }
  if (header.width != info_.width || header.height != info_.height) {
    error_ = "'" + path_ + "': frame " + std::to_string(index) + " at byte " +
             std::to_string(start) + " is " + std::to_string(header.width) + "x" +
             std::to_string(header.height) + ", the clip is " + std::to_string(info_.width) + "x" +
             std::to_string(info_.height);
    return FrameStatus::kError;
  }
  if (!decoder_.decodeGray(data_ + start, length, luma_.view(), error_)) {
    error_ = "'" + path_ + "': frame " + std::to_string(index) + " at byte " +
             std::to_string(start) + ": " + error_;
    return FrameStatus::kCorruptFrame;
  }
  frame.luma = luma_.constView();
  frame.index = index;
  frame.timestamp_s = static_cast<double>(index) / info_.fps;
  frame.encoded = data_ + start;
  frame.encoded_size = length;
  return FrameStatus::kOk;
}

}  // namespace epitrack::hal
