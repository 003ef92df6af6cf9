// libFuzzer harness: the COLMAP text model reader of tools/export (cameras.txt, images.txt,
// points3D.txt) and its cross-reference check. The input holds the three files separated by form
// feeds ('\f'); each parser also reads the whole input. Invariants: a parser either accepts or
// names the line; the consistency check terminates with a message when it refuses; what it
// accepts really is consistent (every 2D-3D reference points back).
#include <string>
#include <vector>

#include "tests/fuzz/fuzz_support.hpp"
#include "tools/export/colmap_text.hpp"

namespace io = epitrack::io;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::string parts[3];
  {
    std::size_t start = 0;
    for (int i = 0; i < 3; ++i) {
      const std::size_t end = i < 2 ? text.find('\f', start) : std::string::npos;
      if (start <= text.size())
        parts[i] = text.substr(start, end == std::string::npos ? std::string::npos : end - start);
      start = end == std::string::npos ? text.size() + 1 : end + 1;
    }
  }
  std::string error;
  io::ColmapModel whole;
  if (!io::parseColmapCameras(text, whole.cameras, error)) FUZZ_CHECK(!error.empty());
  if (!io::parseColmapImages(text, whole.images, error)) FUZZ_CHECK(!error.empty());
  if (!io::parseColmapPoints3D(text, whole.points, error)) FUZZ_CHECK(!error.empty());

  io::ColmapModel model;
  if (!io::parseColmapCameras(parts[0], model.cameras, error) ||
      !io::parseColmapImages(parts[1], model.images, error) ||
      !io::parseColmapPoints3D(parts[2], model.points, error)) {
    FUZZ_CHECK(!error.empty());
    return 0;
  }
  error.clear();
  if (!io::checkColmapConsistency(model, error)) {
    FUZZ_CHECK(!error.empty());
    return 0;
  }
  // Accepted: every triangulated 2D point is in the track of an existing 3D point.
  for (const io::ColmapImage& image : model.images) {
    for (std::size_t i = 0; i < image.points.size(); ++i) {
      const int64_t id = image.points[i].point3d_id;
      if (id == -1) continue;
      bool found = false;
      for (const io::ColmapPoint3D& p : model.points) {
        if (p.id != id) continue;
        for (const auto& [image_id, index] : p.track) {
          found = found || (image_id == image.id && index == static_cast<int>(i));
        }
      }
      FUZZ_CHECK(found);
    }
  }
  return 0;
}
