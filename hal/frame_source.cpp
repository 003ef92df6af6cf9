#include "hal/frame_source.hpp"

#include <cerrno>
#include <cstring>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "hal/io/file_util.hpp"
#include "hal/replay/image_directory_source.hpp"
#include "hal/replay/mjpeg_source.hpp"
#include "hal/replay/y4m_source.hpp"
#include "hal/v4l2/v4l2_capture_source.hpp"

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

namespace {

bool endsWith(const std::string& text, const char* suffix) {
  const std::size_t n = std::strlen(suffix);
  if (text.size() < n) return false;
  for (std::size_t i = 0; i < n; ++i) {
    char c = text[text.size() - n + i];
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
    if (c != suffix[i]) return false;
  }
  return true;
}

template <typename Source>
std::unique_ptr<FrameSource> checked(std::unique_ptr<Source> source, std::string& error) {
  if (!source->ok()) {
    error = source->lastError();
    return nullptr;
  }
  return source;
}

}  // namespace

std::unique_ptr<FrameSource> openFrameSource(const std::string& input, const SourceOptions& options,
                                             std::string& error) {
  if (input.empty()) {
    error = "empty INPUT";
    return nullptr;
  }
  if (input.compare(0, 5, "v4l2:") == 0) {
    return openV4l2Source(input, linuxV4l2Syscalls(), options, error);
  }
  if (input == "-") return checked(std::make_unique<Y4mSource>(input, options), error);
  if (isDirectory(input))
    return checked(std::make_unique<ImageDirectorySource>(input, options), error);

  // A file: recognised by its first bytes, then by its extension.
  const int fd = ::open(input.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    error = "cannot open INPUT '" + input + "': " + errnoText(errno);
    return nullptr;
  }
  unsigned char magic[9] = {};
  ssize_t got = 0;
  do {
    got = ::read(fd, magic, sizeof(magic));
  } while (got < 0 && errno == EINTR);
  ::close(fd);
  const auto n = static_cast<std::size_t>(got > 0 ? got : 0);
  if (n >= 9 && std::memcmp(magic, "YUV4MPEG2", 9) == 0) {
    return checked(std::make_unique<Y4mSource>(input, options), error);
  }
  if (n >= 3 && magic[0] == 0xFF && magic[1] == 0xD8 && magic[2] == 0xFF) {
    return checked(std::make_unique<MjpegSource>(input, options), error);
  }
  if (endsWith(input, ".y4m")) return checked(std::make_unique<Y4mSource>(input, options), error);
  if (endsWith(input, ".mjpeg") || endsWith(input, ".mjpg")) {
    return checked(std::make_unique<MjpegSource>(input, options), error);
  }
  error = "cannot open INPUT '" + input +
          "': not a frame directory, a Y4M file or an MJPEG file (INPUT kinds: a directory of "
          "frames, FILE.y4m, - for Y4M on stdin, FILE.mjpeg, v4l2:/dev/videoN)";
  return nullptr;
}

}  // namespace epitrack::hal
