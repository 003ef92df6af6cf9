// libFuzzer harness: V4L2 capture (hal/v4l2/v4l2_capture_source.cpp) on the fake driver of the
// tests (tests/hal/fake_v4l2_driver.*), with the fuzz input deciding (1) the driver's offer —
// formats, sizes, buffer count, row padding, its built-in faults — and the INPUT options, and
// (2) through a layer between the capture code and the driver, every answer the capture code
// gets: any ioctl, poll or open may fail with an errno, any answer field may be replaced
// (capabilities, formats, frame sizes, negotiated size, bytesperline, sizeimage, frame rate,
// buffer count and lengths, the dequeued buffer's index, bytesused, flags, sequence, timestamp),
// and the bytes of a dequeued buffer may be replaced by fuzz data (an MJPEG frame is then fuzzed
// JPEG). Invariants: nothing reads or writes outside the mapped buffers (ASan); a frame has the
// negotiated size; statuses carry a message; a lost device stays lost; after the source is
// destroyed the device is closed and every buffer unmapped.
#include <fuzzer/FuzzedDataProvider.h>

#include <cerrno>
#include <cstring>
#include <map>
#include <string>
#include <utility>

#include <linux/videodev2.h>
#include <sys/mman.h>

#include "hal/v4l2/v4l2_capture_source.hpp"
#include "tests/fuzz/fuzz_support.hpp"
#include "tests/hal/fake_v4l2_driver.hpp"

namespace hal = epitrack::hal;
namespace test = epitrack::test;

namespace {

constexpr int kMaxNextCalls = 12;
constexpr uint32_t kOtherFourcc = v4l2_fourcc('R', 'G', 'B', '3');

uint32_t pickFourcc(FuzzedDataProvider& in) {
  switch (in.ConsumeIntegralInRange<int>(0, 4)) {
    case 0:
      return V4L2_PIX_FMT_GREY;
    case 1:
      return V4L2_PIX_FMT_YUYV;
    case 2:
      return V4L2_PIX_FMT_MJPEG;
    case 3:
      return kOtherFourcc;
    default:
      return in.ConsumeIntegral<uint32_t>();
  }
}

/// A dimension an answer may claim: usually plausible, sometimes absurd.
uint32_t pickDimension(FuzzedDataProvider& in) {
  switch (in.ConsumeIntegralInRange<int>(0, 3)) {
    case 0:
      return in.ConsumeIntegralInRange<uint32_t>(0, 64);
    case 1:
      return in.ConsumeIntegralInRange<uint32_t>(0, 70000);
    case 2:
      return in.ConsumeIntegral<uint32_t>();
    default:
      return 0;
  }
}

/// Between the capture code and the fake driver: injects errors and rewrites answers.
class FuzzedSyscalls final : public hal::V4l2Syscalls {
 public:
  FuzzedSyscalls(test::FakeV4l2Driver& driver, FuzzedDataProvider& in) : driver_(driver), in_(in) {}

  int open(const char* path, int flags) override {
    if (const int err = injectedError()) return fail(err);
    return driver_.open(path, flags);
  }
  int close(int fd) override { return driver_.close(fd); }
  void* mmap(void* addr, std::size_t length, int prot, int flags, int fd, off_t offset) override {
    if (const int err = injectedError()) {
      errno = err;
      return MAP_FAILED;
    }
    void* p = driver_.mmap(addr, length, prot, flags, fd, offset);
    if (p != MAP_FAILED) mapped_[offset] = {static_cast<uint8_t*>(p), length};
    return p;
  }
  int munmap(void* addr, std::size_t length) override { return driver_.munmap(addr, length); }
  int poll(struct pollfd* fds, nfds_t count, int timeout_ms) override {
    switch (in_.ConsumeIntegralInRange<int>(0, 15)) {
      case 13:
        return fail(EINTR);
      case 14:
        return 0;  // timeout
      case 15:
        fds[0].revents = POLLERR;
        return 1;
      default:
        return driver_.poll(fds, count, timeout_ms);
    }
  }

  int ioctl(int fd, unsigned long request, void* arg) override {
    if (const int err = injectedError()) return fail(err);
    const int rc = driver_.ioctl(fd, request, arg);
    if (rc != 0) return rc;
    if (request == VIDIOC_QUERYBUF) {
      const auto* buf = static_cast<const v4l2_buffer*>(arg);
      offsets_[buf->index] = buf->m.offset;
    }
    if (request == VIDIOC_DQBUF) replaceContents(*static_cast<v4l2_buffer*>(arg));
    if (in_.ConsumeIntegralInRange<int>(0, 7) == 7) rewriteAnswer(request, arg);
    return 0;
  }

 private:
  static int fail(int err) {
    errno = err;
    return -1;
  }

  /// 0 (no fault) for most bytes and when the input is used up.
  int injectedError() {
    static constexpr int kErrors[] = {EINTR, EAGAIN, EIO, ENODEV, EINVAL, EBUSY, ENOMEM, ENOTTY};
    const int b = in_.ConsumeIntegral<uint8_t>();
    return b >= 240 ? kErrors[b % 8] : 0;
  }

