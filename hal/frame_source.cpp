#include "hal/frame_source.hpp"

#include "hal/io/file_util.hpp"
#include "hal/replay/image_directory_source.hpp"

namespace epitrack::hal {

const char* frameStatusName(FrameStatus status) {
  switch (status) {
    case FrameStatus::kOk:
      return "ok";
    case FrameStatus::kEndOfStream:
      return "end_of_stream";
    case FrameStatus::kTimeout:
      return "timeout";
    case FrameStatus::kDeviceLost:
      return "device_lost";
    case FrameStatus::kCorruptFrame:
      return "corrupt_frame";
    case FrameStatus::kError:
      return "error";
  }
  return "error";
}

std::unique_ptr<FrameSource> openFrameSource(const std::string& input, const SourceOptions& options,
                                             std::string& error) {
  if (input.empty()) {
    error = "empty INPUT";
    return nullptr;
  }
  if (isDirectory(input)) {
    auto src = std::make_unique<ImageDirectorySource>(input, options);
    if (!src->ok()) {
      error = src->lastError();
      return nullptr;
    }
    return src;
  }
  error = "cannot open INPUT '" + input +
          "': not a directory of frames (other INPUT kinds: see README)";
  return nullptr;
}

}  // namespace epitrack::hal
