#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "algo/image/image.hpp"
#include "hal/frame_source.hpp"
#include "hal/io/image_codec.hpp"
#include "hal/v4l2/v4l2_syscalls.hpp"

namespace epitrack::hal {

/// What `v4l2:/dev/videoN?width=W&height=H&fps=N&format=grey|yuyv|mjpeg&buffers=B&timeout_ms=T`
/// asks for; 0 (or an empty format) leaves the choice to negotiation.
struct V4l2Options {
  std::string device;
  int width = 0;
  int height = 0;
  double fps = 0.0;
  uint32_t fourcc = 0;    ///< V4L2_PIX_FMT_GREY, _YUYV or _MJPEG; 0 = GREY, else YUYV, else MJPEG
  int buffers = 4;        ///< mmap buffers requested (REQBUFS)
  int timeout_ms = 2000;  ///< poll timeout of one `next` call
};

/// Parses a `v4l2:` INPUT; false with a message naming the bad part.
bool parseV4l2Input(const std::string& input, V4l2Options& options, std::string& error);

/// "GREY", "YUYV", "MJPG", ... (printable fourcc).
std::string fourccName(uint32_t fourcc);

/// Streaming V4L2 capture (mmap buffers) through the syscall seam. The constructor negotiates
/// and starts streaming: QUERYCAP (capture + streaming), ENUM_FMT, ENUM_FRAMESIZES, S_FMT/G_FMT
/// (GREY, then YUYV, then MJPEG unless asked), S_PARM, REQBUFS, QUERYBUF + mmap, QBUF, STREAMON;
/// the destructor stops and unmaps (STREAMOFF, munmap, REQBUFS 0, close). `next` polls with the
/// timeout, dequeues, converts to 8-bit luma in a buffer sized at open (GREY copy, YUYV luma,
/// MJPEG TurboJPEG decode) and re-queues. Faults: EINTR/EAGAIN retried, EIO counted and retried a
/// bounded number of times, ENODEV -> device_lost, short bytesused or an error-flagged buffer or
/// an undecodable JPEG -> corrupt_frame, poll timeout -> timeout.
class V4l2CaptureSource final : public FrameSource {
 public:
  /// Consecutive EIO results of one `next` before it gives up with kError.
  static constexpr int kMaxEioRetries = 5;
  /// EAGAIN after a ready poll (spurious wake-ups) tolerated in one `next` before kTimeout.
  static constexpr int kMaxAgainRetries = 64;
  static constexpr int kMaxBuffers = 32;

  V4l2CaptureSource(V4l2Syscalls& syscalls, const V4l2Options& options,
                    const SourceOptions& source_options);
  ~V4l2CaptureSource() override;

  [[nodiscard]] bool ok() const { return ok_; }
  FrameStatus next(Frame& frame) override;

  /// EIO results seen since open (each was retried).
  [[nodiscard]] int64_t eioCount() const { return eio_total_; }
  [[nodiscard]] uint32_t fourcc() const { return fourcc_; }
  [[nodiscard]] int bufferCount() const { return buffer_count_; }

 private:
  struct MappedBuffer {
    void* data = nullptr;
    std::size_t length = 0;
  };
  bool open(const SourceOptions& source_options);
  bool negotiateFormat();
  bool setFrameRate(const SourceOptions& source_options);
  bool startStreaming();
  void shutdown();
  /// ioctl through the seam, EINTR retried; returns 0 or -errno.
  int xioctl(unsigned long request, void* arg);
  /// Converts a dequeued buffer; kOk or kCorruptFrame (with error_ set).
  FrameStatus convert(const MappedBuffer& buffer, std::size_t bytes_used, int64_t index);

  V4l2Syscalls& sys_;
  V4l2Options options_;
  int fd_ = -1;
  uint32_t fourcc_ = 0;
  uint32_t bytes_per_line_ = 0;
  uint32_t size_image_ = 0;
  std::array<MappedBuffer, kMaxBuffers> buffers_{};
  int buffer_count_ = 0;
  bool buffers_requested_ = false;
  bool streaming_ = false;
  bool lost_ = false;
  bool ok_ = false;
  Image<uint8_t> luma_;
  std::vector<uint8_t> encoded_;  // the last MJPEG frame (capacity: the largest buffer)
  std::unique_ptr<JpegDecoder> jpeg_;
  int64_t frames_dequeued_ = 0;
  int64_t first_sequence_ = -1;
  double first_timestamp_s_ = 0.0;
  int64_t eio_total_ = 0;
};

/// Parses a `v4l2:` INPUT and opens the device through `syscalls`; nullptr with a message when
/// it fails.
std::unique_ptr<FrameSource> openV4l2Source(const std::string& input, V4l2Syscalls& syscalls,
                                            const SourceOptions& options, std::string& error);

}  // namespace epitrack::hal
