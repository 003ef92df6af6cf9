#include "tools/synth/synthetic_sequence.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "tools/synth/random.hpp"

namespace epitrack::synth {
namespace {

constexpr double kNear = 0.01;  // metres; nothing closer to the camera is drawn

struct CameraFrameQuad {
  Eigen::Vector3d n, au, av, o;
  double nd, auo, avo, su, sv;
};

CameraFrameQuad toCamera(const TexturedQuad& q, const Pose& pose) {
  const Eigen::Matrix3d R_cw = pose.R_wc.transpose();
  CameraFrameQuad c{};
  c.o = R_cw * (q.origin - pose.t_wc);
  c.n = R_cw * q.normal;
  c.au = R_cw * q.axis_u;
  c.av = R_cw * q.axis_v;
  c.nd = c.n.dot(c.o);
  c.auo = c.au.dot(c.o);
  c.avo = c.av.dot(c.o);
  c.su = q.sizeU();
  c.sv = q.sizeV();
  return c;
}

}  // namespace

SyntheticSequence::SyntheticSequence(const SynthOptions& options) : options_(options) {
  if (options.kind == SceneKind::kPlanar) {
    scene_ = makePlanarScene(options.seed);
  } else if (options.kind == SceneKind::kOcclusion) {
    scene_ = makeOcclusionScene(options.seed);
  } else {
    scene_ = makeRoomScene(options.seed);
  }
  camera_ = CameraModel::centered(options.width, options.height, options.focal);
  camera_.k1 = options.k1;
  camera_.k2 = options.k2;
  trajectory_.kind = options.kind;
  trajectory_.frames = options.frames;
  trajectory_.target_wander = options.target_wander;
  trajectory_.orbit_speed_deg = options.orbit_speed_deg;
  trajectory_.shake_deg = options.shake_deg;
  trajectory_.walk_m = options.walk_m;
  trajectory_.seed = options.seed;
}

void SyntheticSequence::visibleLandmarks(int frame, std::vector<LandmarkObservation>& out) const {
  out.clear();
  const Pose frame_pose = pose(frame);
  std::vector<CameraFrameQuad> quads;
  quads.reserve(scene_.quads.size());
  for (const auto& q : scene_.quads) quads.push_back(toCamera(q, frame_pose));
  const double max_x = camera_.width - 1.0;
  const double max_y = camera_.height - 1.0;
  const double readout = options_.readout;
  for (const Landmark3d& l : scene_.landmarks) {
    Pose p = frame_pose;
    Eigen::Matrix3d R_cw = p.R_wc.transpose();
    Eigen::Vector3d pc = R_cw * (l.position - p.t_wc);
    if (pc.z() <= kNear) continue;
    Eigen::Vector2d px;
    if (!camera_.project(pc, px)) continue;
    if (readout > 0.0) {
      // The row where the corner is seen depends on the pose, which depends on the row: iterate
      // y <- project_y(pose(rowTime(y))). The map contracts by the vertical image speed times
      // the readout over the height (well below 1 for any hand-held motion): converges in a few
      // steps; a corner that does not settle is left out.
      bool converged = false;
      for (int iter = 0; iter < 50 && !converged; ++iter) {
        const double y = px.y();
        p = pose(rowTime(frame, y, readout));
        R_cw = p.R_wc.transpose();
        pc = R_cw * (l.position - p.t_wc);
        if (pc.z() <= kNear || !camera_.project(pc, px)) break;
        converged = std::abs(px.y() - y) < 1e-9;
      }
      if (!converged) continue;
    }
    if (px.x() < 0.0 || px.y() < 0.0 || px.x() > max_x || px.y() > max_y) continue;
    if (readout > 0.0) {
      quads.clear();
      for (const auto& q : scene_.quads) quads.push_back(toCamera(q, p));
    }
    if (quads[static_cast<std::size_t>(l.quad)].n.dot(pc) >= 0.0) continue;  // seen from behind
    const Eigen::Vector3d r = pc / pc.z();
    bool occluded = false;
    for (std::size_t qi = 0; qi < quads.size() && !occluded; ++qi) {
      if (static_cast<int>(qi) == l.quad) continue;
      const CameraFrameQuad& q = quads[qi];
      const double denom = q.n.dot(r);
      if (std::abs(denom) < 1e-15) continue;
      const double t = q.nd / denom;
      if (t <= kNear || t >= pc.z() * (1.0 - 1e-9)) continue;
      const double u = t * q.au.dot(r) - q.auo;
      const double v = t * q.av.dot(r) - q.avo;
      occluded = u >= 0.0 && u <= q.su && v >= 0.0 && v <= q.sv;
    }
    if (!occluded) out.push_back({l.id, px.x(), px.y()});
  }
}

FrameRenderer::FrameRenderer(const SyntheticSequence& sequence) : seq_(sequence) {
  const CameraModel& cam = seq_.camera();
  const int w = cam.width;
  const int h = cam.height;
  tiles_x_ = (w + kRenderTile - 1) / kRenderTile;
  tiles_y_ = (h + kRenderTile - 1) / kRenderTile;
  if (cam.hasDistortion()) {
    ray_table_.resize(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x)
        ray_table_[static_cast<std::size_t>(y) * w + x] = cam.pixelToNormalized(x, y);
    }
  }
  // Bounds of each tile in normalized undistorted coordinates, from its border at pixel corners.
  tile_bounds_.resize(static_cast<std::size_t>(tiles_x_) * static_cast<std::size_t>(tiles_y_));
  for (int ty = 0; ty < tiles_y_; ++ty) {
    for (int tx = 0; tx < tiles_x_; ++tx) {
      const double x0 = tx * kRenderTile - 0.5;
      const double y0 = ty * kRenderTile - 0.5;
      const double x1 = std::min(w, (tx + 1) * kRenderTile) - 0.5;
      const double y1 = std::min(h, (ty + 1) * kRenderTile) - 0.5;
      Eigen::Vector4d b(1e300, 1e300, -1e300, -1e300);
      const auto add = [&](double x, double y) {
        const Eigen::Vector2d n = cam.pixelToNormalized(x, y);
        b[0] = std::min(b[0], n.x());
        b[1] = std::min(b[1], n.y());
        b[2] = std::max(b[2], n.x());
        b[3] = std::max(b[3], n.y());
      };
      const int steps = cam.hasDistortion() ? kRenderTile : 1;
      for (int s = 0; s <= steps; ++s) {
        const double a = static_cast<double>(s) / steps;
        add(x0 + a * (x1 - x0), y0);
        add(x0 + a * (x1 - x0), y1);
        add(x0, y0 + a * (y1 - y0));
        add(x1, y0 + a * (y1 - y0));
      }
      const double margin = 1e-3 * (b[2] - b[0]) + 1e-9;
      tile_bounds_[static_cast<std::size_t>(ty) * tiles_x_ + tx] =
          Eigen::Vector4d(b[0] - margin, b[1] - margin, b[2] + margin, b[3] + margin);
    }
  }
  tile_quads_.resize(tile_bounds_.size());
  for (auto& list : tile_quads_) list.reserve(seq_.scene().quads.size());
  quads_cam_.resize(seq_.scene().quads.size());
  ids_.resize(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
  radiance_.allocate(w, h);
  accum_.allocate(w, h);
}

Eigen::Vector3d FrameRenderer::pixelRay(double x, double y) const {
  const Eigen::Vector2d n = seq_.camera().pixelToNormalized(x, y);
  return {n.x(), n.y(), 1.0};
}

void FrameRenderer::prepareTiles(const Pose& pose, int tile_row_begin, int tile_row_end) {
  const auto& quads = seq_.scene().quads;
  const std::size_t tile_begin = static_cast<std::size_t>(tile_row_begin) * tiles_x_;
  const std::size_t tile_end = static_cast<std::size_t>(tile_row_end) * tiles_x_;
  for (std::size_t ti = tile_begin; ti < tile_end; ++ti) tile_quads_[ti].clear();
  for (std::size_t qi = 0; qi < quads.size(); ++qi) {
    const TexturedQuad& q = quads[qi];
    const CameraFrameQuad c = toCamera(q, pose);
    quads_cam_[qi] = {c.n, c.au, c.av, c.nd, c.auo, c.avo, c.su, c.sv};
    // Clip the quad against z >= kNear (Sutherland-Hodgman), then bound its projection.
    const Eigen::Vector3d corners[4] = {c.o, c.o + c.su * c.au, c.o + c.su * c.au + c.sv * c.av,
                                        c.o + c.sv * c.av};
    Eigen::Vector4d b(1e300, 1e300, -1e300, -1e300);
    int kept = 0;
    for (int i = 0; i < 4; ++i) {
      const Eigen::Vector3d& a = corners[i];
      const Eigen::Vector3d& nb = corners[(i + 1) % 4];
      const auto addPoint = [&](const Eigen::Vector3d& p) {
        const double x = p.x() / p.z();
        const double y = p.y() / p.z();
        b[0] = std::min(b[0], x);
        b[1] = std::min(b[1], y);
        b[2] = std::max(b[2], x);
        b[3] = std::max(b[3], y);
        ++kept;
      };
      const bool a_in = a.z() >= kNear;
      const bool b_in = nb.z() >= kNear;
      if (a_in) addPoint(a);
      if (a_in != b_in) {
        const double s = (kNear - a.z()) / (nb.z() - a.z());
        addPoint(a + s * (nb - a));
      }
    }
    if (kept == 0) continue;
    for (std::size_t ti = tile_begin; ti < tile_end; ++ti) {
      const Eigen::Vector4d& t = tile_bounds_[ti];
      if (b[0] <= t[2] && b[2] >= t[0] && b[1] <= t[3] && b[3] >= t[1])
        tile_quads_[ti].push_back(static_cast<int>(qi));
    }
  }
}

FrameRenderer::Hit FrameRenderer::castRay(const Eigen::Vector3d& r,
                                          const std::vector<int>& candidates) const {
  Hit best;
  best.t = std::numeric_limits<double>::infinity();
  for (const int qi : candidates) {
    const QuadInCamera& q = quads_cam_[static_cast<std::size_t>(qi)];
    const double denom = q.n.dot(r);
    if (std::abs(denom) < 1e-15) continue;
    const double t = q.nd / denom;
    if (t <= kNear || t >= best.t) continue;
    const double u = t * q.au.dot(r) - q.auo;
    if (u < 0.0 || u > q.su) continue;
    const double v = t * q.av.dot(r) - q.avo;
    if (v < 0.0 || v > q.sv) continue;
    best = {qi, t, u, v};
  }
  return best;
}

float FrameRenderer::shade(const Hit& hit, const Eigen::Vector3d& r, const Eigen::Vector3d& dr_dx,
                           const Eigen::Vector3d& dr_dy) const {
  const QuadInCamera& q = quads_cam_[static_cast<std::size_t>(hit.quad)];
  const double nr = q.n.dot(r);
  // Footprint: derivative of the surface point P = t(r) r with t = nd / (n . r).
  const Eigen::Vector3d dPx = hit.t * dr_dx - hit.t * (q.n.dot(dr_dx) / nr) * r;
  const Eigen::Vector3d dPy = hit.t * dr_dy - hit.t * (q.n.dot(dr_dy) / nr) * r;
  // The pixel maps (to first order) to the parallelogram spanned by dP/dx and dP/dy in texture
  // coordinates; its exact area integral over the cell texture is the anti-aliased value.
  const Eigen::Vector2d a(q.au.dot(dPx), q.av.dot(dPx));
  const Eigen::Vector2d b(q.au.dot(dPy), q.av.dot(dPy));
  return seq_.scene().quads[static_cast<std::size_t>(hit.quad)].parallelogramLookup(hit.u, hit.v, a,
                                                                                    b);
}

Eigen::Vector3d FrameRenderer::rayAt(int x, int y) const {
  const CameraModel& cam = seq_.camera();
  if (ray_table_.empty()) return {(x - cam.cx) / cam.fx, (y - cam.cy) / cam.fy, 1.0};
  const Eigen::Vector2d& n = ray_table_[static_cast<std::size_t>(y) * cam.width + x];
  return {n.x(), n.y(), 1.0};
}

void FrameRenderer::rayDerivatives(int x, int y, Eigen::Vector3d& dx, Eigen::Vector3d& dy) const {
  const CameraModel& cam = seq_.camera();
  if (ray_table_.empty()) {
    dx = Eigen::Vector3d(1.0 / cam.fx, 0.0, 0.0);
    dy = Eigen::Vector3d(0.0, 1.0 / cam.fy, 0.0);
    return;
  }
  const int xl = std::max(0, x - 1);
  const int xr = std::min(cam.width - 1, x + 1);
  const int yu = std::max(0, y - 1);
  const int yd = std::min(cam.height - 1, y + 1);
  dx = (rayAt(xr, y) - rayAt(xl, y)) / static_cast<double>(xr - xl);
  dy = (rayAt(x, yd) - rayAt(x, yu)) / static_cast<double>(yd - yu);
}

void FrameRenderer::shadeRow(int y, ImageView<float> out) {
  const int w = seq_.camera().width;
  const float background = seq_.scene().background;
  float* row = out.row(y);
  const std::vector<int>* tile_row =
      &tile_quads_[static_cast<std::size_t>(y / kRenderTile) * tiles_x_];
  for (int x = 0; x < w; ++x) {
    const Eigen::Vector3d r = rayAt(x, y);
    const Hit hit = castRay(r, tile_row[x / kRenderTile]);
    ids_[static_cast<std::size_t>(y) * w + x] = static_cast<int16_t>(hit.quad);
    if (hit.quad < 0) {
      row[x] = background;
    } else {
      Eigen::Vector3d dx;
      Eigen::Vector3d dy;
      rayDerivatives(x, y, dx, dy);
      row[x] = shade(hit, r, dx, dy);
    }
  }
}

bool FrameRenderer::rowHasEdge(int y) const {
  const int w = seq_.camera().width;
  const int h = seq_.camera().height;
  for (int x = 0; x < w; ++x) {
    const int16_t id = ids_[static_cast<std::size_t>(y) * w + x];
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int nx = x + dx;
        const int ny = y + dy;
        if (nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
        if (ids_[static_cast<std::size_t>(ny) * w + nx] != id) return true;
      }
    }
  }
  return false;
}

