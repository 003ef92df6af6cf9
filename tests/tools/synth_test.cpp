#include "tools/synth/synthetic_sequence.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>

#include <Eigen/Dense>

#include "hal/io/image_codec.hpp"
#include "hal/io/text_formats.hpp"
#include "tests/support/test_support.hpp"
#include "tests/support/well_conditioned.hpp"
#include "tools/synth/portable_math.hpp"

namespace synth = epitrack::synth;
using epitrack::Image;

namespace {

// Förstner's corner estimate (the fixed point behind cornerSubPix): the point q that minimises
// sum w (g . (p - q))^2 over a window, gradients by central differences. Independent of algo/.
bool refineCorner(const Image<uint8_t>& img, Eigen::Vector2d q, int radius, Eigen::Vector2d& out) {
  for (int iter = 0; iter < 20; ++iter) {
    const int cx = static_cast<int>(std::lround(q.x()));
    const int cy = static_cast<int>(std::lround(q.y()));
    if (cx - radius - 1 < 0 || cy - radius - 1 < 0 || cx + radius + 1 >= img.width() ||
        cy + radius + 1 >= img.height())
      return false;
    Eigen::Matrix2d A = Eigen::Matrix2d::Zero();
    Eigen::Vector2d b = Eigen::Vector2d::Zero();
    const double s2 = 2.0 * (radius * 0.6) * (radius * 0.6);
    for (int dy = -radius; dy <= radius; ++dy) {
      for (int dx = -radius; dx <= radius; ++dx) {
        const int x = cx + dx;
        const int y = cy + dy;
        const Eigen::Vector2d g(0.5 * (img(x + 1, y) - img(x - 1, y)),
                                0.5 * (img(x, y + 1) - img(x, y - 1)));
        const double w = std::exp(-(dx * dx + dy * dy) / s2);
        const Eigen::Matrix2d G = w * g * g.transpose();
        A += G;
        b += G * Eigen::Vector2d(x, y);
      }
    }
    if (A.determinant() < 1e-6 * A.trace() * A.trace()) return false;
    const Eigen::Vector2d next = A.ldlt().solve(b);
    if ((next - q).norm() < 1e-4) {
      out = next;
      return true;
    }
    q = next;
  }
  out = q;
  return true;
}

// An independent reference renderer: brute-force ray casting against every quad with n x n point
// samples per pixel (no footprint filtering, no culling, no shared code with FrameRenderer).
Image<float> referenceRender(const synth::SyntheticSequence& seq, int frame, int n) {
  const synth::CameraModel& cam = seq.camera();
  const synth::Pose p = seq.pose(frame);
  Image<float> out(cam.width, cam.height);
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      double sum = 0;
      for (int sy = 0; sy < n; ++sy) {
        for (int sx = 0; sx < n; ++sx) {
          const Eigen::Vector2d m =
              cam.pixelToNormalized(x - 0.5 + (sx + 0.5) / n, y - 0.5 + (sy + 0.5) / n);
          const Eigen::Vector3d dir = p.R_wc * Eigen::Vector3d(m.x(), m.y(), 1.0);
          double best = 1e30;
          double value = seq.scene().background;
          for (const auto& q : seq.scene().quads) {
            const double denom = q.normal.dot(dir);
            if (std::abs(denom) < 1e-15) continue;
            const double t = q.normal.dot(q.origin - p.t_wc) / denom;
            if (t <= 0.01 || t >= best) continue;
            const Eigen::Vector3d hit = p.t_wc + t * dir - q.origin;
            const double u = hit.dot(q.axis_u);
            const double v = hit.dot(q.axis_v);
            if (u < 0 || v < 0 || u > q.sizeU() || v > q.sizeV()) continue;
            best = t;
            const int i = std::min(q.cells_u - 1, static_cast<int>(u / q.cell));
            const int j = std::min(q.cells_v - 1, static_cast<int>(v / q.cell));
            value = q.cellValue(i, j);
          }
          sum += value;
        }
      }
      out(x, y) = static_cast<float>(sum / (n * n));
    }
  }
  return out;
}

