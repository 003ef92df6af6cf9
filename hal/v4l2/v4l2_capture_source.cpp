// V4L2 streaming capture with mmap buffers, following the kernel's V4L2 API documentation
// ("Streaming I/O (Memory Mapping)", VIDIOC_REQBUFS/QBUF/DQBUF) and libcamera's
// V4L2VideoDevice for the order of negotiation. Every kernel call goes through V4l2Syscalls.
#include "hal/v4l2/v4l2_capture_source.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>

#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/mman.h>

#include "hal/io/file_util.hpp"

namespace epitrack::hal {
namespace {

constexpr uint32_t kPreferredFormats[] = {V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG};
constexpr int kMaxFormats = 64;
constexpr int kMaxFrameSizes = 256;
constexpr int kDefaultWidth = 640;  // the size chosen when the user names none
constexpr int kDefaultHeight = 480;

bool parseInt(const std::string& text, int lo, int hi, int& value) {
  if (text.empty() || text.size() > 9) return false;
  char* end = nullptr;
  const long v = std::strtol(text.c_str(), &end, 10);
  if (*end != '\0' || v < lo || v > hi) return false;
  value = static_cast<int>(v);
  return true;
}

std::size_t minimumBytesUsed(uint32_t fourcc, int width, int height, uint32_t bytes_per_line) {
  const std::size_t row = fourcc == V4L2_PIX_FMT_YUYV ? 2 * static_cast<std::size_t>(width)
                                                      : static_cast<std::size_t>(width);
  return static_cast<std::size_t>(bytes_per_line) * static_cast<std::size_t>(height - 1) + row;
}

}  // namespace

std::string fourccName(uint32_t fourcc) {
  std::string name;
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((fourcc >> (8 * i)) & 0xFF);
    name.push_back(c >= 32 && c < 127 ? c : '?');
  }
  while (!name.empty() && name.back() == ' ') name.pop_back();
  return name;
}

bool parseV4l2Input(const std::string& input, V4l2Options& options, std::string& error) {
  options = V4l2Options{};
  if (input.compare(0, 5, "v4l2:") != 0) {
    error = "'" + input + "' is not a v4l2: INPUT";
    return false;
  }
  const std::size_t q = input.find('?');
  options.device = input.substr(5, q == std::string::npos ? std::string::npos : q - 5);
  if (options.device.empty()) {
    error = "'" + input + "': no device path (expected v4l2:/dev/videoN)";
    return false;
  }
  if (q == std::string::npos) return true;
  std::size_t pos = q + 1;
  while (pos <= input.size()) {
    std::size_t amp = input.find('&', pos);
    if (amp == std::string::npos) amp = input.size();
    const std::string item = input.substr(pos, amp - pos);
    pos = amp + 1;
    if (item.empty()) continue;
    const std::size_t eq = item.find('=');
    const std::string key = item.substr(0, eq);
    const std::string value = eq == std::string::npos ? std::string() : item.substr(eq + 1);
    bool good = true;
    if (key == "width") {
      good = parseInt(value, 1, kMaxImageDimension, options.width);
    } else if (key == "height") {
      good = parseInt(value, 1, kMaxImageDimension, options.height);
    } else if (key == "fps") {
      char* end = nullptr;
      options.fps = std::strtod(value.c_str(), &end);
      good = !value.empty() && *end == '\0' && options.fps > 0.0 && options.fps <= 1000.0;
    } else if (key == "format") {
      if (value == "grey" || value == "gray") {
        options.fourcc = V4L2_PIX_FMT_GREY;
      } else if (value == "yuyv") {
        options.fourcc = V4L2_PIX_FMT_YUYV;
      } else if (value == "mjpeg" || value == "mjpg") {
        options.fourcc = V4L2_PIX_FMT_MJPEG;
      } else {
        good = false;
      }
    } else if (key == "buffers") {
      good = parseInt(value, 2, V4l2CaptureSource::kMaxBuffers, options.buffers);
    } else if (key == "timeout_ms") {
      good = parseInt(value, 1, 600000, options.timeout_ms);
    } else {
      error = "'" + input + "': unknown option '" + key +
              "' (known: width, height, fps, format=grey|yuyv|mjpeg, buffers, timeout_ms)";
      return false;
    }
    if (!good) {
      error = "'" + input + "': bad value in '" + item + "'";
      return false;
    }
  }
  if ((options.width == 0) != (options.height == 0)) {
    error = "'" + input + "': give width and height together";
    return false;
  }
  return true;
}

