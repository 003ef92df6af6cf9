// libFuzzer harness: MJPEG replay (hal/replay/mjpeg_source.cpp) — the input is a `.mjpeg` file
// (concatenated JPEGs) served from a memory file, so the production path runs unchanged: open,
// mmap, count frames by the marker walk, then decode frame after frame, skipping damaged ones.
// Invariants: every delivered frame has the clip's size, a growing index, and its encoded bytes
// inside the file starting with SOI; damaged frames are reported and replay goes on; the frame
// count of the open matches the frames and corrupt frames seen before the end.
#include <string>

#include <sys/mman.h>
#include <unistd.h>

#include "hal/io/image_codec.hpp"
#include "hal/replay/mjpeg_source.hpp"
#include "tests/fuzz/fuzz_support.hpp"

namespace hal = epitrack::hal;

namespace {

constexpr int kMaxFramesPerInput = 256;

/// A memory file (memfd) holding the input, reachable by path through /proc/self/fd.
class MemoryFile {
 public:
  MemoryFile(const uint8_t* data, std::size_t size) {
    fd_ = ::memfd_create("fuzz-mjpeg", MFD_CLOEXEC);
    FUZZ_CHECK(fd_ >= 0);
    std::size_t done = 0;
    while (done < size) {
      const ssize_t n = ::write(fd_, data + done, size - done);
      FUZZ_CHECK(n > 0);
      done += static_cast<std::size_t>(n);
    }
    path_ = "/proc/self/fd/" + std::to_string(fd_);
  }
  ~MemoryFile() { ::close(fd_); }
  MemoryFile(const MemoryFile&) = delete;
  MemoryFile& operator=(const MemoryFile&) = delete;
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  int fd_ = -1;
  std::string path_;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  // Frames larger than the harness cap are not decoded (the first frame sets the clip size).
  static hal::JpegDecoder probe;
  hal::ImageHeader first;
  std::string error;
  if (size >= 3 && probe.readHeader(data, size, first, error) &&
      !epitrack::fuzz::smallEnough(first.width, first.height)) {
    return 0;
  }

  const MemoryFile file(data, size);
  hal::MjpegSource source(file.path(), hal::SourceOptions{});
  hal::Frame frame;
  if (!source.ok()) {
    FUZZ_CHECK(!source.lastError().empty());
    FUZZ_CHECK(source.next(frame) == hal::FrameStatus::kError);
    return 0;
  }
  const hal::SourceInfo& info = source.info();
  FUZZ_CHECK(info.width >= 1 && info.height >= 1);
  FUZZ_CHECK(info.frame_count >= 1);
  int64_t seen = 0;  // frames and corrupt frames
  int64_t last_index = -1;
  for (int i = 0; i < kMaxFramesPerInput; ++i) {
    const hal::FrameStatus status = source.next(frame);
    if (status == hal::FrameStatus::kEndOfStream) {
      FUZZ_CHECK(seen == info.frame_count);
      FUZZ_CHECK(source.next(frame) == hal::FrameStatus::kEndOfStream);
      break;
    }
    if (status == hal::FrameStatus::kOk) {
      FUZZ_CHECK(frame.luma.width == info.width && frame.luma.height == info.height);
      FUZZ_CHECK(frame.index > last_index);
      last_index = frame.index;
      FUZZ_CHECK(frame.encoded != nullptr && frame.encoded_size >= 4);
      // The encoded bytes are a view into the mapped file: compare them with the input.
      FUZZ_CHECK(frame.encoded[0] == 0xFF && frame.encoded[1] == 0xD8);
      FUZZ_CHECK(frame.encoded[frame.encoded_size - 2] == 0xFF &&
                 frame.encoded[frame.encoded_size - 1] == 0xD9);
      ++seen;
      continue;
    }
    FUZZ_CHECK(!source.lastError().empty());
    if (status == hal::FrameStatus::kCorruptFrame) {
      ++seen;
      continue;
    }
    FUZZ_CHECK(status == hal::FrameStatus::kError);  // a frame of another size
    break;
  }
  return 0;
}
