#include <string>

#include "hal/io/file_util.hpp"
#include "tools/export/output_writers.hpp"

namespace epitrack::io {

bool writeAllOutputs(const Reconstruction& rec, const std::string& dir, std::string& error) {
  return writeAllOutputs(rec, dir, ExportOptions{}, error);
}

bool writeAllOutputs(const Reconstruction& rec, const std::string& dir,
                     const ExportOptions& options, std::string& error) {
  const std::string base = (!dir.empty() && dir.back() == '/') ? dir : dir + "/";
  if (!hal::makeDirectories(base + "colmap", error)) return false;
  const std::vector<uint8_t> ply = formatPointsPly(rec);
  return hal::writeTextAtomic(base + "cameras.tum", formatCamerasTum(rec), error) &&
         hal::writeTextAtomic(base + "intrinsics.txt", formatIntrinsicsFile(rec), error) &&
         hal::writeFileAtomic(base + "points.ply", ply.data(), ply.size(), error) &&
         hal::writeTextAtomic(base + "colmap/cameras.txt", formatColmapCameras(rec), error) &&
         hal::writeTextAtomic(base + "colmap/images.txt", formatColmapImages(rec, options),
                              error) &&
         hal::writeTextAtomic(base + "colmap/points3D.txt", formatColmapPoints3D(rec), error) &&
         hal::writeTextAtomic(base + "blender_camera.py", formatBlenderScript(rec, options),
                              error) &&
         hal::writeTextAtomic(base + "camera.chan", formatNukeChan(rec, options), error) &&
         // Last, so that a complete summary means a complete output directory.
         hal::writeTextAtomic(base + "summary.json", formatSummaryJson(rec), error);
}

}  // namespace epitrack::io