V4l2CaptureSource::V4l2CaptureSource(V4l2Syscalls& syscalls, const V4l2Options& options,
                                     const SourceOptions& source_options)
    : sys_(syscalls), options_(options) {
  ok_ = open(source_options);
  if (!ok_) shutdown();
}

V4l2CaptureSource::~V4l2CaptureSource() { shutdown(); }

int V4l2CaptureSource::xioctl(unsigned long request, void* arg) {
  for (;;) {
    if (sys_.ioctl(fd_, request, arg) == 0) return 0;
    const int err = errno;
    if (err != EINTR) return -err;
  }
}

bool V4l2CaptureSource::open(const SourceOptions& source_options) {
  const std::string& dev = options_.device;
  fd_ = sys_.open(dev.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) {
    const int err = errno;
    error_ = "cannot open camera '" + dev + "': " + errnoText(err) +
             (err == ENOENT   ? " (no such device; list cameras with `v4l2-ctl --list-devices`)"
              : err == EACCES ? " (add yourself to the 'video' group)"
                              : "");
    return false;
  }
  v4l2_capability cap{};
  if (const int rc = xioctl(VIDIOC_QUERYCAP, &cap); rc < 0) {
    error_ = "'" + dev + "' is not a V4L2 device (VIDIOC_QUERYCAP: " + errnoText(-rc) + ")";
    return false;
  }
  const uint32_t caps =
      (cap.capabilities & V4L2_CAP_DEVICE_CAPS) != 0 ? cap.device_caps : cap.capabilities;
  if ((caps & V4L2_CAP_VIDEO_CAPTURE) == 0) {
    error_ = "'" + dev + "' (" + reinterpret_cast<const char*>(cap.card) +
             ") is not a video capture device";
    return false;
  }
  if ((caps & V4L2_CAP_STREAMING) == 0) {
    error_ = "'" + dev + "' (" + reinterpret_cast<const char*>(cap.card) +
             ") does not support streaming I/O";
    return false;
  }
  if (!negotiateFormat()) return false;
  if (!setFrameRate(source_options)) return false;
  if (!startStreaming()) return false;
  info_.width = luma_.width();
  info_.height = luma_.height();
  info_.pixel_format = fourccName(fourcc_);
  info_.real_timestamps = true;
  info_.frame_count = -1;
  return true;
}

