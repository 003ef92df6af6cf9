#pragma once

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "algo/image/image.hpp"
#include "hal/frame_source.hpp"
#include "hal/replay/replay_pacer.hpp"

namespace epitrack::hal {

/// The parsed stream header of a YUV4MPEG2 (Y4M) file: `YUV4MPEG2 W.. H.. F.. I.. A.. C.. X..`.
struct Y4mHeader {
  int width = 0;
  int height = 0;
  int fps_num = 0;  ///< F tag; 0 when absent
  int fps_den = 0;
  std::string chroma = "420jpeg";  ///< C tag (default 420jpeg, as in the mjpegtools spec)
  int bit_depth = 8;               ///< 8, or 9..16 for the `p10`/`p12`/`p16`/`mono16` forms
  /// Bytes of the planes after luma in one frame (chroma and alpha, skipped).
  std::size_t other_plane_bytes = 0;
};

/// Parses a Y4M stream header line (without the trailing newline). Any chroma layout of the
/// mjpegtools/ffmpeg family is accepted: 420jpeg, 420paldv, 420mpeg2, 420, 411, 422, 444,
/// 444alpha, mono, and their high-bit-depth forms (420p10, 422p12, 444p16, mono16, ...).
bool parseY4mHeader(const std::string& line, Y4mHeader& header, std::string& error);

/// Replays a Y4M stream (a file, or standard input for INPUT `-`): the luma plane of each frame
/// is read into a buffer sized at open; chroma is read into scratch and dropped. High bit depths
/// are reduced to 8 bits (value >> (depth - 8)). A frame cut short by the end of the stream is a
/// corrupt frame (naming the frame and the byte offset), followed by the end of the stream.
class Y4mSource final : public FrameSource {
 public:
  /// Opens a file by path ("-": standard input). Check `ok()` / `lastError()`.
  Y4mSource(const std::string& path, const SourceOptions& options);
  /// Reads from an open stream (e.g. a pipe); takes ownership of `stream` when `owns_stream`.
  Y4mSource(std::FILE* stream, bool owns_stream, const std::string& name,
            const SourceOptions& options);
  ~Y4mSource() override;

  [[nodiscard]] bool ok() const { return ok_; }
  FrameStatus next(Frame& frame) override;

 private:
  void openStream(const SourceOptions& options, std::int64_t file_size);
  /// Reads up to the next '\n' (exclusive) into `line` (capacity reserved at open); false at EOF
  /// or when the line is longer than `max_length`.
  bool readLine(std::string& line, std::size_t max_length);
  std::size_t readBytes(void* dst, std::size_t size);

  std::FILE* stream_ = nullptr;
  bool owns_stream_ = false;
  std::string name_;
  Y4mHeader header_;
  Image<uint8_t> luma_;
  std::vector<uint8_t> scratch_;           // one high-bit-depth luma row, or the chroma planes
  std::unique_ptr<char[]> stream_buffer_;  // stdio buffer, left uninitialised (1 MB)
  std::string line_;
  ReplayPacer pacer_;
  std::int64_t next_index_ = 0;
  std::uint64_t offset_ = 0;  // bytes consumed, for messages
  bool ok_ = false;
  bool ended_ = false;
};

}  // namespace epitrack::hal
