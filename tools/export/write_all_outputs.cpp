#include <string>

#include "hal/io/file_util.hpp"
#include "tools/export/output_writers.hpp"

namespace epitrack::io {

namespace {
std::string withSlash(const std::string& dir) {
  return (!dir.empty() && dir.back() == '/') ? dir : dir + "/";
}
}  // namespace

const std::vector<std::string>& exportFileNames() {
  static const std::vector<std::string> names = {
      "cameras.tum",        "intrinsics.txt",    "points.ply",
      "colmap/cameras.txt", "colmap/images.txt", "colmap/points3D.txt",
      "blender_camera.py",  "camera.chan",       "camera.nk"};
  return names;
}

bool writeSummaryJson(const Reconstruction& rec, const std::string& dir, std::string& error) {
  return hal::writeTextAtomic(withSlash(dir) + "summary.json", formatSummaryJson(rec), error);
}

bool writeAllOutputs(const Reconstruction& rec, const std::string& dir, std::string& error) {
  return writeAllOutputs(rec, dir, ExportOptions{}, error);
}

bool writeAllOutputs(const Reconstruction& rec, const std::string& dir,
                     const ExportOptions& options, std::string& error) {
  const std::string base = withSlash(dir);
  if (!hal::makeDirectories(base + "colmap", error)) return false;
  const std::vector<uint8_t> ply = formatPointsPly(rec);
  const bool written =
      hal::writeTextAtomic(base + "cameras.tum", formatCamerasTum(rec), error) &&
      hal::writeTextAtomic(base + "intrinsics.txt", formatIntrinsicsFile(rec), error) &&
      hal::writeFileAtomic(base + "points.ply", ply.data(), ply.size(), error) &&
      hal::writeTextAtomic(base + "colmap/cameras.txt", formatColmapCameras(rec), error) &&
      hal::writeTextAtomic(base + "colmap/images.txt", formatColmapImages(rec, options), error) &&
      hal::writeTextAtomic(base + "colmap/points3D.txt", formatColmapPoints3D(rec), error) &&
      hal::writeTextAtomic(base + "blender_camera.py", formatBlenderScript(rec, options), error) &&
      hal::writeTextAtomic(base + "camera.chan", formatNukeChan(rec, options), error) &&
      hal::writeTextAtomic(base + "camera.nk", formatNukeScript(rec, options), error);
  if (!written) return false;
  std::vector<std::string> names = exportFileNames();
  if (rec.readout_frames > 0.0) {
    if (!hal::writeTextAtomic(base + "rolling_shutter.txt", formatRollingShutter(rec), error))
      return false;
    names.insert(names.begin() + 1, "rolling_shutter.txt");
  }
  // Last, so that a complete summary means a complete output directory.
  return hal::writeTextAtomic(base + "summary.json", formatSummaryJson(rec, names), error);
}

}  // namespace epitrack::io