bool V4l2CaptureSource::negotiateFormat() {
  const std::string& dev = options_.device;
  // ENUM_FMT: the formats the device offers.
  std::array<uint32_t, kMaxFormats> offered{};
  int offered_count = 0;
  for (uint32_t i = 0; offered_count < kMaxFormats; ++i) {
    v4l2_fmtdesc desc{};
    desc.index = i;
    desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (xioctl(VIDIOC_ENUM_FMT, &desc) < 0) break;
    offered[static_cast<std::size_t>(offered_count++)] = desc.pixelformat;
  }
  auto isOffered = [&](uint32_t f) {
    for (int i = 0; i < offered_count; ++i) {
      if (offered[static_cast<std::size_t>(i)] == f) return true;
    }
    return false;
  };
  auto offeredList = [&] {
    std::string list;
    for (int i = 0; i < offered_count; ++i) {
      list += (i > 0 ? ", " : "") + fourccName(offered[static_cast<std::size_t>(i)]);
    }
    return list.empty() ? std::string("none") : list;
  };
  if (options_.fourcc != 0) {
    if (!isOffered(options_.fourcc)) {
      error_ = "'" + dev + "' does not offer format " + fourccName(options_.fourcc) +
               " (it offers: " + offeredList() + ")";
      return false;
    }
    fourcc_ = options_.fourcc;
  } else {
    for (uint32_t f : kPreferredFormats) {
      if (isOffered(f)) {
        fourcc_ = f;
        break;
      }
    }
    if (fourcc_ == 0) {
      error_ = "'" + dev +
               "' offers no format epitrack reads (GREY, YUYV, MJPG); it offers: " + offeredList();
      return false;
    }
  }

  // The size: the user's, else the offered size closest to 640x480 (ENUM_FRAMESIZES).
  int width = options_.width;
  int height = options_.height;
  if (width == 0) {
    int64_t best_cost = -1;  // pixel counts: a device may offer sizes whose product passes 2^31
    for (uint32_t i = 0; i < kMaxFrameSizes; ++i) {
      v4l2_frmsizeenum size{};
      size.index = i;
      size.pixel_format = fourcc_;
      if (xioctl(VIDIOC_ENUM_FRAMESIZES, &size) < 0) break;
      int w = 0;
      int h = 0;
      if (size.type == V4L2_FRMSIZE_TYPE_DISCRETE) {
        w = static_cast<int>(size.discrete.width);
        h = static_cast<int>(size.discrete.height);
      } else {  // stepwise or continuous: clamp the default into the range, on the step grid
        const auto& s = size.stepwise;
        auto fit = [](int want, uint32_t lo, uint32_t hi, uint32_t step) {
          const int64_t st = step > 0 ? step : 1;
          int64_t v = std::max<int64_t>(lo, std::min<int64_t>(hi, want));
          v = lo + (v - lo) / st * st;
          return static_cast<int>(v);
        };
        w = fit(kDefaultWidth, s.min_width, s.max_width, s.step_width);
        h = fit(kDefaultHeight, s.min_height, s.max_height, s.step_height);
      }
      const int64_t cost =
          std::llabs(static_cast<int64_t>(w) * h - int64_t{kDefaultWidth} * kDefaultHeight);
      if (best_cost < 0 || cost < best_cost) {
        best_cost = cost;
        width = w;
        height = h;
      }
      if (size.type != V4L2_FRMSIZE_TYPE_DISCRETE) break;
    }
    if (width == 0) {  // no size enumeration: keep the current size
      v4l2_format current{};
      current.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      if (const int rc = xioctl(VIDIOC_G_FMT, &current); rc < 0) {
        error_ = "'" + dev + "': VIDIOC_G_FMT failed: " + errnoText(-rc);
        return false;
      }
      width = static_cast<int>(current.fmt.pix.width);
      height = static_cast<int>(current.fmt.pix.height);
    }
  }

  // Sizes come from the driver here (frame-size enumeration or the current format): refuse what
  // no reader accepts (an empty frame, or more than kMaxImageDimension a side).
  if (width < 1 || height < 1 || width > kMaxImageDimension || height > kMaxImageDimension) {
    error_ = "'" + dev + "' offers no usable frame size (" + std::to_string(width) + "x" +
             std::to_string(height) + "); ask for one with ?width=W&height=H";
    return false;
  }
  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  fmt.fmt.pix.width = static_cast<uint32_t>(width);
  fmt.fmt.pix.height = static_cast<uint32_t>(height);
  fmt.fmt.pix.pixelformat = fourcc_;
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  if (const int rc = xioctl(VIDIOC_S_FMT, &fmt); rc < 0) {
    error_ = "'" + dev + "' refused format " + fourccName(fourcc_) + " " + std::to_string(width) +
             "x" + std::to_string(height) + " (VIDIOC_S_FMT: " + errnoText(-rc) + ")";
    return false;
  }
  // Drivers adjust rather than fail: check what was set, then read it back (G_FMT).
  for (int pass = 0; pass < 2; ++pass) {
    if (pass == 1) {
      fmt = v4l2_format{};
      fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      if (const int rc = xioctl(VIDIOC_G_FMT, &fmt); rc < 0) {
        error_ = "'" + dev + "': VIDIOC_G_FMT failed: " + errnoText(-rc);
        return false;
      }
    }
    const v4l2_pix_format& pix = fmt.fmt.pix;
    if (pix.pixelformat != fourcc_) {
      error_ = "'" + dev + "' refused format " + fourccName(fourcc_) + " (the driver set " +
               fourccName(pix.pixelformat) + "); ask for another with ?format=grey|yuyv|mjpeg";
      return false;
    }
    if (static_cast<int>(pix.width) != width || static_cast<int>(pix.height) != height) {
      error_ = "'" + dev + "' changed the negotiated size " + std::to_string(width) + "x" +
               std::to_string(height) + " to " + std::to_string(pix.width) + "x" +
               std::to_string(pix.height) +
               "; refusing it (ask for a size the camera offers: " + "v4l2-ctl --list-formats-ext)";
      return false;
    }
  }
  const v4l2_pix_format& pix = fmt.fmt.pix;
  const uint32_t min_line =
      fourcc_ == V4L2_PIX_FMT_YUYV ? 2 * pix.width : (fourcc_ == V4L2_PIX_FMT_GREY ? pix.width : 0);
  bytes_per_line_ = pix.bytesperline >= min_line ? pix.bytesperline : min_line;
  size_image_ = pix.sizeimage;
  if (!luma_.allocate(width, height)) {
    error_ = "cannot allocate " + std::to_string(width) + "x" + std::to_string(height) + " frames";
    return false;
  }
  if (fourcc_ == V4L2_PIX_FMT_MJPEG) {
    jpeg_ = std::make_unique<JpegDecoder>();
    if (!jpeg_->valid()) {
      error_ = "TurboJPEG decoder could not be created";
      return false;
    }
  }
  return true;
}