  /// Replaces the bytes of a dequeued buffer (and its bytesused) with fuzz data.
  void replaceContents(v4l2_buffer& buf) {
    if (!in_.ConsumeBool()) return;
    const auto offset = offsets_.find(buf.index);
    if (offset == offsets_.end()) return;
    const auto mapping = mapped_.find(static_cast<off_t>(offset->second));
    if (mapping == mapped_.end()) return;
    const auto [data, length] = mapping->second;
    const std::size_t n = in_.ConsumeIntegralInRange<std::size_t>(0, length);
    const std::vector<uint8_t> bytes = in_.ConsumeBytes<uint8_t>(n);
    if (!bytes.empty()) std::memcpy(data, bytes.data(), bytes.size());
    buf.bytesused = static_cast<uint32_t>(bytes.size());
  }

  void rewriteAnswer(unsigned long request, void* arg) {
    switch (request) {
      case VIDIOC_QUERYCAP: {
        auto* cap = static_cast<v4l2_capability*>(arg);
        cap->capabilities = in_.ConsumeIntegral<uint32_t>();
        cap->device_caps = in_.ConsumeIntegral<uint32_t>();
        break;
      }
      case VIDIOC_ENUM_FMT:
        static_cast<v4l2_fmtdesc*>(arg)->pixelformat = pickFourcc(in_);
        break;
      case VIDIOC_ENUM_FRAMESIZES: {
        auto* size = static_cast<v4l2_frmsizeenum*>(arg);
        size->type = in_.ConsumeIntegralInRange<uint32_t>(0, 4);
        if (size->type == V4L2_FRMSIZE_TYPE_DISCRETE) {
          size->discrete.width = pickDimension(in_);
          size->discrete.height = pickDimension(in_);
        } else {
          size->stepwise.min_width = pickDimension(in_);
          size->stepwise.max_width = pickDimension(in_);
          size->stepwise.step_width = pickDimension(in_);
          size->stepwise.min_height = pickDimension(in_);
          size->stepwise.max_height = pickDimension(in_);
          size->stepwise.step_height = pickDimension(in_);
        }
        break;
      }
      case VIDIOC_S_FMT:
      case VIDIOC_G_FMT: {
        v4l2_pix_format& pix = static_cast<v4l2_format*>(arg)->fmt.pix;
        switch (in_.ConsumeIntegralInRange<int>(0, 4)) {
          case 0:
            pix.width = pickDimension(in_);
            pix.height = pickDimension(in_);
            break;
          case 1:
            pix.bytesperline = pickDimension(in_);
            break;
          case 2:
            pix.sizeimage = in_.ConsumeIntegral<uint32_t>();
            break;
          case 3:
            pix.pixelformat = pickFourcc(in_);
            break;
          default:
            pix.width = pickDimension(in_);
            pix.height = pickDimension(in_);
            pix.bytesperline = pickDimension(in_);
            break;
        }
        break;
      }
      case VIDIOC_G_PARM:
      case VIDIOC_S_PARM: {
        v4l2_captureparm& capture = static_cast<v4l2_streamparm*>(arg)->parm.capture;
        capture.capability = in_.ConsumeIntegral<uint32_t>();
        capture.timeperframe.numerator = in_.ConsumeIntegral<uint32_t>();
        capture.timeperframe.denominator = in_.ConsumeIntegral<uint32_t>();
        break;
      }
      case VIDIOC_REQBUFS:
        static_cast<v4l2_requestbuffers*>(arg)->count = in_.ConsumeIntegralInRange<uint32_t>(0, 64);
        break;
      case VIDIOC_QUERYBUF: {
        auto* buf = static_cast<v4l2_buffer*>(arg);
        if (in_.ConsumeBool()) {
          buf->length = in_.ConsumeIntegral<uint32_t>();
        } else {
          buf->m.offset = in_.ConsumeIntegral<uint32_t>();
        }
        break;
      }
      case VIDIOC_DQBUF: {
        auto* buf = static_cast<v4l2_buffer*>(arg);
        switch (in_.ConsumeIntegralInRange<int>(0, 4)) {
          case 0:
            buf->index = in_.ConsumeIntegralInRange<uint32_t>(0, 40);
            break;
          case 1:
            buf->bytesused = in_.ConsumeIntegral<uint32_t>();
            break;
          case 2:
            buf->flags = in_.ConsumeIntegral<uint32_t>();
            break;
          case 3:
            buf->sequence = in_.ConsumeIntegral<uint32_t>();
            break;
          default:
            buf->timestamp.tv_sec = in_.ConsumeIntegral<time_t>();
            buf->timestamp.tv_usec = in_.ConsumeIntegral<suseconds_t>();
            break;
        }
        break;
      }
      default:
        break;
    }
  }

