#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace epitrack::render {

/// Writes an MJPEG AVI (RIFF 'AVI ' with an 'idx1' index: the classic AVI 1.0 layout that ffmpeg,
/// mpv and VLC play). Frames are JPEG files as produced by hal::JpegEncoder. The file is written
/// to `path + ".tmp"` and renamed in `finish()`, so an interrupted run leaves no broken video.
/// Limit: AVI 1.0 offsets are 32-bit, so a video is refused beyond 2 GiB (no OpenDML).
class MjpegAviWriter {
 public:
  MjpegAviWriter() = default;
  ~MjpegAviWriter();
  MjpegAviWriter(const MjpegAviWriter&) = delete;
  MjpegAviWriter& operator=(const MjpegAviWriter&) = delete;

  bool open(const std::string& path, int width, int height, double fps, std::string& error);
  bool addFrame(const uint8_t* jpeg, std::size_t size, std::string& error);
  /// Writes the index, fixes the header sizes and renames the file into place.
  bool finish(std::string& error);
  [[nodiscard]] int frames() const { return static_cast<int>(index_.size()); }

 private:
  struct IndexEntry {
    uint32_t offset;  // from the 'movi' fourcc
    uint32_t size;
  };
  bool writeHeaders(std::string& error);
  std::FILE* file_ = nullptr;
  std::string path_;
  std::string tmp_path_;
  int width_ = 0;
  int height_ = 0;
  double fps_ = 30.0;
  long movi_start_ = 0;  // file offset of the 'movi' list's fourcc
  uint32_t max_frame_bytes_ = 0;
  std::vector<IndexEntry> index_;
};

}  // namespace epitrack::render