// The cell (i, j) of quad `quad` hit by the ray through pixel (x, y), or (-1, -1).
Eigen::Vector2i cellAtPixel(const synth::SyntheticSequence& seq, int frame, int quad, double x,
                            double y) {
  const synth::Pose p = seq.pose(frame);
  const synth::TexturedQuad& q = seq.scene().quads[static_cast<std::size_t>(quad)];
  const Eigen::Vector2d m = seq.camera().pixelToNormalized(x, y);
  const Eigen::Vector3d dir = p.R_wc * Eigen::Vector3d(m.x(), m.y(), 1.0);
  const double t = q.normal.dot(q.origin - p.t_wc) / q.normal.dot(dir);
  const Eigen::Vector3d hit = p.t_wc + t * dir - q.origin;
  return {static_cast<int>(std::floor(hit.dot(q.axis_u) / q.cell)),
          static_cast<int>(std::floor(hit.dot(q.axis_v) / q.cell))};
}

}  // namespace

TEST_CASE("Portable sin/cos match libm to 1e-15 on [-20, 20]", "[synth][math]") {
  for (int i = -2000; i <= 2000; ++i) {
    const double x = i * 0.01 + 0.003;
    REQUIRE(std::abs(synth::portableSin(x) - std::sin(x)) < 1e-15);
    REQUIRE(std::abs(synth::portableCos(x) - std::cos(x)) < 1e-15);
  }
}

TEST_CASE("Each visible landmark projects onto a corner of the rendered texture",
          "[synth][landmarks]") {
  synth::SynthOptions o;
  o.width = 320;
  o.height = 240;
  o.focal = 280;
  o.frames = 100;
  for (const auto kind :
       {synth::SceneKind::kOrbit, synth::SceneKind::kPlanar, synth::SceneKind::kHandheld,
        synth::SceneKind::kShake, synth::SceneKind::kFastPan, synth::SceneKind::kOcclusion}) {
    for (const double k1 : {0.0, -0.15}) {
      o.kind = kind;
      o.k1 = k1;
      o.k2 = k1 == 0.0 ? 0.0 : 0.03;
      const synth::SyntheticSequence seq(o);
      const int frame = 37;
      std::vector<synth::LandmarkObservation> obs;
      seq.visibleLandmarks(frame, obs);
      INFO(synth::sceneKindName(kind)
           << " k1=" << k1 << ": " << obs.size() << " visible landmarks");
      REQUIRE(obs.size() > 100);
      // 1. Geometry: the rays through the projection +-0.02 px diagonally hit the four texture
      // cells
      //    that meet at the landmark's grid vertex, so the vertex is within 0.02 px of the
      //    projection.
      int on_corner = 0;
      for (const auto& ob : obs) {
        const auto& l = seq.scene().landmarks[static_cast<std::size_t>(ob.id)];
        const auto& q = seq.scene().quads[static_cast<std::size_t>(l.quad)];
        const Eigen::Vector3d rel = l.position - q.origin;
        const int vi = static_cast<int>(std::lround(rel.dot(q.axis_u) / q.cell));
        const int vj = static_cast<int>(std::lround(rel.dot(q.axis_v) / q.cell));
        // Image directions of the texture axes at the vertex; probe one point in each quadrant.
        const synth::Pose p = seq.pose(frame);
        // Zero-initialised: project() leaves its output alone for a point behind the camera (GCC
        // 12 saw that path in the armhf build: -Wmaybe-uninitialized).
        Eigen::Vector2d c0 = Eigen::Vector2d::Zero();
        Eigen::Vector2d cu = Eigen::Vector2d::Zero();
        Eigen::Vector2d cv = Eigen::Vector2d::Zero();
        seq.camera().project(p.R_wc.transpose() * (l.position - p.t_wc), c0);
        seq.camera().project(p.R_wc.transpose() * (l.position + 0.01 * q.cell * q.axis_u - p.t_wc),
                             cu);
        seq.camera().project(p.R_wc.transpose() * (l.position + 0.01 * q.cell * q.axis_v - p.t_wc),
                             cv);
        const Eigen::Vector2d du = (cu - c0).normalized();
        const Eigen::Vector2d dv = (cv - c0).normalized();
        std::vector<Eigen::Vector2i> cells;
        for (const double su : {-0.02, 0.02}) {
          for (const double sv : {-0.02, 0.02}) {
            const Eigen::Vector2d probe = Eigen::Vector2d(ob.x, ob.y) + su * du + sv * dv;
            cells.push_back(cellAtPixel(seq, frame, l.quad, probe.x(), probe.y()));
          }
        }
        bool all_adjacent = true;
        for (const auto& c : cells)
          all_adjacent &= (c.x() == vi || c.x() == vi - 1) && (c.y() == vj || c.y() == vj - 1);
        std::sort(cells.begin(), cells.end(),
                  [](auto a, auto b) { return a.x() != b.x() ? a.x() < b.x() : a.y() < b.y(); });
        const bool four_distinct = std::unique(cells.begin(), cells.end()) == cells.end();
        on_corner += all_adjacent && four_distinct;
      }
      REQUIRE(on_corner == static_cast<int>(obs.size()));
    }
  }
}

