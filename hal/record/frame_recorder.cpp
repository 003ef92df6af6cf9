#include "hal/record/frame_recorder.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>

#include <fcntl.h>
#include <unistd.h>

#include "hal/io/file_util.hpp"

namespace epitrack::hal {
namespace {

bool endsWithNoCase(const std::string& text, const char* suffix) {
  const std::size_t n = std::strlen(suffix);
  if (text.size() < n) return false;
  for (std::size_t i = 0; i < n; ++i) {
    char c = text[text.size() - n + i];
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
    if (c != suffix[i]) return false;
  }
  return true;
}

}  // namespace

FrameRecorder::~FrameRecorder() {
  std::string ignored;
  finish(ignored);
}

bool FrameRecorder::open(const std::string& output, const RecorderOptions& options,
                         std::string& error) {
  if (kind_ != Kind::kNone) {
    error = "recorder already open";
    return false;
  }
  options_ = options;
  output_ = output;
  frames_ = 0;
  bytes_ = 0;
  if (endsWithNoCase(output, ".mjpeg") || endsWithNoCase(output, ".mjpg")) {
    temp_path_ = output + ".tmp-" + std::to_string(::getpid());
    fd_ = ::open(temp_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd_ < 0) {
      error = "cannot create '" + output + "' (as '" + temp_path_ + "'): " + errnoText(errno);
      return false;
    }
    kind_ = Kind::kMjpeg;
    return true;
  }
  if (!makeDirectories(output, error)) {
    error = "cannot create the frame directory '" + output + "': " + error;
    return false;
  }
  // Paths are built in place in strings whose capacity is reserved here.
  frame_path_.reserve(output.size() + 32);
  frame_temp_.reserve(output.size() + 64);
  kind_ = Kind::kPgmDirectory;
  return true;
}

bool FrameRecorder::writeAll(int fd, const uint8_t* data, std::size_t size, const std::string& name,
                             std::string& error) {
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(fd, data + done, size - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      error = "cannot write '" + name + "': " + errnoText(n < 0 ? errno : EIO);
      return false;
    }
    done += static_cast<std::size_t>(n);
  }
  bytes_ += size;
  return true;
}

bool FrameRecorder::write(const Frame& frame, std::string& error) {
  if (kind_ == Kind::kMjpeg) {
    if (fd_ < 0) {
      error = "recorder for '" + output_ + "' is finished";
      return false;
    }
    const uint8_t* data = nullptr;
    std::size_t size = 0;
    if (options_.pass_through_jpeg && frame.encoded != nullptr && frame.encoded_size > 0) {
      data = frame.encoded;
      size = frame.encoded_size;
    } else {
      if (!encoder_.encodeGray(frame.luma, options_.jpeg_quality, error)) return false;
      data = encoder_.data();
      size = encoder_.size();
    }
    if (!writeAll(fd_, data, size, temp_path_, error)) return false;
    ++frames_;
    return true;
  }
  if (kind_ != Kind::kPgmDirectory) {
    error = "recorder not open";
    return false;
  }
  encodePgm(frame.luma, pgm_);
  char name[32];
  std::snprintf(name, sizeof(name), "/%06lld.pgm", static_cast<long long>(frames_));
  frame_path_.assign(output_);
  frame_path_.append(name);
  frame_temp_.assign(frame_path_);
  frame_temp_.append(".tmp");
  const int fd = ::open(frame_temp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    error = "cannot create '" + frame_temp_ + "': " + errnoText(errno);
    return false;
  }
  const bool written = writeAll(fd, pgm_.data(), pgm_.size(), frame_temp_, error);
  if (::close(fd) != 0 && written) {
    error = "cannot write '" + frame_temp_ + "': " + errnoText(errno);
    ::unlink(frame_temp_.c_str());
    return false;
  }
  if (!written) {
    ::unlink(frame_temp_.c_str());
    return false;
  }
  if (::rename(frame_temp_.c_str(), frame_path_.c_str()) != 0) {
    error = "cannot rename '" + frame_temp_ + "' to '" + frame_path_ + "': " + errnoText(errno);
    ::unlink(frame_temp_.c_str());
    return false;
  }
  ++frames_;
  return true;
}

bool FrameRecorder::finish(std::string& error) {
  if (kind_ != Kind::kMjpeg || fd_ < 0) return true;
  bool good = ::fsync(fd_) == 0 || errno == EINVAL;
  if (!good) error = "cannot flush '" + temp_path_ + "': " + errnoText(errno);
  if (::close(fd_) != 0 && good) {
    error = "cannot write '" + temp_path_ + "': " + errnoText(errno);
    good = false;
  }
  fd_ = -1;
  if (good && ::rename(temp_path_.c_str(), output_.c_str()) != 0) {
    error = "cannot rename '" + temp_path_ + "' to '" + output_ + "': " + errnoText(errno);
    good = false;
  }
  if (!good) ::unlink(temp_path_.c_str());
  return good;
}

}  // namespace epitrack::hal
