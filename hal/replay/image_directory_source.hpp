#pragma once

#include <string>
#include <vector>

#include "algo/image/image.hpp"
#include "hal/frame_source.hpp"
#include "hal/io/image_codec.hpp"
#include "hal/replay/replay_pacer.hpp"

namespace epitrack::hal {

/// Replays a directory of frames (*.jpg, *.jpeg, *.png, *.pgm, *.ppm) sorted by name. The frame
/// buffer is sized from the first file; a later file of another size is an error naming it, an
/// undecodable file a corrupt frame naming it.
class ImageDirectorySource final : public FrameSource {
 public:
  /// Lists the directory and reads the first frame's header; check `ok()` / `lastError()`.
  ImageDirectorySource(const std::string& dir, const SourceOptions& options);
  [[nodiscard]] bool ok() const { return ok_; }
  FrameStatus next(Frame& frame) override;
  [[nodiscard]] const std::vector<std::string>& paths() const { return paths_; }

 private:
  std::vector<std::string> paths_;
  GrayImageDecoder decoder_;
  Image<uint8_t> buffer_;
  ReplayPacer pacer_;
  std::size_t next_ = 0;
  bool ok_ = false;
};

}  // namespace epitrack::hal