TEST_CASE("The anti-aliased renderer matches a brute-force supersampled reference",
          "[synth][render][slow]") {
  synth::SynthOptions o;
  o.width = 240;
  o.height = 180;
  o.focal = 210;
  o.frames = 100;
  for (const double k1 : {0.0, -0.15}) {
    o.k1 = k1;
    o.k2 = k1 == 0.0 ? 0.0 : 0.03;
    const synth::SyntheticSequence seq(o);
    synth::FrameRenderer r(seq);
    Image<uint8_t> img;
    r.render(20, img);
    const Image<float> ref = referenceRender(seq, 20, 16);
    // Over the whole frame (far grazing floor included) and in the windows around corners.
    std::vector<double> all;
    for (int y = 0; y < 180; ++y)
      for (int x = 0; x < 240; ++x)
        all.push_back(std::abs(img(x, y) - static_cast<double>(ref(x, y))));
    double mean_all = 0;
    for (double d : all) mean_all += d;
    mean_all /= static_cast<double>(all.size());
    INFO("whole frame: mean |render - reference| " << mean_all);
    REQUIRE(mean_all < 0.6);  // measured 0.37; the rest is the far grazing floor
    std::vector<synth::LandmarkObservation> obs;
    seq.visibleLandmarks(20, obs);
    std::vector<double> diffs;
    for (const auto& ob : obs) {
      if (!epitrack::test::wellConditioned(
              seq, seq.scene().landmarks[static_cast<std::size_t>(ob.id)], 20))
        continue;
      const int cx = static_cast<int>(std::lround(ob.x));
      const int cy = static_cast<int>(std::lround(ob.y));
      for (int y = std::max(0, cy - 4); y <= std::min(179, cy + 4); ++y)
        for (int x = std::max(0, cx - 4); x <= std::min(239, cx + 4); ++x)
          diffs.push_back(std::abs(img(x, y) - static_cast<double>(ref(x, y))));
    }
    REQUIRE(diffs.size() > 1000);
    std::sort(diffs.begin(), diffs.end());
    double mean = 0;
    for (double d : diffs) mean += d;
    mean /= static_cast<double>(diffs.size());
    const double p99 = diffs[diffs.size() * 99 / 100];
    INFO("k1 " << k1 << ": around corners mean |render - reference| " << mean << ", p99 " << p99);
    REQUIRE(mean < 0.4);  // measured 0.29 (0.25 is the rounding to 8 bits alone)
    REQUIRE(p99 < 1.5);   // measured 0.88
    // Sub-pixel corner positions agree: the same corner estimator run on both images.
    Image<uint8_t> ref8(240, 180);
    for (int y = 0; y < 180; ++y)
      for (int x = 0; x < 240; ++x) ref8(x, y) = static_cast<uint8_t>(std::lround(ref(x, y)));
    std::vector<double> shifts;
    for (const auto& ob : obs) {
      if (!epitrack::test::wellConditioned(
              seq, seq.scene().landmarks[static_cast<std::size_t>(ob.id)], 20))
        continue;
      Eigen::Vector2d a;
      Eigen::Vector2d b;
      if (!refineCorner(img, Eigen::Vector2d(ob.x, ob.y), 3, a) ||
          !refineCorner(ref8, Eigen::Vector2d(ob.x, ob.y), 3, b))
        continue;
      shifts.push_back((a - b).norm());
    }
    REQUIRE(shifts.size() > 30);
    std::sort(shifts.begin(), shifts.end());
    INFO(shifts.size() << " corners: median shift " << shifts[shifts.size() / 2] << " px");
    REQUIRE(shifts[shifts.size() / 2] < 0.02);  // measured 0.007
  }
}

