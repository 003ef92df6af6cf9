#include "tools/export/colmap_text.hpp"

#include <map>
#include <set>
#include <sstream>

#include "hal/io/text_formats.hpp"

namespace epitrack::io {
namespace {

// The lines of a COLMAP text file, numbered from 1 for messages.
class LineReader {
 public:
  explicit LineReader(const std::string& text) : in_(text) {}
  /// The next line, whatever it holds.
  bool next(std::string& line) {
    if (!std::getline(in_, line)) return false;
    ++number_;
    return true;
  }
  /// The next line that is neither blank nor a '#' comment.
  bool nextRecord(std::string& line) {
    while (next(line)) {
      const auto first = line.find_first_not_of(" \t\r");
      if (first != std::string::npos && line[first] != '#') return true;
    }
    return false;
  }
  /// "line N: ", N the line last read.
  [[nodiscard]] std::string where() const { return "line " + std::to_string(number_) + ": "; }

 private:
  std::istringstream in_;
  int number_ = 0;
};

int expectedParams(const std::string& model) {
  if (model == "SIMPLE_PINHOLE") return 3;
  if (model == "PINHOLE" || model == "SIMPLE_RADIAL") return 4;
  if (model == "RADIAL") return 5;
  if (model == "OPENCV") return 8;
  return -1;
}

}  // namespace

bool parseColmapCameras(const std::string& text, std::vector<ColmapCamera>& cameras,
                        std::string& error) {
  cameras.clear();
  LineReader lines(text);
  std::string line;
  while (lines.nextRecord(line)) {
    std::istringstream fields(line);
    ColmapCamera c;
    if (!(fields >> c.id >> c.model >> c.width >> c.height)) {
      error = lines.where() + "expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]";
      return false;
    }
    double p = 0.0;
    while (fields >> p) c.params.push_back(p);
    if (!fields.eof()) {
      error = lines.where() + "bad camera parameter";
      return false;
    }
    cameras.push_back(c);
  }
  return true;
}

bool parseColmapImages(const std::string& text, std::vector<ColmapImage>& images,
                       std::string& error) {
  images.clear();
  LineReader lines(text);
  std::string line;
  while (lines.nextRecord(line)) {
    std::istringstream fields(line);
    ColmapImage im;
    double qw = 0, qx = 0, qy = 0, qz = 0;
    if (!(fields >> im.id >> qw >> qx >> qy >> qz >> im.t_cw.x() >> im.t_cw.y() >> im.t_cw.z() >>
          im.camera_id >> im.name)) {
      error = lines.where() + "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME";
      return false;
    }
    im.q_cw = Eigen::Quaterniond(qw, qx, qy, qz);
    // The next line (possibly empty) holds the 2D points.
    if (!lines.next(line)) {
      error = lines.where() + "missing POINTS2D line";
      return false;
    }
    std::istringstream pts(line);
    ColmapPoint2D p;
    while (pts >> p.x) {
      if (!(pts >> p.y >> p.point3d_id)) {
        error = lines.where() + "POINTS2D must be triples X Y POINT3D_ID";
        return false;
      }
      im.points.push_back(p);
    }
    if (!pts.eof()) {
      error = lines.where() + "bad POINTS2D value";
      return false;
    }
    images.push_back(im);
  }
  return true;
}

bool parseColmapPoints3D(const std::string& text, std::vector<ColmapPoint3D>& points,
                         std::string& error) {
  points.clear();
  LineReader lines(text);
  std::string line;
  while (lines.nextRecord(line)) {
    std::istringstream fields(line);
    ColmapPoint3D p;
    if (!(fields >> p.id >> p.X.x() >> p.X.y() >> p.X.z() >> p.r >> p.g >> p.b >> p.error)) {
      error = lines.where() + "expected POINT3D_ID X Y Z R G B ERROR TRACK[]";
      return false;
    }
    int64_t image_id = 0;
    while (fields >> image_id) {
      int idx = 0;
      if (!(fields >> idx)) {
        error = lines.where() + "TRACK must be pairs IMAGE_ID POINT2D_IDX";
        return false;
      }
      p.track.emplace_back(image_id, idx);
    }
    if (!fields.eof()) {
      error = lines.where() + "bad TRACK value";
      return false;
    }
    points.push_back(p);
  }
  return true;
}

bool readColmapModel(const std::string& dir, ColmapModel& model, std::string& error) {
  std::string text;
  const std::string base = dir + "/";
  if (!hal::readTextFile(base + "cameras.txt", text, error)) return false;
  if (!parseColmapCameras(text, model.cameras, error)) {
    error = "cameras.txt " + error;
    return false;
  }
  if (!hal::readTextFile(base + "images.txt", text, error)) return false;
  if (!parseColmapImages(text, model.images, error)) {
    error = "images.txt " + error;
    return false;
  }
  if (!hal::readTextFile(base + "points3D.txt", text, error)) return false;
  if (!parseColmapPoints3D(text, model.points, error)) {
    error = "points3D.txt " + error;
    return false;
  }
  return true;
}

bool checkColmapConsistency(const ColmapModel& model, std::string& error) {
  std::set<int64_t> camera_ids;
  for (const ColmapCamera& c : model.cameras) {
    if (!camera_ids.insert(c.id).second) {
      error = "camera id " + std::to_string(c.id) + " repeated";
      return false;
    }
    if (expectedParams(c.model) != static_cast<int>(c.params.size())) {
      error = "camera " + std::to_string(c.id) + ": model " + c.model + " with " +
              std::to_string(c.params.size()) + " parameters";
      return false;
    }
  }
  std::map<int64_t, const ColmapImage*> images;
  for (const ColmapImage& im : model.images) {
    if (!images.emplace(im.id, &im).second) {
      error = "image id " + std::to_string(im.id) + " repeated";
      return false;
    }
    if (camera_ids.count(im.camera_id) == 0) {
      error = "image " + std::to_string(im.id) + " names a missing camera";
      return false;
    }
    if (std::abs(im.q_cw.norm() - 1.0) > 1e-6) {
      error = "image " + std::to_string(im.id) + " quaternion is not unit";
      return false;
    }
  }
  std::map<int64_t, std::set<std::pair<int64_t, int>>> tracks;
  for (const ColmapPoint3D& p : model.points) {
    auto [it, inserted] = tracks.emplace(p.id, std::set<std::pair<int64_t, int>>());
    if (!inserted) {
      error = "point id " + std::to_string(p.id) + " repeated";
      return false;
    }
    for (const auto& [image_id, idx] : p.track) {
      const auto im = images.find(image_id);
      if (im == images.end()) {
        error = "point " + std::to_string(p.id) + " track names missing image " +
                std::to_string(image_id);
        return false;
      }
      if (idx < 0 || static_cast<std::size_t>(idx) >= im->second->points.size() ||
          im->second->points[static_cast<std::size_t>(idx)].point3d_id != p.id) {
        error = "point " + std::to_string(p.id) + " track entry (" + std::to_string(image_id) +
                ", " + std::to_string(idx) + ") does not refer back to it";
        return false;
      }
      it->second.emplace(image_id, idx);
    }
  }
  for (const ColmapImage& im : model.images) {
    for (std::size_t i = 0; i < im.points.size(); ++i) {
      const int64_t id = im.points[i].point3d_id;
      if (id == -1) continue;
      const auto t = tracks.find(id);
      if (t == tracks.end() || t->second.count({im.id, static_cast<int>(i)}) == 0) {
        error = "image " + std::to_string(im.id) + " point2D " + std::to_string(i) +
                " refers to point " + std::to_string(id) + " whose track does not hold it";
        return false;
      }
    }
  }
  return true;
}

}  // namespace epitrack::io
