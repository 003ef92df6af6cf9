#pragma once

// The user mask of epitrack-track and epitrack-solve (`--mask PGM|DIR`): zero pixels are never
// tracked (moving people, sky, a logo).

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "algo/image/image.hpp"
#include "hal/io/file_util.hpp"
#include "hal/io/image_codec.hpp"

namespace epitrack::tools {

/// A user mask: one PGM for every frame, or a directory with one image per frame (by sorted
/// position; the last one is reused when the directory holds fewer).
class MaskSource {
 public:
  bool open(const std::string& spec, std::string& error) {
    if (spec.empty()) return true;
    if (hal::isDirectory(spec)) {
      if (!hal::listFrameFiles(spec, paths_, error)) return false;
    } else {
      paths_.push_back(spec);
    }
    // The first mask is read now, so that a missing or unreadable --mask is reported before
    // anything starts (exit 2), not at the first frame.
    if (!decoder_.decodeFile(paths_.front(), image_, error)) return false;
    loaded_ = 0;
    return true;
  }
  /// The mask for frame `index` (empty view when there is none).
  bool maskFor(int64_t index, int width, int height, ImageView<const uint8_t>& mask,
               std::string& error) {
    mask = {};
    if (paths_.empty()) return true;
    const auto i =
        static_cast<std::size_t>(std::min<int64_t>(index, static_cast<int64_t>(paths_.size()) - 1));
    if (i != loaded_) {
      if (!decoder_.decodeFile(paths_[i], image_, error)) return false;
      loaded_ = i;
    }
    if (image_.width() != width || image_.height() != height) {
      error = paths_[i] + ": mask is " + std::to_string(image_.width()) + "x" +
              std::to_string(image_.height()) + ", frames are " + std::to_string(width) + "x" +
              std::to_string(height);
      return false;
    }
    mask = image_.constView();
    return true;
  }

 private:
  std::vector<std::string> paths_;
  std::size_t loaded_ = static_cast<std::size_t>(-1);
  hal::GrayImageDecoder decoder_;
  Image<uint8_t> image_;
};

}  // namespace epitrack::tools
