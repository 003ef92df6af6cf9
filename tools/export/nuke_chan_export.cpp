// Nuke: camera.chan (a Camera node's File > Import chan file) and camera.nk (a script holding the
// Camera with everything .chan cannot carry, and a Read node for the plate).

#include <cctype>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

#include "tools/export/export_geometry.hpp"
#include "tools/export/output_writers.hpp"

namespace epitrack::io {

namespace {

constexpr double kDegrees = 180.0 / std::numbers::pi;

struct NukeKey {
  int64_t frame = 0;      ///< Nuke frame
  Eigen::Vector3d t;      ///< translate, Nuke world (Y up)
  Eigen::Vector3d r_deg;  ///< rotate, degrees, order ZXY
};

/// One key per solved camera: our world turned Y-up, the camera looking down -Z, and each angle
/// unwrapped to within 180 degrees of the previous frame's so that Nuke's interpolation between
/// frames (motion blur, retiming) never spins the camera around.
std::vector<NukeKey> nukeKeys(const Reconstruction& rec, const ExportOptions& options) {
  const Eigen::Matrix3d W = ourWorldToNukeWorld();
  std::vector<NukeKey> keys;
  for (const SolvedCamera& c : rec.cameras) {
    if (!c.solved || !c.R_wc.allFinite() || !c.p_wc.allFinite()) continue;
    NukeKey k;
    k.frame = c.frame + options.nuke_frame_offset;
    k.t = W * c.p_wc;
    k.r_deg = nukeZxyFromRotation(W * glCameraRotation(c.R_wc)) * kDegrees;
    if (!keys.empty()) {
      const Eigen::Vector3d& previous = keys.back().r_deg;
      for (int a = 0; a < 3; ++a)
        k.r_deg[a] -= 360.0 * std::round((k.r_deg[a] - previous[a]) / 360.0);
    }
    keys.push_back(k);
  }
  return keys;
}

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.10g", std::isfinite(v) ? v : 0.0);
  return buf;
}

/// A Nuke (TCL) string in double quotes.
std::string nukeString(const std::string& text) {
  std::string s = "\"";
  for (const char ch : text) {
    if (ch == '"' || ch == '\\' || ch == '[' || ch == ']' || ch == '$') s += '\\';
    s += ch;
  }
  return s + "\"";
}

/// `{curve x<frame> <value> ...}` of one component of the keys.
template <typename Get>
std::string curve(const std::vector<NukeKey>& keys, Get get) {
  std::string s = "{curve";
  for (const NukeKey& k : keys) s += " x" + std::to_string(k.frame) + " " + num(get(k));
  return s + "}";
}

/// Frame files named prefix + number + suffix with consecutive numbers (one per readable frame):
/// the Read node's `file` pattern with Nuke's %0Nd and the first and last file numbers.
bool numberedSequence(const std::vector<std::string>& names, std::string& pattern, long& first,
                      long& last) {
  if (names.empty()) return false;
  const std::string& n0 = names.front();
  const std::size_t dot = n0.find_last_of('.');
  const std::size_t stem_end = dot == std::string::npos ? n0.size() : dot;
  std::size_t digits_begin = stem_end;
  while (digits_begin > 0 && std::isdigit(static_cast<unsigned char>(n0[digits_begin - 1])))
    --digits_begin;
  const std::size_t width = stem_end - digits_begin;
  if (width == 0 || width > 9) return false;
  const std::string prefix = n0.substr(0, digits_begin);
  const std::string suffix = n0.substr(stem_end);
  first = std::stol(n0.substr(digits_begin, width));
  for (std::size_t i = 0; i < names.size(); ++i) {
    char expected[32];
    std::snprintf(expected, sizeof(expected), "%0*ld", static_cast<int>(width),
                  first + static_cast<long>(i));
    const std::string& name = names[i];
    if (name.size() != prefix.size() + width + suffix.size() ||
        name.compare(0, prefix.size(), prefix) != 0 ||
        name.compare(prefix.size(), width, expected) != 0 ||
        name.compare(prefix.size() + width, std::string::npos, suffix) != 0)
      return false;
  }
  last = first + static_cast<long>(names.size()) - 1;
  pattern = prefix + "%0" + std::to_string(width) + "d" + suffix;
  return true;
}

}  // namespace

std::string formatNukeChan(const Reconstruction& rec, const ExportOptions& options) {
  const CameraIntrinsics& k = rec.intrinsics;
  // Vertical field of view over the full image height (pixel edges), in degrees.
  const double vfov_deg =
      (k.fy > 0.0 && k.height > 0) ? 2.0 * std::atan(0.5 * k.height / k.fy) * kDegrees : 0.0;
  std::string out;
  char buf[256];
  for (const NukeKey& key : nukeKeys(rec, options)) {
    std::snprintf(buf, sizeof(buf), "%lld %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n",
                  static_cast<long long>(key.frame), key.t.x(), key.t.y(), key.t.z(), key.r_deg.x(),
                  key.r_deg.y(), key.r_deg.z(), vfov_deg);
    out += buf;
  }
  return out;
}