bool V4l2CaptureSource::setFrameRate(const SourceOptions& source_options) {
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  const bool have_parm = xioctl(VIDIOC_G_PARM, &parm) == 0;
  const bool settable = have_parm && (parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME) != 0;
  if (options_.fps > 0.0 && settable) {
    // timeperframe = 1 / fps as a fraction (1000 / (1000 fps) keeps 29.97 exact enough).
    parm.parm.capture.timeperframe.numerator = 1000;
    parm.parm.capture.timeperframe.denominator =
        static_cast<uint32_t>(std::lround(options_.fps * 1000.0));
    if (const int rc = xioctl(VIDIOC_S_PARM, &parm); rc < 0) {
      error_ = "'" + options_.device + "': cannot set " + std::to_string(options_.fps) +
               " fps (VIDIOC_S_PARM: " + errnoText(-rc) + ")";
      return false;
    }
  }
  const v4l2_fract& tpf = parm.parm.capture.timeperframe;
  if (have_parm && tpf.numerator > 0 && tpf.denominator > 0) {
    info_.fps = static_cast<double>(tpf.denominator) / tpf.numerator;
  } else {
    info_.fps = options_.fps > 0.0 ? options_.fps : source_options.default_fps;
  }
  return true;
}

bool V4l2CaptureSource::startStreaming() {
  const std::string& dev = options_.device;
  v4l2_requestbuffers req{};
  req.count = static_cast<uint32_t>(options_.buffers);
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  if (const int rc = xioctl(VIDIOC_REQBUFS, &req); rc < 0) {
    error_ = "'" + dev + "' cannot allocate mmap buffers (VIDIOC_REQBUFS: " + errnoText(-rc) + ")";
    return false;
  }
  buffers_requested_ = true;
  if (req.count < 2 || req.count > static_cast<uint32_t>(kMaxBuffers)) {
    error_ = "'" + dev + "' granted " + std::to_string(req.count) + " buffers (need 2.." +
             std::to_string(kMaxBuffers) + ")";
    return false;
  }
  const std::size_t needed =
      fourcc_ == V4L2_PIX_FMT_MJPEG
          ? 1
          : minimumBytesUsed(fourcc_, luma_.width(), luma_.height(), bytes_per_line_);
  std::size_t largest = 0;
  for (uint32_t i = 0; i < req.count; ++i) {
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = i;
    if (const int rc = xioctl(VIDIOC_QUERYBUF, &buf); rc < 0) {
      error_ = "'" + dev + "': VIDIOC_QUERYBUF " + std::to_string(i) + ": " + errnoText(-rc);
      // 32-bit builds have 64-bit time (cmake/EpitrackCompileOptions.cmake), so their
      // v4l2_buffer is the time64 layout, which kernels before 5.6 do not know (ENOTTY).
      if (rc == -ENOTTY && sizeof(void*) == 4) {
        error_ += " (this 32-bit build passes 64-bit timestamps, which need Linux 5.6 or later)";
      }
      return false;
    }
    if (buf.length < needed) {
      error_ = "'" + dev + "': buffer " + std::to_string(i) + " holds " +
               std::to_string(buf.length) + " bytes, a frame needs " + std::to_string(needed);
      return false;
    }
    void* data = sys_.mmap(nullptr, buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_,
                           static_cast<off_t>(buf.m.offset));
    if (data == MAP_FAILED) {
      error_ = "'" + dev + "': cannot map buffer " + std::to_string(i) + ": " + errnoText(errno);
      return false;
    }
    buffers_[i] = MappedBuffer{data, buf.length};
    buffer_count_ = static_cast<int>(i) + 1;
    largest = std::max<std::size_t>(largest, buf.length);
  }
  if (fourcc_ == V4L2_PIX_FMT_MJPEG) encoded_.reserve(largest);
  for (int i = 0; i < buffer_count_; ++i) {
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = static_cast<uint32_t>(i);
    if (const int rc = xioctl(VIDIOC_QBUF, &buf); rc < 0) {
      error_ = "'" + dev + "': VIDIOC_QBUF " + std::to_string(i) + ": " + errnoText(-rc);
      return false;
    }
  }
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (const int rc = xioctl(VIDIOC_STREAMON, &type); rc < 0) {
    error_ = "'" + dev + "': cannot start streaming (VIDIOC_STREAMON: " + errnoText(-rc) + ")";
    return false;
  }
  streaming_ = true;
  return true;
}

