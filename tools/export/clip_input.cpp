#include "tools/export/clip_input.hpp"

#include <filesystem>
#include <system_error>

namespace epitrack::io {

namespace {

std::string absolutePath(const std::filesystem::path& p) {
  std::error_code ec;
  const std::filesystem::path a = std::filesystem::absolute(p, ec);
  return (ec ? p : a).lexically_normal().string();
}

}  // namespace

void describeClipInput(Reconstruction& rec, const std::string& input,
                       const std::vector<std::string>& frame_paths, double fps) {
  namespace fs = std::filesystem;
  rec.fps = fps > 0.0 ? fps : 0.0;
  rec.frame_names.clear();
  rec.frames_dir.clear();
  rec.input_movie.clear();
  bool any_file = false;
  for (const std::string& p : frame_paths) any_file = any_file || !p.empty();
  if (any_file) {
    rec.frame_names.reserve(frame_paths.size());
    for (const std::string& p : frame_paths) {
      const fs::path path(p);
      if (rec.frames_dir.empty() && !p.empty()) rec.frames_dir = absolutePath(path.parent_path());
      rec.frame_names.push_back(path.filename().string());
    }
    return;
  }
  // "-" is stdin and "/dev/video*" a device: no file to show as a plate.
  std::error_code ec;
  if (input != "-" && fs::is_regular_file(input, ec)) rec.input_movie = absolutePath(input);
}

}  // namespace epitrack::io