TEST_CASE("Rendering is deterministic for a seed and differs between seeds",
          "[synth][determinism]") {
  synth::SynthOptions o;
  o.width = 320;
  o.height = 240;
  o.focal = 280;
  o.frames = 10;
  o.noise_sigma = 3.0;
  o.kind = synth::SceneKind::kHandheld;
  const synth::SyntheticSequence a(o);
  const synth::SyntheticSequence b(o);
  o.seed = 2;
  const synth::SyntheticSequence c(o);
  synth::FrameRenderer ra(a);
  synth::FrameRenderer rb(b);
  synth::FrameRenderer rc(c);
  Image<uint8_t> ia;
  Image<uint8_t> ib;
  Image<uint8_t> ic;
  ra.render(5, ia);
  rb.render(5, ib);
  rb.render(5, ib);  // a renderer reused for the same frame gives the same bytes
  rc.render(5, ic);
  int differ_seed = 0;
  for (int y = 0; y < 240; ++y) {
    for (int x = 0; x < 320; ++x) {
      REQUIRE(ia(x, y) == ib(x, y));
      differ_seed += ia(x, y) != ic(x, y);
    }
  }
  REQUIRE(differ_seed > 320 * 240 / 2);
  // A digest pins the exact output, so a change of the renderer or of the platform shows up
  // (a deliberate change of the renderer updates it, and says so in its commit).
  uint64_t h = 1469598103934665603ull;
  for (int y = 0; y < 240; ++y)
    for (int x = 0; x < 320; ++x) h = (h ^ ia(x, y)) * 1099511628211ull;
  INFO("FNV-1a digest " << h);
  CHECK(h == 14386822709350410723ull);
}

TEST_CASE("Noise has the requested standard deviation", "[synth][noise]") {
  synth::SynthOptions o;
  o.width = 200;
  o.height = 150;
  o.focal = 180;
  o.frames = 2;
  const synth::SyntheticSequence clean(o);
  o.noise_sigma = 5.0;
  const synth::SyntheticSequence noisy(o);
  synth::FrameRenderer rc(clean);
  synth::FrameRenderer rn(noisy);
  Image<uint8_t> a;
  Image<uint8_t> b;
  rc.render(1, a);
  rn.render(1, b);
  double s = 0;
  double s2 = 0;
  int n = 0;
  for (int y = 0; y < 150; ++y) {
    for (int x = 0; x < 200; ++x) {
      if (a(x, y) < 20 || a(x, y) > 235) continue;  // avoid clipping
      const double d = b(x, y) - a(x, y);
      s += d;
      s2 += d * d;
      ++n;
    }
  }
  const double mean = s / n;
  const double sd = std::sqrt(s2 / n - mean * mean);
  REQUIRE(std::abs(mean) < 0.1);
  REQUIRE(sd == Approx(5.0).epsilon(0.05));
}