void V4l2CaptureSource::shutdown() {
  if (fd_ < 0) return;
  if (streaming_) {
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    xioctl(VIDIOC_STREAMOFF, &type);  // fails harmlessly (ENODEV) on an unplugged device
    streaming_ = false;
  }
  for (int i = 0; i < buffer_count_; ++i) {
    MappedBuffer& b = buffers_[static_cast<std::size_t>(i)];
    if (b.data != nullptr) sys_.munmap(b.data, b.length);
    b = MappedBuffer{};
  }
  buffer_count_ = 0;
  if (buffers_requested_) {
    v4l2_requestbuffers req{};
    req.count = 0;
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    xioctl(VIDIOC_REQBUFS, &req);
    buffers_requested_ = false;
  }
  sys_.close(fd_);
  fd_ = -1;
}

FrameStatus V4l2CaptureSource::convert(const MappedBuffer& buffer, std::size_t bytes_used,
                                       int64_t index) {
  const auto* src = static_cast<const uint8_t*>(buffer.data);
  const int w = luma_.width();
  const int h = luma_.height();
  if (bytes_used > buffer.length) {
    // A driver bug, but trusting it read past the mapped buffer, and for MJPEG grew the encoded
    // copy to the claimed size (3 GB in the fuzzer's case; found by fuzzing).
    error_ = "'" + options_.device + "': frame " + std::to_string(index) + " claims " +
             std::to_string(bytes_used) + " bytes in a buffer of " + std::to_string(buffer.length);
    return FrameStatus::kCorruptFrame;
  }
  if (fourcc_ == V4L2_PIX_FMT_MJPEG) {
    if (bytes_used < 4) {
      error_ = "'" + options_.device + "': frame " + std::to_string(index) + " is empty (" +
               std::to_string(bytes_used) + " bytes)";
      return FrameStatus::kCorruptFrame;
    }
    encoded_.resize(bytes_used);  // within the capacity reserved at open
    std::memcpy(encoded_.data(), src, bytes_used);
    if (!jpeg_->decodeGray(encoded_.data(), bytes_used, luma_.view(), error_)) {
      error_ = "'" + options_.device + "': frame " + std::to_string(index) + ": " + error_;
      return FrameStatus::kCorruptFrame;
    }
    return FrameStatus::kOk;
  }
  const std::size_t needed = minimumBytesUsed(fourcc_, w, h, bytes_per_line_);
  if (bytes_used < needed) {
    error_ = "'" + options_.device + "': frame " + std::to_string(index) + " is short (" +
             std::to_string(bytes_used) + " of " + std::to_string(needed) + " bytes)";
    return FrameStatus::kCorruptFrame;
  }
  if (fourcc_ == V4L2_PIX_FMT_GREY) {
    for (int y = 0; y < h; ++y) {
      std::memcpy(luma_.row(y), src + static_cast<std::size_t>(y) * bytes_per_line_,
                  static_cast<std::size_t>(w));
    }
  } else {  // YUYV: Y0 U Y1 V, luma at the even bytes
    for (int y = 0; y < h; ++y) {
      const uint8_t* in = src + static_cast<std::size_t>(y) * bytes_per_line_;
      uint8_t* out = luma_.row(y);
      for (int x = 0; x < w; ++x) out[x] = in[2 * x];
    }
  }
  return FrameStatus::kOk;
}

