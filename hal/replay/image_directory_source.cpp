#include "hal/replay/image_directory_source.hpp"

#include "hal/io/file_util.hpp"

namespace epitrack::hal {

ImageDirectorySource::ImageDirectorySource(const std::string& dir, const SourceOptions& options) {
  if (!listFrameFiles(dir, paths_, error_)) return;
  ImageHeader header;
  if (!decoder_.readFileHeader(paths_.front(), header, error_)) return;
  if (!buffer_.allocate(header.width, header.height)) {
    error_ = "cannot allocate frames of " + std::to_string(header.width) + "x" +
             std::to_string(header.height);
    return;
  }
  info_.width = header.width;
  info_.height = header.height;
  info_.fps = options.default_fps;
  info_.pixel_format = imageFormatName(header.format);
  info_.real_timestamps = false;
  info_.frame_count = static_cast<int64_t>(paths_.size());
  pacer_.configure(options.realtime, info_.fps);
  ok_ = true;
}

FrameStatus ImageDirectorySource::next(Frame& frame) {
  if (!ok_) return FrameStatus::kError;
  if (next_ >= paths_.size()) return FrameStatus::kEndOfStream;
  const std::size_t i = next_++;
  const std::string& path = paths_[i];
  pacer_.wait(static_cast<int64_t>(i));
  ImageHeader header;
  if (!decoder_.readFileHeader(path, header, error_)) return FrameStatus::kCorruptFrame;
  if (header.width != info_.width || header.height != info_.height) {
    error_ = "frame '" + path + "' is " + std::to_string(header.width) + "x" +
             std::to_string(header.height) + ", the clip is " + std::to_string(info_.width) + "x" +
             std::to_string(info_.height);
    return FrameStatus::kError;
  }
  if (!decoder_.decodeLastFile(buffer_.view(), error_)) return FrameStatus::kCorruptFrame;
  frame.luma = buffer_.constView();
  frame.index = static_cast<int64_t>(i);
  frame.timestamp_s = static_cast<double>(i) / info_.fps;
  frame.path = path;
  return FrameStatus::kOk;
}

}  // namespace epitrack::hal