  test::FakeV4l2Driver& driver_;
  FuzzedDataProvider& in_;
  std::map<uint32_t, uint32_t> offsets_;                      // buffer index -> mmap offset
  std::map<off_t, std::pair<uint8_t*, std::size_t>> mapped_;  // mmap offset -> memory
};

test::FakeV4l2Config driverConfig(FuzzedDataProvider& in) {
  test::FakeV4l2Config config;
  const int format_count = in.ConsumeIntegralInRange<int>(1, 3);
  for (int i = 0; i < format_count; ++i) config.formats.push_back(pickFourcc(in));
  const int size_count = in.ConsumeIntegralInRange<int>(1, 3);
  for (int i = 0; i < size_count; ++i) {
    // The fake driver renders its synthetic scene at these sizes: small, and at least 8 px.
    config.sizes.emplace_back(in.ConsumeIntegralInRange<int>(8, 48),
                              in.ConsumeIntegralInRange<int>(8, 48));
  }
  config.max_buffers = in.ConsumeIntegralInRange<int>(1, 12);
  config.row_padding = in.ConsumeIntegralInRange<int>(0, 16);
  config.jpeg_quality = in.ConsumeIntegralInRange<int>(30, 95);
  config.distinct_frames = 1;
  test::FakeV4l2Faults& f = config.faults;
  auto at = [&in] { return in.ConsumeIntegralInRange<int64_t>(-1, 6); };
  f.eagain_at = at();
  f.eagain_count = in.ConsumeIntegralInRange<int>(0, 70);
  f.eintr_at = at();
  f.eintr_count = in.ConsumeIntegralInRange<int>(0, 3);
  f.eio_at = at();
  f.eio_count = in.ConsumeIntegralInRange<int>(0, 7);
  f.unplug_at = at();
  f.short_bytesused_at = at();
  f.corrupt_jpeg_at = at();
  f.error_flag_at = at();
  f.poll_timeout_at = at();
  f.poll_timeout_count = in.ConsumeIntegralInRange<int>(0, 2);
  f.change_size = in.ConsumeIntegralInRange<int>(0, 7) == 0;
  f.change_size_on_get = in.ConsumeIntegralInRange<int>(0, 7) == 0;
  return config;
}

std::string inputString(FuzzedDataProvider& in) {
  std::string input = "v4l2:/dev/video0?timeout_ms=1";
  static const char* const kFormats[] = {"", "grey", "yuyv", "mjpeg"};
  const char* format = kFormats[in.ConsumeIntegralInRange<int>(0, 3)];
  if (*format != '\0') input += std::string("&format=") + format;
  if (in.ConsumeBool()) {
    input += "&width=" + std::to_string(in.ConsumeIntegralInRange<int>(1, 64)) +
             "&height=" + std::to_string(in.ConsumeIntegralInRange<int>(1, 64));
  }
  input += "&buffers=" + std::to_string(in.ConsumeIntegralInRange<int>(2, 32));
  if (in.ConsumeBool()) input += "&fps=" + std::to_string(in.ConsumeIntegralInRange<int>(1, 120));
  return input;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  test::FakeV4l2Driver driver(driverConfig(in));
  const std::string input = inputString(in);
  {
    FuzzedSyscalls syscalls(driver, in);
    std::string error;
    const std::unique_ptr<hal::FrameSource> source =
        hal::openV4l2Source(input, syscalls, hal::SourceOptions{}, error);
    if (source == nullptr) {
      FUZZ_CHECK(!error.empty());
    } else {
      const hal::SourceInfo& info = source->info();
      FUZZ_CHECK(info.width >= 1 && info.height >= 1);
      FUZZ_CHECK(info.width <= hal::kMaxImageDimension && info.height <= hal::kMaxImageDimension);
      bool lost = false;
      for (int i = 0; i < kMaxNextCalls; ++i) {
        hal::Frame frame;
        const hal::FrameStatus status = source->next(frame);
        if (lost) FUZZ_CHECK(status == hal::FrameStatus::kDeviceLost);
        if (status == hal::FrameStatus::kOk) {
          FUZZ_CHECK(frame.luma.width == info.width && frame.luma.height == info.height);
          uint64_t sum = 0;  // touch every pixel of the delivered view
          for (int y = 0; y < frame.luma.height; ++y) {
            for (int x = 0; x < frame.luma.width; ++x) sum += frame.luma(x, y);
          }
          FUZZ_CHECK(sum <=
                     255u * static_cast<uint64_t>(info.width) * static_cast<uint64_t>(info.height));
          if (frame.encoded != nullptr) {
            FUZZ_CHECK(frame.encoded_size >= 4);
            FUZZ_CHECK(frame.encoded[0] + frame.encoded[frame.encoded_size - 1] >= 0);
          }
          continue;
        }
        FUZZ_CHECK(!source->lastError().empty());
        if (status == hal::FrameStatus::kDeviceLost) lost = true;
        if (status == hal::FrameStatus::kError) break;
      }
    }
  }
  // Whatever happened, the device is closed and nothing stays mapped.
  FUZZ_CHECK(driver.openFds() == 0);
  FUZZ_CHECK(driver.mappedBuffers() == 0);
  return 0;
}