FrameStatus V4l2CaptureSource::next(Frame& frame) {
  if (!ok_) return FrameStatus::kError;
  if (lost_) return FrameStatus::kDeviceLost;
  int again = 0;
  int eio = 0;
  for (;;) {
    pollfd p{};
    p.fd = fd_;
    p.events = POLLIN;
    const int ready = sys_.poll(&p, 1, options_.timeout_ms);
    if (ready < 0) {
      const int err = errno;
      if (err == EINTR) continue;
      error_ = "'" + options_.device + "': poll failed: " + errnoText(err);
      return FrameStatus::kError;
    }
    if (ready == 0) {
      error_ = "'" + options_.device + "': no frame within " + std::to_string(options_.timeout_ms) +
               " ms";
      return FrameStatus::kTimeout;
    }
    // Ready, or POLLERR/POLLHUP: DQBUF says which.
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    const int rc = xioctl(VIDIOC_DQBUF, &buf);
    if (rc == -EAGAIN) {
      if (++again > kMaxAgainRetries) {
        error_ = "'" + options_.device + "': no frame after " + std::to_string(again) +
                 " wake-ups (EAGAIN)";
        return FrameStatus::kTimeout;
      }
      continue;
    }
    if (rc == -EIO) {
      ++eio_total_;
      if (++eio > kMaxEioRetries) {
        error_ = "'" + options_.device + "': input/output error " + std::to_string(eio) +
                 " times in a row (VIDIOC_DQBUF: EIO)";
        return FrameStatus::kError;
      }
      continue;
    }
    if (rc == -ENODEV) {
      lost_ = true;
      error_ = "'" + options_.device + "': device lost (unplugged?)";
      return FrameStatus::kDeviceLost;
    }
    if (rc < 0) {
      error_ = "'" + options_.device + "': VIDIOC_DQBUF: " + errnoText(-rc);
      return FrameStatus::kError;
    }
    if (buf.index >= static_cast<uint32_t>(buffer_count_)) {
      error_ = "'" + options_.device + "': driver returned buffer " + std::to_string(buf.index) +
               " of " + std::to_string(buffer_count_);
      return FrameStatus::kError;
    }
    // Read everything the frame needs from `buf` now: VIDIOC_QBUF below hands the buffer back and
    // the kernel (videobuf2) rewrites the caller's struct with the re-queued buffer's state, whose
    // timestamp is no longer this frame's (found on Linux 6.1 with vivid under qemu).
    const auto sequence = static_cast<int64_t>(buf.sequence);
    const double timestamp_s = static_cast<double>(buf.timestamp.tv_sec) +
                               static_cast<double>(buf.timestamp.tv_usec) * 1e-6;
    if (first_sequence_ < 0) {
      first_sequence_ = sequence;
      first_timestamp_s_ = timestamp_s;
    }
    // Index: frames since the first, by the driver's sequence number when it counts (so dropped
    // frames leave gaps), else by our count.
    const int64_t index = std::max(frames_dequeued_, sequence - first_sequence_);
    frames_dequeued_ = index + 1;
    FrameStatus status = FrameStatus::kOk;
    if ((buf.flags & V4L2_BUF_FLAG_ERROR) != 0) {
      error_ = "'" + options_.device + "': frame " + std::to_string(index) +
               " flagged as damaged by the driver";
      status = FrameStatus::kCorruptFrame;
    } else {
      status = convert(buffers_[buf.index], buf.bytesused, index);
    }
    // Give the buffer back to the driver before handing out the converted frame.
    const int qrc = xioctl(VIDIOC_QBUF, &buf);
    if (qrc == -ENODEV) {
      lost_ = true;  // reported by the next call
      error_ = "'" + options_.device + "': device lost (unplugged?)";
    } else if (qrc < 0) {
      error_ = "'" + options_.device + "': VIDIOC_QBUF: " + errnoText(-qrc);
      return FrameStatus::kError;
    }
    if (status != FrameStatus::kOk) return status;
    frame.luma = luma_.constView();
    frame.index = index;
    frame.timestamp_s = timestamp_s - first_timestamp_s_;
    frame.encoded = fourcc_ == V4L2_PIX_FMT_MJPEG ? encoded_.data() : nullptr;
    frame.encoded_size = fourcc_ == V4L2_PIX_FMT_MJPEG ? encoded_.size() : 0;
    return FrameStatus::kOk;
  }
}

std::unique_ptr<FrameSource> openV4l2Source(const std::string& input, V4l2Syscalls& syscalls,
                                            const SourceOptions& options, std::string& error) {
  V4l2Options v4l2;
  if (!parseV4l2Input(input, v4l2, error)) return nullptr;
  auto source = std::make_unique<V4l2CaptureSource>(syscalls, v4l2, options);
  if (!source->ok()) {
    error = source->lastError();
    return nullptr;
  }
  return source;
}

}  // namespace epitrack::hal
