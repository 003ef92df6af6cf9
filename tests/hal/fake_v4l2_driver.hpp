#pragma once

// A fake V4L2 capture driver behind the syscall seam: it implements the mmap streaming protocol
// (QUERYCAP, ENUM_FMT, ENUM_FRAMESIZES, S_FMT/G_FMT, G_PARM/S_PARM, REQBUFS, QUERYBUF, mmap, QBUF,
// STREAMON, poll, DQBUF, STREAMOFF, munmap, close) for GREY, YUYV and MJPEG, serves frames of the
// synthetic scene, and injects faults. The production V4l2CaptureSource runs unchanged on top.

#include <cstdint>
#include <deque>
#include <string>
#include <utility>
#include <vector>

#include "algo/image/image.hpp"
#include "hal/v4l2/v4l2_syscalls.hpp"

namespace epitrack::test {

struct FakeV4l2Faults {
  int64_t eagain_at = -1;  ///< at this frame, DQBUF fails with EAGAIN `eagain_count` times
  int eagain_count = 0;
  int64_t eintr_at = -1;  ///< at this frame, poll and DQBUF fail with EINTR `eintr_count` times
  int eintr_count = 0;
  int64_t eio_at = -1;  ///< at this frame, DQBUF fails with EIO `eio_count` times
  int eio_count = 0;
  int64_t unplug_at = -1;           ///< from this frame on, the device is gone (ENODEV, POLLERR)
  int64_t short_bytesused_at = -1;  ///< this frame's bytesused is half the image
  int64_t corrupt_jpeg_at = -1;     ///< this MJPEG frame is cut to 60% and loses its EOI
  int64_t error_flag_at = -1;       ///< this frame carries V4L2_BUF_FLAG_ERROR
  int64_t poll_timeout_at = -1;     ///< at this frame, poll times out `poll_timeout_count` times
  int poll_timeout_count = 0;
  uint32_t refuse_fourcc = 0;       ///< S_FMT with this format sets another offered format instead
  bool change_size = false;         ///< S_FMT sets half the requested size
  bool change_size_on_get = false;  ///< S_FMT agrees, G_FMT then reports another size
};

struct FakeV4l2Config {
  std::string device = "/dev/video0";
  std::vector<uint32_t> formats;           ///< offered, in ENUM_FMT order
  std::vector<std::pair<int, int>> sizes;  ///< discrete frame sizes (all formats)
  uint32_t capabilities = 0;               ///< 0: video capture + streaming
  int max_buffers = 8;
  int row_padding = 0;  ///< extra bytes per line (bytesperline > minimum) for GREY/YUYV
  int jpeg_quality = 90;
  int distinct_frames = 3;  ///< frames of the synthetic scene, served in a cycle
  FakeV4l2Faults faults;
};

class FakeV4l2Driver final : public hal::V4l2Syscalls {
 public:
  explicit FakeV4l2Driver(FakeV4l2Config config);
  ~FakeV4l2Driver() override;

  int open(const char* path, int flags) override;
  int close(int fd) override;
  int ioctl(int fd, unsigned long request, void* arg) override;
  void* mmap(void* addr, std::size_t length, int prot, int flags, int fd, off_t offset) override;
  int munmap(void* addr, std::size_t length) override;
  int poll(struct pollfd* fds, nfds_t count, int timeout_ms) override;

  /// The gray frame served as frame `sequence` (for MJPEG: the scene before encoding).
  [[nodiscard]] const Image<uint8_t>& sceneFrame(int64_t sequence) const;
  /// The JPEG bytes served as frame `sequence` (MJPEG only).
  [[nodiscard]] const std::vector<uint8_t>& jpegFrame(int64_t sequence) const;

  // Leak and protocol bookkeeping.
  [[nodiscard]] int openFds() const { return open_fds_; }
  [[nodiscard]] int mappedBuffers() const { return static_cast<int>(mapped_.size()); }
  [[nodiscard]] bool streaming() const { return streaming_; }
  [[nodiscard]] int allocatedBuffers() const { return static_cast<int>(buffers_.size()); }
  [[nodiscard]] int64_t framesServed() const { return sequence_; }
  [[nodiscard]] uint32_t currentFourcc() const { return fourcc_; }
  [[nodiscard]] std::pair<int, int> currentSize() const { return {width_, height_}; }
  [[nodiscard]] uint32_t timePerFrameDenominator() const { return tpf_den_; }
  [[nodiscard]] int protocolErrors() const { return protocol_errors_; }

 private:
  struct Buffer {
    std::vector<uint8_t> memory;
    bool queued = false;
  };
  static constexpr int kFd = 42;
  static constexpr uint32_t kOffsetStride = 1u << 24;

  int fail(int err);
  int protocolError(int err);
  void prepareFrames();
  [[nodiscard]] bool unplugged() const;
  [[nodiscard]] uint32_t bytesPerLine() const;
  [[nodiscard]] uint32_t sizeImage() const;

  FakeV4l2Config config_;
  FakeV4l2Faults faults_;  // counters consumed as faults fire
  int open_fds_ = 0;
  bool streaming_ = false;
  uint32_t fourcc_ = 0;
  int width_ = 0;
  int height_ = 0;
  uint32_t tpf_num_ = 1;
  uint32_t tpf_den_ = 30;
  std::vector<Buffer> buffers_;
  std::deque<uint32_t> queue_;
  std::vector<std::pair<void*, std::size_t>> mapped_;
  std::vector<Image<uint8_t>> scene_;
  std::vector<std::vector<uint8_t>> jpegs_;
  int64_t sequence_ = 0;
  int protocol_errors_ = 0;
};

}  // namespace epitrack::test