NukeLens nukeLens(const CameraIntrinsics& k, double haperture_mm) {
  NukeLens lens;
  lens.haperture_mm = haperture_mm;
  if (!(k.fx > 0.0) || !(k.fy > 0.0) || k.width <= 0 || k.height <= 0) return lens;
  // A pixel is haperture / width millimetres wide and fx / fy of that high (fy / fx is Nuke's
  // pixel aspect, width over height).
  const double pixel_mm = haperture_mm / k.width;
  lens.pixel_aspect = k.fy / k.fx;
  lens.focal_mm = k.fx * pixel_mm;
  lens.vaperture_mm = k.height * pixel_mm / lens.pixel_aspect;
  // Principal point from the image centre (pixel edges: our centre-of-pixel origin + 0.5), in
  // Nuke's window units: half the aperture width, y up; a row is pixel_aspect of those widths.
  lens.win_translate_u = 2.0 * (k.cx + 0.5 - 0.5 * k.width) / k.width;
  lens.win_translate_v = 2.0 * (0.5 * k.height - (k.cy + 0.5)) / (k.width * lens.pixel_aspect);
  return lens;
}

std::string formatNukeScript(const Reconstruction& rec, const ExportOptions& options) {
  const CameraIntrinsics& k = rec.intrinsics;
  const NukeLens lens = nukeLens(k, options.sensor_width_mm);
  const std::vector<NukeKey> keys = nukeKeys(rec, options);
  int64_t clip_frames = rec.frames;
  for (const SolvedCamera& c : rec.cameras) clip_frames = std::max(clip_frames, c.frame + 1);
  const int64_t first_frame = options.nuke_frame_offset;
  const int64_t last_frame = std::max<int64_t>(clip_frames, 1) - 1 + options.nuke_frame_offset;
  const std::string format = nukeString(
      std::to_string(k.width) + " " + std::to_string(k.height) + " 0 0 " + std::to_string(k.width) +
      " " + std::to_string(k.height) + " " + num(lens.pixel_aspect) + " epitrack_format");

  std::string s;
  s += "#! nuke script written by epitrack-solve (File > Open, or File > Import Script)\n";
  s += "# Camera 'epitrack_camera': translate/rotate keyed on every solved frame (Nuke frame = "
       "frame\n";
  s += "# index + " + std::to_string(options.nuke_frame_offset) +
       "), rotation order ZXY, Y-up world, the lens as focal/haperture/vaperture with\n";
  s += "# the principal point as win_translate and non-square pixels as the format's pixel "
       "aspect.\n";
  s += "# Radial distortion is not carried (k1 " + num(k.k1) + ", k2 " + num(k.k2) +
       " on normalized coordinates):\n";
  s += "# use a LensDistortion node. Read 'epitrack_plate': the input frames, when they were "
       "files.\n";
  // Nuke's camera has no rolling shutter: the keys are the middle row's poses.
  if (rec.readout_frames > 0.0) s += "# " + rollingShutterNote(rec) + "\n";
  s += "Root {\n inputs 0\n";
  s += " first_frame " + std::to_string(first_frame) + "\n";
  s += " last_frame " + std::to_string(last_frame) + "\n";
  if (rec.fps > 0.0) s += " fps " + num(rec.fps) + "\n";
  s += " format " + format + "\n}\n";

  std::string pattern;
  long first_file = 0, last_file = 0;
  if (!rec.frames_dir.empty() &&
      numberedSequence(rec.frame_names, pattern, first_file, last_file)) {
    s += "Read {\n inputs 0\n";
    s += " file " + nukeString(rec.frames_dir + "/" + pattern) + "\n";
    s += " format " + format + "\n";
    s += " first " + std::to_string(first_file) + "\n last " + std::to_string(last_file) + "\n";
    s += " origfirst " + std::to_string(first_file) + "\n origlast " + std::to_string(last_file) +
         "\n origset true\n";
    if (first_file != first_frame) {
      // The first file at the first frame of the script.
      s += " frame_mode \"start at\"\n frame " + nukeString(std::to_string(first_frame)) + "\n";
    }
    s += " name epitrack_plate\n}\n";
  } else if (!rec.input_movie.empty()) {
    s += "Read {\n inputs 0\n file " + nukeString(rec.input_movie) + "\n format " + format +
         "\n first " + std::to_string(first_frame) + "\n last " + std::to_string(last_frame) +
         "\n name epitrack_plate\n}\n";
  } else if (!rec.frame_names.empty()) {
    s += "# no Read node: the frame files are not one consecutively numbered sequence\n";
  }

  s += "Camera2 {\n inputs 0\n rot_order ZXY\n";
  if (!keys.empty()) {
    s += " translate {" + curve(keys, [](const NukeKey& x) { return x.t.x(); }) + " " +
         curve(keys, [](const NukeKey& x) { return x.t.y(); }) + " " +
         curve(keys, [](const NukeKey& x) { return x.t.z(); }) + "}\n";
    s += " rotate {" + curve(keys, [](const NukeKey& x) { return x.r_deg.x(); }) + " " +
         curve(keys, [](const NukeKey& x) { return x.r_deg.y(); }) + " " +
         curve(keys, [](const NukeKey& x) { return x.r_deg.z(); }) + "}\n";
  }
  s += " focal " + num(lens.focal_mm) + "\n";
  s += " haperture " + num(lens.haperture_mm) + "\n";
  s += " vaperture " + num(lens.vaperture_mm) + "\n";
  s += " win_translate {" + num(lens.win_translate_u) + " " + num(lens.win_translate_v) + "}\n";
  s += " name epitrack_camera\n}\n";
  return s;
}

}  // namespace epitrack::io