TEST_CASE("Trajectories have the documented shape", "[synth][trajectory]") {
  synth::TrajectoryParams t;
  t.frames = 340;
  SECTION("orbit: every optical axis passes through the target unless it wanders") {
    t.kind = synth::SceneKind::kOrbit;
    for (int f = 0; f < 340; f += 37) {
      const synth::Pose p = synth::trajectoryPose(t, f);
      const Eigen::Vector3d to_target = Eigen::Vector3d(0, 0, 0.5) - p.t_wc;
      REQUIRE(p.R_wc.col(2).cross(to_target.normalized()).norm() < 1e-12);
      REQUIRE(std::hypot(p.t_wc.x(), p.t_wc.y()) == Approx(6.0));
    }
    t.target_wander = 1.0;
    double worst = 0;
    for (int f = 0; f < 340; f += 17) {
      const synth::Pose p = synth::trajectoryPose(t, f);
      const Eigen::Vector3d to_target = (Eigen::Vector3d(0, 0, 0.5) - p.t_wc).normalized();
      worst = std::max(worst, p.R_wc.col(2).cross(to_target).norm());
    }
    REQUIRE(worst > 0.05);
  }
  SECTION("pan: the centre does not move") {
    t.kind = synth::SceneKind::kPan;
    const Eigen::Vector3d c0 = synth::trajectoryPose(t, 0).t_wc;
    for (int f = 1; f < 340; f += 13)
      REQUIRE((synth::trajectoryPose(t, f).t_wc - c0).norm() < 1e-12);
    const Eigen::Matrix3d R0 = synth::trajectoryPose(t, 0).R_wc;
    const Eigen::Matrix3d R1 = synth::trajectoryPose(t, 100).R_wc;
    REQUIRE(Eigen::AngleAxisd(R0.transpose() * R1).angle() > 0.2);
  }
  SECTION("dolly: forward motion along the optical axis") {
    t.kind = synth::SceneKind::kDolly;
    const synth::Pose a = synth::trajectoryPose(t, 0);
    const synth::Pose b = synth::trajectoryPose(t, 339);
    const Eigen::Vector3d motion = b.t_wc - a.t_wc;
    REQUIRE(motion.norm() > 4.0);
    REQUIRE(motion.normalized().dot(a.R_wc.col(2)) > 0.99);
  }
  SECTION("rotations are orthonormal") {
    for (auto k : {synth::SceneKind::kOrbit, synth::SceneKind::kDolly, synth::SceneKind::kPan,
                   synth::SceneKind::kHandheld, synth::SceneKind::kPlanar, synth::SceneKind::kShake,
                   synth::SceneKind::kFastPan, synth::SceneKind::kOcclusion}) {
      t.kind = k;
      for (int f = 0; f < 340; f += 31) {
        const Eigen::Matrix3d R = synth::trajectoryPose(t, f).R_wc;
        REQUIRE((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < 1e-12);
        REQUIRE(R.determinant() == Approx(1.0));
      }
    }
  }
}

TEST_CASE("epitrack-synth writes every file of the contract", "[synth][cli]") {
  epitrack::test::TempDir dir("synth-cli");
  const std::string exe = epitrack::test::binaryPath("tools/synth/epitrack-synth");
  REQUIRE(epitrack::test::run(
              exe +
              " --scene orbit --frames 6 --size 160x120 --focal 140 --noise 2 --target-wander 1 "
              "--distortion -0.05,0.01 --seed 3 --quiet --out " +
              dir.path()) == 0);
  for (int f = 0; f < 6; ++f) {
    char name[32];
    std::snprintf(name, sizeof(name), "frames/%06d.pgm", f);
    epitrack::hal::GrayImageDecoder dec;
    Image<uint8_t> img;
    std::string err;
    REQUIRE(dec.decodeFile(dir.file(name), img, err));
    REQUIRE(img.width() == 160);
  }
  std::vector<epitrack::hal::TrajectoryEntry> gt;
  std::string err;
  REQUIRE(epitrack::hal::readTrajectoryFile(dir.file("groundtruth.txt"), gt, err));
  REQUIRE(gt.size() == 6);
  epitrack::CameraIntrinsics k;
  REQUIRE(epitrack::hal::readIntrinsicsFile(dir.file("intrinsics.txt"), k, err));
  REQUIRE(k.fx == 140.0);
  REQUIRE(k.cx == 79.5);
  REQUIRE(k.k1 == Approx(-0.05));
  // Every landmark line refers to a point of points3d.txt and lies inside the image.
  std::ifstream pts(dir.file("points3d.txt"));
  std::map<int, Eigen::Vector3d> points;
  std::string line;
  while (std::getline(pts, line)) {
    if (line.empty() || line[0] == '#') continue;
    int id;
    double x, y, z;
    REQUIRE(std::sscanf(line.c_str(), "%d %lf %lf %lf", &id, &x, &y, &z) == 4);
    points[id] = Eigen::Vector3d(x, y, z);
  }
  REQUIRE(points.size() > 1000);
  std::ifstream lm(dir.file("landmarks.txt"));
  int lines = 0;
  while (std::getline(lm, line)) {
    if (line.empty() || line[0] == '#') continue;
    int f, id;
    double x, y;
    REQUIRE(std::sscanf(line.c_str(), "%d %d %lf %lf", &f, &id, &x, &y) == 4);
    REQUIRE(points.count(id) == 1);
    REQUIRE((f >= 0 && f < 6));
    REQUIRE((x >= 0 && x <= 159 && y >= 0 && y <= 119));
    ++lines;
  }
  REQUIRE(lines > 6 * 50);
}

TEST_CASE("epitrack-synth rejects bad usage with exit code 2", "[synth][cli]") {
  const std::string exe = epitrack::test::binaryPath("tools/synth/epitrack-synth");
  REQUIRE(epitrack::test::run(exe + " --scene spiral --out /tmp/x 2>/dev/null") == 2);
  REQUIRE(epitrack::test::run(exe + " --frames 0 --out /tmp/x 2>/dev/null") == 2);
  REQUIRE(epitrack::test::run(exe + " --size 10by10 --out /tmp/x 2>/dev/null") == 2);
  REQUIRE(epitrack::test::run(exe + " --frames 3 2>/dev/null") == 2);  // --out missing
  REQUIRE(epitrack::test::run(exe + " --bogus 1 --out /tmp/x 2>/dev/null") == 2);
  REQUIRE(epitrack::test::run(exe + " --help >/dev/null") == 0);
}
