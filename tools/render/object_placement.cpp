#include "tools/render/object_placement.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Geometry>

namespace epitrack::render {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double medianOf(std::vector<double> v) {
  if (v.empty()) return kNaN;
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  return v[mid];
}

double quantileOf(std::vector<double> v, double q) {
  if (v.empty()) return kNaN;
  const std::size_t k =
      std::min(v.size() - 1,
               static_cast<std::size_t>(std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

struct Box {
  Eigen::Vector3d min = Eigen::Vector3d::Zero();
  Eigen::Vector3d max = Eigen::Vector3d::Zero();
};

Box boundsOf(const Mesh& mesh) {
  Box b;
  if (mesh.vertices.empty()) return b;
  b.min = b.max = mesh.vertices.front();
  for (const Eigen::Vector3d& v : mesh.vertices) {
    b.min = b.min.cwiseMin(v);
    b.max = b.max.cwiseMax(v);
  }
  return b;
}

/// Whether the box (unit-scale bounds `box` scaled by `scale` at `anchor`) is in view of the
/// camera: every corner in front, at least options.min_inside_fraction of its image rectangle
/// inside the image, and that part covering options.min_box_coverage of the image.
bool boxInView(const CameraIntrinsics& k, const io::SolvedCamera& cam, const Box& box,
               const Eigen::Vector3d& anchor, double scale, const ObjectPlacementOptions& options) {
  const Eigen::Matrix3d R_cw = cam.R_wc.transpose();
  double u0 = std::numeric_limits<double>::infinity(), v0 = u0, u1 = -u0, v1 = -u0;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d corner(c & 1 ? box.max.x() : box.min.x(),
                                 c & 2 ? box.max.y() : box.min.y(),
                                 c & 4 ? box.max.z() : box.min.z());
    const Eigen::Vector3d p = R_cw * (anchor + scale * corner - cam.p_wc);
    if (!(p.z() > 1e-6)) return false;
    const double u = k.fx * p.x() / p.z() + k.cx;
    const double v = k.fy * p.y() / p.z() + k.cy;
    u0 = std::min(u0, u);
    u1 = std::max(u1, u);
    v0 = std::min(v0, v);
    v1 = std::max(v1, v);
  }
  const double area = (u1 - u0) * (v1 - v0);
  if (!(area > 0.0)) return false;
  const double iu = std::max(0.0, std::min(u1, k.width - 0.5) - std::max(u0, -0.5));
  const double iv = std::max(0.0, std::min(v1, k.height - 0.5) - std::max(v0, -0.5));
  const double inside = iu * iv;
  return inside >= options.min_inside_fraction * area &&
         inside >= options.min_box_coverage * static_cast<double>(k.width) * k.height;
}

}  // namespace

Mesh makeObjectMesh(const std::string& object, const Eigen::Vector3d& anchor, double scale) {
  if (object == "towers") return makeTowers(anchor, scale);
  if (object == "cube") return makeCube(anchor, scale);
  if (object == "axes") return makeAxes(anchor, scale);
  return Mesh{};
}

double objectUnitHeight(const std::string& object) {
  const Mesh mesh = makeObjectMesh(object, Eigen::Vector3d::Zero(), 1.0);
  if (mesh.vertices.empty()) return 0.0;
  const Box b = boundsOf(mesh);
  return b.max.z() - std::min(0.0, b.min.z());
}

io::AugmentedObject placeObject(const io::Reconstruction& rec, const std::string& object,
                                const std::optional<Eigen::Vector3d>& given_at,
                                const std::optional<double>& given_scale,
                                const ObjectPlacementOptions& options) {
  io::AugmentedObject placed;
  placed.placement = given_at && given_scale ? "given" : "default";
  placed.at = given_at.value_or(Eigen::Vector3d::Zero());
  placed.scale = given_scale.value_or(1.0);
  const double unit_height = objectUnitHeight(object);
  placed.height = unit_height * placed.scale;
  if ((given_at && given_scale) || rec.ground == "none" || !(unit_height > 0.0)) return placed;

  std::vector<const io::SolvedCamera*> cams;
  for (const io::SolvedCamera& c : rec.cameras)
    if (c.solved && c.R_wc.allFinite() && c.p_wc.allFinite()) cams.push_back(&c);
  if (cams.empty()) return placed;
  const CameraIntrinsics& k = rec.intrinsics;
  if (!(k.fx > 0.0) || !(k.fy > 0.0) || k.width <= 0 || k.height <= 0) return placed;

  // Anchors at scale 1 for the box test: the mesh's bounds relative to its anchor.
  const Box unit_box = boundsOf(makeObjectMesh(object, Eigen::Vector3d::Zero(), 1.0));

  // Candidate frames: evenly spread, visited from the middle of the clip outwards so that ties
  // go to the middle frames.
  const int n = static_cast<int>(cams.size());
  const int count = std::max(1, std::min(n, options.candidate_frames));
  std::vector<int> order;
  for (int i = 0; i < count; ++i) order.push_back(count == 1 ? n / 2 : i * (n - 1) / (count - 1));
  std::stable_sort(order.begin(), order.end(), [n](int a, int b) {
    return std::abs(2 * a - (n - 1)) < std::abs(2 * b - (n - 1));
  });

  std::vector<double> depths;
  std::vector<Eigen::Vector3d> candidates;
  if (given_at) candidates.push_back(*given_at);  // only the size is chosen
  if (given_at) order.clear();
  const std::array<double, 3> us = {0.5, 0.35, 0.65};
  const std::array<double, 4> vs = {0.55, 0.65, 0.75, 0.85};
  for (const int index : order) {
    const io::SolvedCamera& cam = *cams[static_cast<std::size_t>(index)];
    if (!(cam.p_wc.z() > 0.0)) continue;  // a camera under the ground sees no ground from above
    const Eigen::Matrix3d R_cw = cam.R_wc.transpose();
    depths.clear();
    for (const io::ScenePoint& p : rec.points) {
      const double z = R_cw.row(2).dot(p.X - cam.p_wc);
      if (z > 0.0 && std::isfinite(z)) depths.push_back(z);
    }
    const double max_depth = quantileOf(depths, options.max_depth_quantile);
    if (!std::isfinite(max_depth)) continue;
    for (const double v : vs)
      for (const double u : us) {
        const Eigen::Vector3d ray_c((u * k.width - k.cx) / k.fx, (v * k.height - k.cy) / k.fy, 1.0);
        const Eigen::Vector3d ray = cam.R_wc * ray_c;
        if (!(ray.z() < -1e-9)) continue;          // looking level or up: never meets the ground
        const double t = -cam.p_wc.z() / ray.z();  // = depth, since ray_c.z() == 1
        if (!(t > 0.0) || t > max_depth) continue;
        candidates.push_back(cam.p_wc + t * ray);
      }
  }

  // The scene origin (on the ground, under the points or at the ground plane's inlier centroid)
  // is a candidate too: the only one when no ray meets the ground in front of the scene's points.
  if (!given_at) candidates.push_back(Eigen::Vector3d::Zero());
  int best_frames = -1;
  std::vector<double> anchor_depths;
  for (const Eigen::Vector3d& c : candidates) {
    anchor_depths.clear();
    for (const io::SolvedCamera* cam : cams) {
      const double z = cam->R_wc.col(2).dot(c - cam->p_wc);
      if (z > 0.0) anchor_depths.push_back(z);
    }
    const double depth = quantileOf(anchor_depths, options.size_depth_quantile);
    if (!std::isfinite(depth)) continue;
    const double scale =
        given_scale ? *given_scale
                    : options.image_height_fraction * k.height * depth / (k.fy * unit_height);
    int frames = 0;
    for (const io::SolvedCamera* cam : cams)
      frames += boxInView(k, *cam, unit_box, c, scale, options) ? 1 : 0;
    if (frames > best_frames) {
      best_frames = frames;
      placed.at = c;
      if (!given_scale) placed.scale = scale;
    }
  }
  if (best_frames < 0) return placed;
  placed.placement = "auto";
  placed.height = unit_height * placed.scale;
  return placed;
}

double uprightCosine(const CameraIntrinsics& k, const Eigen::Matrix3d& R_wc,
                     const Eigen::Vector3d& p_wc, const Eigen::Vector3d& anchor, double height) {
  const Eigen::Matrix3d R_cw = R_wc.transpose();
  const Eigen::Vector3d a = R_cw * (anchor - p_wc);
  const Eigen::Vector3d b = R_cw * (anchor + height * Eigen::Vector3d::UnitZ() - p_wc);
  double dx = 0.0;
  double dy = 0.0;
  if (a.z() > 1e-9 && b.z() > 1e-9 && height > 0.0) {
    dx = k.fx * (b.x() / b.z() - a.x() / a.z());
    dy = k.fy * (b.y() / b.z() - a.y() / a.z());
  } else {
    const Eigen::Vector3d z_c = R_cw.col(2);
    dx = z_c.x();
    dy = z_c.y();
  }
  const double norm = std::hypot(dx, dy);
  return norm > 1e-12 ? -dy / norm : kNaN;
}

void measureObjectView(const io::Reconstruction& rec, const Mesh& mesh, io::AugmentedObject& object,
                       double min_coverage, std::vector<double>* per_frame) {
  object.solved_frames = 0;
  object.visible_frames = 0;
  std::vector<double> coverages;
  std::vector<double> cosines;
  OverlayRenderer renderer(rec.intrinsics);
  const double pixels = static_cast<double>(rec.intrinsics.width) * rec.intrinsics.height;
  for (const io::SolvedCamera& cam : rec.cameras) {
    if (!cam.solved || !cam.R_wc.allFinite() || !cam.p_wc.allFinite()) continue;
    ++object.solved_frames;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = cam.R_wc;
    T.translation() = cam.p_wc;
    renderer.clear();
    renderer.drawMesh(mesh, T);
    renderer.resolve();
    const ImageView<const float> alpha = renderer.coverage();
    double covered = 0.0;
    for (int y = 0; y < alpha.height; ++y)
      for (int x = 0; x < alpha.width; ++x) covered += static_cast<double>(alpha(x, y));
    const double coverage = pixels > 0.0 ? covered / pixels : 0.0;
    coverages.push_back(coverage);
    if (coverage >= min_coverage) ++object.visible_frames;
    const double c = uprightCosine(rec.intrinsics, cam.R_wc, cam.p_wc, object.at, object.height);
    if (std::isfinite(c)) cosines.push_back(c);
  }
  if (per_frame != nullptr) *per_frame = coverages;
  object.median_coverage = medianOf(coverages);
  object.upright_cosine_median = medianOf(cosines);
}

}  // namespace epitrack::render