void FrameRenderer::supersampleRow(int y, ImageView<float> out) {
  const int w = seq_.camera().width;
  const int h = seq_.camera().height;
  const float background = seq_.scene().background;
  const std::vector<int>* tile_row =
      &tile_quads_[static_cast<std::size_t>(y / kRenderTile) * tiles_x_];
  for (int x = 0; x < w; ++x) {
    const int16_t id = ids_[static_cast<std::size_t>(y) * w + x];
    bool edge = false;
    for (int dy = -1; dy <= 1 && !edge; ++dy) {
      for (int dx = -1; dx <= 1 && !edge; ++dx) {
        const int nx = x + dx;
        const int ny = y + dy;
        if (nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
        edge = ids_[static_cast<std::size_t>(ny) * w + nx] != id;
      }
    }
    if (!edge) continue;
    Eigen::Vector3d drx;
    Eigen::Vector3d dry;
    rayDerivatives(x, y, drx, dry);
    drx *= 0.25;
    dry *= 0.25;
    double sum = 0.0;
    for (int sy = 0; sy < 4; ++sy) {
      for (int sx = 0; sx < 4; ++sx) {
        const Eigen::Vector3d r =
            pixelRay(x + (sx + 0.5) * 0.25 - 0.5, y + (sy + 0.5) * 0.25 - 0.5);
        const Hit hit = castRay(r, tile_row[x / kRenderTile]);
        sum += hit.quad < 0 ? static_cast<double>(background)
                            : static_cast<double>(shade(hit, r, drx, dry));
      }
    }
    out(x, y) = static_cast<float>(sum / 16.0);
  }
}

void FrameRenderer::renderRadiance(const Pose& pose, ImageView<float> out) {
  const int h = seq_.camera().height;
  prepareTiles(pose, 0, tiles_y_);
  // Pass 1: one ray per pixel centre, box-filtered texture.
  for (int y = 0; y < h; ++y) shadeRow(y, out);
  // Pass 2: pixels next to a change of surface are supersampled 4x4.
  for (int y = 0; y < h; ++y) supersampleRow(y, out);
}

void FrameRenderer::renderRadianceRolling(double frame_time, double readout, ImageView<float> out) {
  const int h = seq_.camera().height;
  // Each row at its own pose (exact from the trajectory): the scene is brought into that row's
  // camera frame and culled for the row's band of tiles only. With readout 0 every row gets the
  // frame's pose and the same candidate lists, hence exactly renderRadiance's bytes.
  const auto prepareRow = [&](int y) {
    const int tile_row = y / kRenderTile;
    prepareTiles(seq_.pose(seq_.rowTime(frame_time, y, readout)), tile_row, tile_row + 1);
  };
  for (int y = 0; y < h; ++y) {
    prepareRow(y);
    shadeRow(y, out);
  }
  for (int y = 0; y < h; ++y) {
    if (!rowHasEdge(y)) continue;
    prepareRow(y);
    supersampleRow(y, out);
  }
}

void FrameRenderer::render(int frame, Image<uint8_t>& out) {
  const SynthOptions& o = seq_.options();
  const int w = seq_.camera().width;
  const int h = seq_.camera().height;
  out.allocate(w, h);
  if (o.blur > 0.0) {
    const int k = std::clamp(static_cast<int>(std::ceil(8.0 * o.blur)), 4, 32);
    accum_.fill(0.0F);
    for (int s = 0; s < k; ++s) {
      const double t = frame + o.blur * ((s + 0.5) / k - 0.5);
      if (o.readout > 0.0) {
        renderRadianceRolling(t, o.readout, radiance_.view());
      } else {
        renderRadiance(seq_.pose(t), radiance_.view());
      }
      for (int y = 0; y < h; ++y) {
        float* a = accum_.row(y);
        const float* r = radiance_.row(y);
        for (int x = 0; x < w; ++x) a[x] += r[x];
      }
    }
    const float inv = 1.0F / static_cast<float>(k);
    for (int y = 0; y < h; ++y) {
      float* a = accum_.row(y);
      for (int x = 0; x < w; ++x) a[x] *= inv;
    }
  } else {
    if (o.readout > 0.0) {
      renderRadianceRolling(frame, o.readout, accum_.view());
    } else {
      renderRadiance(seq_.pose(frame), accum_.view());
    }
  }
  SplitMix64 rng(mixSeed(o.seed, 1000003ull + static_cast<uint64_t>(frame)));
  for (int y = 0; y < h; ++y) {
    const float* a = accum_.row(y);
    uint8_t* dst = out.row(y);
    for (int x = 0; x < w; ++x) {
      double v = a[x];
      if (o.noise_sigma > 0.0) v += o.noise_sigma * rng.gaussian();
      v = std::floor(v + 0.5);
      dst[x] = static_cast<uint8_t>(std::clamp(v, 0.0, 255.0));
    }
  }
}

}  // namespace epitrack::synth
