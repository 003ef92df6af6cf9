#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "hal/frame_source.hpp"
#include "hal/io/image_codec.hpp"

namespace epitrack::hal {

struct RecorderOptions {
  int jpeg_quality = 92;  ///< for frames that arrive uncompressed
  /// Write the source's own JPEG bytes (Frame::encoded) unchanged when it has them, so an MJPEG
  /// camera's recording replays bit-identically; otherwise frames are re-encoded.
  bool pass_through_jpeg = true;
};

/// Writes any FrameSource's frames out: to `FILE.mjpeg`/`FILE.mjpg` (concatenated JPEGs, the
/// TurboJPEG handle created once) or to a directory of PGM frames `000000.pgm`, ... (lossless: a
/// gray or YUYV capture replays bit-identically). Outputs are atomic: the .mjpeg is written under a
/// temporary name and renamed by `finish` (or the destructor); each PGM is written to a temporary
/// name and renamed. After the first frame, `write` reuses its buffers.
class FrameRecorder {
 public:
  enum class Kind { kNone, kMjpeg, kPgmDirectory };

  FrameRecorder() = default;
  ~FrameRecorder();
  FrameRecorder(const FrameRecorder&) = delete;
  FrameRecorder& operator=(const FrameRecorder&) = delete;

  /// Opens `output`: a path ending in .mjpeg/.mjpg is a file, anything else a directory (created
  /// with its parents). False with a message naming the path.
  bool open(const std::string& output, const RecorderOptions& options, std::string& error);
  /// Appends one frame. False with a message (disk full, ...).
  bool write(const Frame& frame, std::string& error);
  /// Completes the output (renames the .mjpeg into place). Idempotent.
  bool finish(std::string& error);

  [[nodiscard]] Kind kind() const { return kind_; }
  [[nodiscard]] int64_t framesWritten() const { return frames_; }
  [[nodiscard]] uint64_t bytesWritten() const { return bytes_; }
  /// The temporary name of the .mjpeg while recording.
  [[nodiscard]] const std::string& temporaryPath() const { return temp_path_; }

 private:
  bool writeAll(int fd, const uint8_t* data, std::size_t size, const std::string& name,
                std::string& error);

  Kind kind_ = Kind::kNone;
  RecorderOptions options_;
  std::string output_;
  std::string temp_path_;
  int fd_ = -1;
  JpegEncoder encoder_;
  std::vector<uint8_t> pgm_;
  std::string frame_path_;  // capacity reserved at open
  std::string frame_temp_;
  int64_t frames_ = 0;
  uint64_t bytes_ = 0;
};

}  // namespace epitrack::hal
