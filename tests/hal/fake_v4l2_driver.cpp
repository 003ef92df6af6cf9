#include "tests/hal/fake_v4l2_driver.hpp"

#include <algorithm>
#include <cerrno>
#include <cstring>

#include <linux/videodev2.h>
#include <sys/mman.h>

#include "hal/io/image_codec.hpp"
#include "tests/hal/replay_test_helpers.hpp"

namespace epitrack::test {

FakeV4l2Driver::FakeV4l2Driver(FakeV4l2Config config)
    : config_(std::move(config)), faults_(config_.faults) {
  if (config_.capabilities == 0) {
    config_.capabilities = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
  }
  if (!config_.sizes.empty()) {
    width_ = config_.sizes.front().first;
    height_ = config_.sizes.front().second;
  }
  if (!config_.formats.empty()) fourcc_ = config_.formats.front();
}

FakeV4l2Driver::~FakeV4l2Driver() = default;

int FakeV4l2Driver::fail(int err) {
  errno = err;
  return -1;
}

int FakeV4l2Driver::protocolError(int err) {
  ++protocol_errors_;
  return fail(err);
}

bool FakeV4l2Driver::unplugged() const {
  return faults_.unplug_at >= 0 && sequence_ >= faults_.unplug_at;
}

uint32_t FakeV4l2Driver::bytesPerLine() const {
  if (fourcc_ == V4L2_PIX_FMT_MJPEG) return 0;
  const int bpp = fourcc_ == V4L2_PIX_FMT_YUYV ? 2 : 1;
  return static_cast<uint32_t>(width_ * bpp + config_.row_padding);
}

uint32_t FakeV4l2Driver::sizeImage() const {
  if (fourcc_ == V4L2_PIX_FMT_MJPEG) {
    return static_cast<uint32_t>(2 * width_ * height_ + 4096);  // room for any gray JPEG
  }
  return bytesPerLine() * static_cast<uint32_t>(height_);
}

void FakeV4l2Driver::prepareFrames() {
  scene_ = syntheticFrames(width_, height_, config_.distinct_frames);
  jpegs_.clear();
  if (fourcc_ == V4L2_PIX_FMT_MJPEG) {
    for (const Image<uint8_t>& f : scene_) {
      jpegs_.emplace_back();
      hal::JpegEncoder enc;
      std::string err;
      enc.encodeGray(f.constView(), config_.jpeg_quality, err);
      jpegs_.back().assign(enc.data(), enc.data() + enc.size());
    }
  }
}

const Image<uint8_t>& FakeV4l2Driver::sceneFrame(int64_t sequence) const {
  return scene_[static_cast<std::size_t>(sequence % static_cast<int64_t>(scene_.size()))];
}

const std::vector<uint8_t>& FakeV4l2Driver::jpegFrame(int64_t sequence) const {
  return jpegs_[static_cast<std::size_t>(sequence % static_cast<int64_t>(jpegs_.size()))];
}

int FakeV4l2Driver::open(const char* path, int /*flags*/) {
  if (config_.device != path) return fail(ENOENT);
  if (open_fds_ > 0) return fail(EBUSY);
  ++open_fds_;
  return kFd;
}

int FakeV4l2Driver::close(int fd) {
  if (fd != kFd || open_fds_ == 0) return protocolError(EBADF);
  if (streaming_ || !buffers_.empty() || !mapped_.empty()) ++protocol_errors_;  // not released
  --open_fds_;
  return 0;
}

void* FakeV4l2Driver::mmap(void* /*addr*/, std::size_t length, int /*prot*/, int /*flags*/, int fd,
                           off_t offset) {
  if (fd != kFd || open_fds_ == 0) {
    protocolError(EBADF);
    return MAP_FAILED;
  }
  const auto index = static_cast<std::size_t>(offset) / kOffsetStride;
  if (static_cast<std::size_t>(offset) % kOffsetStride != 0 || index >= buffers_.size() ||
      length > buffers_[index].memory.size()) {
    protocolError(EINVAL);
    return MAP_FAILED;
  }
  void* p = buffers_[index].memory.data();
  mapped_.emplace_back(p, length);
  return p;
}

int FakeV4l2Driver::munmap(void* addr, std::size_t length) {
  const auto it = std::find(mapped_.begin(), mapped_.end(), std::make_pair(addr, length));
  if (it == mapped_.end()) return protocolError(EINVAL);
  mapped_.erase(it);
  return 0;
}

int FakeV4l2Driver::poll(struct pollfd* fds, nfds_t count, int /*timeout_ms*/) {
  if (count != 1 || fds[0].fd != kFd) return protocolError(EINVAL);
  fds[0].revents = 0;
  if (faults_.eintr_at >= 0 && sequence_ >= faults_.eintr_at && faults_.eintr_count > 0) {
    --faults_.eintr_count;
    return fail(EINTR);
  }
  if (unplugged()) {
    fds[0].revents = POLLERR | POLLHUP;
    return 1;
  }
  if (faults_.poll_timeout_at >= 0 && sequence_ >= faults_.poll_timeout_at &&
      faults_.poll_timeout_count > 0) {
    --faults_.poll_timeout_count;
    return 0;
  }
  if (!streaming_) {
    fds[0].revents = POLLERR;
    return 1;
  }
  if (queue_.empty()) return 0;  // nothing to fill: the timeout elapses
  fds[0].revents = POLLIN | POLLRDNORM;
  return 1;
}

int FakeV4l2Driver::ioctl(int fd, unsigned long request, void* arg) {
  if (fd != kFd || open_fds_ == 0) return protocolError(EBADF);
  if (unplugged() && request != VIDIOC_STREAMOFF && request != VIDIOC_REQBUFS) {
    return fail(ENODEV);
  }
  switch (request) {
    case VIDIOC_QUERYCAP: {
      auto* cap = static_cast<v4l2_capability*>(arg);
      *cap = v4l2_capability{};
      std::strcpy(reinterpret_cast<char*>(cap->driver), "epitrack-fake");
      std::strcpy(reinterpret_cast<char*>(cap->card), "Fake synthetic camera");
      cap->capabilities = config_.capabilities | V4L2_CAP_DEVICE_CAPS;
      cap->device_caps = config_.capabilities;
      return 0;
    }
    case VIDIOC_ENUM_FMT: {
      auto* desc = static_cast<v4l2_fmtdesc*>(arg);
      if (desc->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || desc->index >= config_.formats.size()) {
        return fail(EINVAL);
      }
      desc->pixelformat = config_.formats[desc->index];
      desc->flags = desc->pixelformat == V4L2_PIX_FMT_MJPEG ? V4L2_FMT_FLAG_COMPRESSED : 0;
      return 0;
    }
    case VIDIOC_ENUM_FRAMESIZES: {
      auto* size = static_cast<v4l2_frmsizeenum*>(arg);
      if (std::find(config_.formats.begin(), config_.formats.end(), size->pixel_format) ==
              config_.formats.end() ||
          size->index >= config_.sizes.size()) {
        return fail(EINVAL);
      }
      size->type = V4L2_FRMSIZE_TYPE_DISCRETE;
      size->discrete.width = static_cast<uint32_t>(config_.sizes[size->index].first);
      size->discrete.height = static_cast<uint32_t>(config_.sizes[size->index].second);
      return 0;
    }
    case VIDIOC_S_FMT:
    case VIDIOC_G_FMT: {
      auto* fmt = static_cast<v4l2_format*>(arg);
      if (fmt->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      if (request == VIDIOC_S_FMT) {
        if (streaming_ || !buffers_.empty()) return fail(EBUSY);
        uint32_t f = fmt->fmt.pix.pixelformat;
        if (std::find(config_.formats.begin(), config_.formats.end(), f) == config_.formats.end() ||
            f == faults_.refuse_fourcc) {
          // Like real drivers: adjust to something supported instead of failing.
          f = config_.formats.front() != faults_.refuse_fourcc ? config_.formats.front()
                                                               : config_.formats.back();
        }
        // Nearest offered size.
        int best_w = width_;
        int best_h = height_;
        long best = -1;
        for (const auto& [w, h] : config_.sizes) {
          const long cost = std::labs(static_cast<long>(w) - fmt->fmt.pix.width) +
                            std::labs(static_cast<long>(h) - fmt->fmt.pix.height);
          if (best < 0 || cost < best) {
            best = cost;
            best_w = w;
            best_h = h;
          }
        }
        if (faults_.change_size) {
          best_w /= 2;
          best_h /= 2;
        }
        fourcc_ = f;
        width_ = best_w;
        height_ = best_h;
      }
      fmt->fmt.pix = v4l2_pix_format{};
      fmt->fmt.pix.width = static_cast<uint32_t>(width_);
      fmt->fmt.pix.height = static_cast<uint32_t>(height_);
      if (request == VIDIOC_G_FMT && faults_.change_size_on_get) fmt->fmt.pix.height += 16;
      fmt->fmt.pix.pixelformat = fourcc_;
      fmt->fmt.pix.field = V4L2_FIELD_NONE;
      fmt->fmt.pix.bytesperline = bytesPerLine();
      fmt->fmt.pix.sizeimage = sizeImage();
      fmt->fmt.pix.colorspace = V4L2_COLORSPACE_SRGB;
      return 0;
    }
    case VIDIOC_G_PARM:
    case VIDIOC_S_PARM: {
      auto* parm = static_cast<v4l2_streamparm*>(arg);
      if (parm->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      if (request == VIDIOC_S_PARM) {
        const v4l2_fract want = parm->parm.capture.timeperframe;
        if (want.numerator == 0 || want.denominator == 0) return fail(EINVAL);
        // Supports 5..60 fps; clamps like a driver.
        const double fps = static_cast<double>(want.denominator) / want.numerator;
        const double clamped = std::min(60.0, std::max(5.0, fps));
        tpf_num_ = 1000;
        tpf_den_ = static_cast<uint32_t>(clamped * 1000.0 + 0.5);
      }
      parm->parm.capture = v4l2_captureparm{};
      parm->parm.capture.capability = V4L2_CAP_TIMEPERFRAME;
      parm->parm.capture.timeperframe.numerator = tpf_num_;
      parm->parm.capture.timeperframe.denominator = tpf_den_;
      return 0;
    }
    case VIDIOC_REQBUFS: {
      auto* req = static_cast<v4l2_requestbuffers*>(arg);
      if (req->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || req->memory != V4L2_MEMORY_MMAP) {
        return fail(EINVAL);
      }
      if (streaming_) return fail(EBUSY);
      if (req->count == 0) {
        if (!mapped_.empty()) return protocolError(EBUSY);  // still mapped
        buffers_.clear();
        queue_.clear();
        return 0;
      }
      if (!buffers_.empty()) return protocolError(EBUSY);
      req->count = std::min<uint32_t>(req->count, static_cast<uint32_t>(config_.max_buffers));
      buffers_.resize(req->count);
      for (Buffer& b : buffers_) b.memory.assign(sizeImage(), 0);
      if (scene_.empty() || scene_.front().width() != width_ ||
          scene_.front().height() != height_) {
        prepareFrames();
      }
      return 0;
    }
    case VIDIOC_QUERYBUF:
    case VIDIOC_QBUF: {
      auto* buf = static_cast<v4l2_buffer*>(arg);
      if (buf->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || buf->memory != V4L2_MEMORY_MMAP ||
          buf->index >= buffers_.size()) {
        return protocolError(EINVAL);
      }
      Buffer& b = buffers_[buf->index];
      if (request == VIDIOC_QUERYBUF) {
        buf->length = static_cast<uint32_t>(b.memory.size());
        buf->m.offset = buf->index * kOffsetStride;
        buf->flags = b.queued ? V4L2_BUF_FLAG_QUEUED : 0;
        return 0;
      }
      if (b.queued) return protocolError(EINVAL);
      b.queued = true;
      queue_.push_back(buf->index);
      // Like videobuf2, write the queued buffer's state back into the caller's struct: a capture
      // buffer waiting in the driver has no timestamp or sequence yet, so a caller that reads the
      // frame's timestamp after QBUF gets garbage, as it would from the kernel.
      buf->flags = V4L2_BUF_FLAG_MAPPED | V4L2_BUF_FLAG_QUEUED | V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
      buf->timestamp = timeval{};
      buf->sequence = 0;
      buf->bytesused = 0;
      return 0;
    }
    case VIDIOC_STREAMON:
      if (buffers_.empty()) return protocolError(EINVAL);
      streaming_ = true;
      return 0;
    case VIDIOC_STREAMOFF:
      streaming_ = false;
      for (Buffer& b : buffers_) b.queued = false;
      queue_.clear();
      return unplugged() ? fail(ENODEV) : 0;
    case VIDIOC_DQBUF: {
      auto* buf = static_cast<v4l2_buffer*>(arg);
      if (!streaming_) return protocolError(EINVAL);
      if (faults_.eintr_at >= 0 && sequence_ >= faults_.eintr_at && faults_.eintr_count > 0) {
        --faults_.eintr_count;
        return fail(EINTR);
      }
      if (faults_.eagain_at >= 0 && sequence_ >= faults_.eagain_at && faults_.eagain_count > 0) {
        --faults_.eagain_count;
        return fail(EAGAIN);
      }
      if (faults_.eio_at >= 0 && sequence_ >= faults_.eio_at && faults_.eio_count > 0) {
        --faults_.eio_count;
        return fail(EIO);
      }
      if (queue_.empty()) return fail(EAGAIN);
      const uint32_t index = queue_.front();
      queue_.pop_front();
      Buffer& b = buffers_[index];
      b.queued = false;
      const int64_t seq = sequence_++;
      uint32_t used = 0;
      const Image<uint8_t>& scene = sceneFrame(seq);
      if (fourcc_ == V4L2_PIX_FMT_MJPEG) {
        const std::vector<uint8_t>& jpeg = jpegFrame(seq);
        std::memcpy(b.memory.data(), jpeg.data(), jpeg.size());
        used = static_cast<uint32_t>(jpeg.size());
        if (seq == faults_.corrupt_jpeg_at) used = used * 6 / 10;
      } else {
        const uint32_t bpl = bytesPerLine();
        for (int y = 0; y < height_; ++y) {
          uint8_t* row = b.memory.data() + static_cast<std::size_t>(y) * bpl;
          const uint8_t* luma = scene.row(y);
          if (fourcc_ == V4L2_PIX_FMT_GREY) {
            std::memcpy(row, luma, static_cast<std::size_t>(width_));
          } else {
            for (int x = 0; x < width_; ++x) {
              row[2 * x] = luma[x];
              row[2 * x + 1] = static_cast<uint8_t>(x % 2 == 0 ? 90 + y % 7 : 170 - x % 5);
            }
          }
          std::memset(row + (bpl - static_cast<uint32_t>(config_.row_padding)), 0xEE,
                      static_cast<std::size_t>(config_.row_padding));
        }
        used = sizeImage();
      }
      if (seq == faults_.short_bytesused_at) used /= 2;
      *buf = v4l2_buffer{};
      buf->type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buf->memory = V4L2_MEMORY_MMAP;
      buf->index = index;
      buf->bytesused = used;
      buf->length = static_cast<uint32_t>(b.memory.size());
      buf->sequence = static_cast<uint32_t>(seq);
      buf->flags = V4L2_BUF_FLAG_MAPPED | V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC |
                   (seq == faults_.error_flag_at ? V4L2_BUF_FLAG_ERROR : 0);
      // Timestamps: 1000 s + seq / fps, in microseconds.
      const int64_t us = 1000000000LL + seq * 1000000LL * tpf_num_ / tpf_den_;
      buf->timestamp.tv_sec = static_cast<time_t>(us / 1000000);
      buf->timestamp.tv_usec = static_cast<suseconds_t>(us % 1000000);
      return 0;
    }
    default:
      return fail(ENOTTY);
  }
}

}  // namespace epitrack::test
