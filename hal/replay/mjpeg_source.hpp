#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "algo/image/image.hpp"
#include "hal/frame_source.hpp"
#include "hal/io/image_codec.hpp"
#include "hal/replay/replay_pacer.hpp"

namespace epitrack::hal {

/// Replays a `.mjpeg`/`.mjpg` file of concatenated JPEG frames (what the device and
/// `epitrack-record` write). The file is memory-mapped; frames are found by walking the JPEG
/// markers and decoded straight to gray by one TurboJPEG handle created at open. A frame that does
/// not decode is a corrupt frame (naming its index and byte offset) and replay goes on; a frame of
/// another size is an error.
class MjpegSource final : public FrameSource {
 public:
  MjpegSource(const std::string& path, const SourceOptions& options);
  ~MjpegSource() override;

  [[nodiscard]] bool ok() const { return ok_; }
  FrameStatus next(Frame& frame) override;

 private:
  std::string path_;
  const uint8_t* data_ = nullptr;
  std::size_t size_ = 0;
  std::size_t pos_ = 0;
  JpegDecoder decoder_;
  Image<uint8_t> luma_;
  ReplayPacer pacer_;
  std::int64_t next_index_ = 0;
  bool ok_ = false;
};

}  // namespace epitrack::hal
