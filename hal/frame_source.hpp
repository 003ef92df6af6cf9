#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "algo/image/image_view.hpp"

namespace epitrack::hal {

/// Result of FrameSource::next.
enum class FrameStatus {
  kOk,            ///< `frame` holds a new frame
  kEndOfStream,   ///< no more frames (replay finished)
  kTimeout,       ///< a live source produced nothing within its timeout; try again
  kDeviceLost,    ///< the device went away (unplugged); the source is finished
  kCorruptFrame,  ///< this frame could not be decoded; the caller may skip it and go on
  kError,         ///< unrecoverable; `lastError()` says why
};
const char* frameStatusName(FrameStatus status);

/// One frame: a view of 8-bit luma owned by the source (valid until the next `next` call), its
/// index in the stream (0-based, counting skipped and corrupt frames) and a timestamp in seconds.
struct Frame {
  ImageView<const uint8_t> luma;
  int64_t index = -1;
  double timestamp_s = 0.0;
  /// The compressed JPEG this frame was decoded from, when the source delivers JPEG (MJPEG replay,
  /// V4L2 MJPEG); nullptr otherwise. Valid until the next `next` call. A recorder writes these
  /// bytes unchanged so that a recording replays bit-identically.
  const uint8_t* encoded = nullptr;
  std::size_t encoded_size = 0;
  /// The file this frame was read from, as listed (image directories); empty for streams and
  /// devices. Valid until the source is destroyed. The exports name the frames with it (COLMAP's
  /// images.txt, the Blender and Nuke plates).
  std::string_view path;
};

struct SourceInfo {
  int width = 0;
  int height = 0;
  double fps = 0.0;          ///< nominal frame rate
  std::string pixel_format;  ///< "PGM", "PNG", "JPEG", "Y4M 420jpeg", "GREY", "YUYV", "MJPG", ...
  bool real_timestamps =
      false;                 ///< true when timestamps come from the device or file, not index/fps
  int64_t frame_count = -1;  ///< frames in a replay, -1 when unknown (live or streamed)
};

/// A stream of 8-bit gray frames. Buffers belong to the source and are reused: after opening,
/// `next` does not allocate (decoders reach their steady buffer sizes within the first frames).
class FrameSource {
 public:
  FrameSource() = default;
  FrameSource(const FrameSource&) = delete;
  FrameSource& operator=(const FrameSource&) = delete;
  virtual ~FrameSource() = default;

  virtual FrameStatus next(Frame& frame) = 0;
  [[nodiscard]] const SourceInfo& info() const { return info_; }
  /// Why the last call did not return kOk (names the file, device or byte offset).
  [[nodiscard]] const std::string& lastError() const { return error_; }

 protected:
  SourceInfo info_;
  std::string error_;
};

struct SourceOptions {
  bool realtime =
      false;  ///< pace replay at the nominal rate (device loop); default: as fast as possible
  double default_fps = 30.0;  ///< nominal rate of sources that carry none (image directories)
};

/// Opens an INPUT string (see ARCHITECTURE.md "Inputs"). Returns nullptr and sets `error` when it
/// cannot be opened (missing path, no frames, unreadable first frame, unsupported kind).
std::unique_ptr<FrameSource> openFrameSource(const std::string& input, const SourceOptions& options,
                                             std::string& error);

}  // namespace epitrack::hal
