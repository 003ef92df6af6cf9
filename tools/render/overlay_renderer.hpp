#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "algo/geometry/camera_intrinsics.hpp"
#include "algo/geometry/rolling_shutter.hpp"
#include "algo/image/image.hpp"

namespace epitrack::render {

struct Rgb8 {
  uint8_t r = 0;
  uint8_t g = 0;
  uint8_t b = 0;
  friend bool operator==(const Rgb8& a, const Rgb8& c) {
    return a.r == c.r && a.g == c.g && a.b == c.b;
  }
};

/// A triangle mesh in scene coordinates; triangles wind counter-clockwise seen from outside
/// (their normal (v1 - v0) x (v2 - v0) points out), one colour per triangle.
struct Mesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<Eigen::Vector3i> triangles;
  std::vector<Rgb8> colors;
  bool shaded = true;  ///< Lambert shading from a fixed light; false draws the flat colours
};

/// Line segments drawn with a constant width in pixels (e.g. a ground grid), depth-tested.
struct LineSet {
  std::vector<Eigen::Vector3d> from;
  std::vector<Eigen::Vector3d> to;
  Rgb8 color{255, 255, 255};
  double width_px = 1.5;
};

/// A software rasterizer that draws virtual objects over video frames: triangles with a depth
/// buffer, back faces culled, clipping at the near plane, 16 samples per pixel (a 4x4 grid) for
/// sub-pixel-accurate anti-aliased edges, flat or Lambert shading. Objects are composited over the
/// frame by their coverage. With radial distortion in the intrinsics the overlay is rendered for
/// the ideal pinhole camera and warped through the distortion before compositing.
/// Buffers are sized in the constructor (about 7 bytes per sample).
class OverlayRenderer {
 public:
  static constexpr int kSamples = 16;

  explicit OverlayRenderer(const CameraIntrinsics& intrinsics, double near_plane = 1e-3);

  /// Forgets everything drawn.
  void clear();
  /// Rolling shutter (issue 27, docs/augmentation.md): from now on drawMesh and drawLines draw
  /// every image row with the pose of its own exposure time, the pose they are given being the
  /// reference row's (`shutter.reference_row`) and `motion` the camera's over the readout
  /// (algo/geometry/rolling_shutter.hpp), so that the objects shear with a rolling-shutter plate.
  /// A zero line delay or a zero motion draws with the one pose, exactly as without.
  void setRollingShutter(const RollingShutter& shutter, const RollingShutterMotion& motion);
  /// Draws a mesh seen from the camera pose T_wc (camera to scene).
  void drawMesh(const Mesh& mesh, const Eigen::Isometry3d& T_wc);
  /// Draws line segments of constant pixel width.
  void drawLines(const LineSet& lines, const Eigen::Isometry3d& T_wc);
  /// Composites what was drawn over `frame` (RGB, the intrinsics' size).
  void composite(ImageView<Rgb8> frame);
  /// Fraction of each pixel covered by the overlay (after `composite` or `resolve`).
  [[nodiscard]] ImageView<const float> coverage() const { return alpha_.constView(); }
  /// Computes coverage and colour per pixel without touching a frame.
  void resolve();

 private:
  struct ScreenVertex {
    double x, y;   // pixels
    double inv_z;  // 1 / depth, linear in screen space
  };
  void rasterizeTriangle(const ScreenVertex& a, const ScreenVertex& b, const ScreenVertex& c,
                         const Rgb8& color);
  bool project(const Eigen::Vector3d& p_c, ScreenVertex& out) const;
  void drawMeshAtPose(const Mesh& mesh, const Eigen::Isometry3d& T_wc);
  void drawLinesAtPose(const LineSet& lines, const Eigen::Isometry3d& T_wc);
  /// The pose (camera to scene) row `y` of the rendered pinhole image is drawn with.
  [[nodiscard]] Eigen::Isometry3d rowPose(const Eigen::Isometry3d& T_wc, int y) const;
  [[nodiscard]] bool rolling() const;

  CameraIntrinsics k_;
  double near_;
  RollingShutter shutter_;
  RollingShutterMotion motion_;
  int row_begin_ = 0;  // rows rasterized: [row_begin_, row_end_] (one row at a time when rolling)
  int row_end_ = 0;
  int width_;
  int height_;
  std::vector<float> depth_;    // per sample: 1/z, 0 = empty
  std::vector<Rgb8> color_;     // per sample
  std::vector<uint8_t> dirty_;  // per pixel: something drawn
  Image<float> alpha_;
  Image<float> premul_r_;
  Image<float> premul_g_;
  Image<float> premul_b_;
};

// -- objects (scene frame: z up, the ground plane z = 0, unit = median camera-to-plane distance) --

/// An axis-aligned box from `min` to `max`.
Mesh makeBox(const Eigen::Vector3d& min, const Eigen::Vector3d& max, Rgb8 color);
/// A cube of side 0.25 * scale standing on the ground at `anchor`.
Mesh makeCube(const Eigen::Vector3d& anchor, double scale);
/// Two towers with pyramid roofs standing on the ground either side of `anchor` (the paper's
/// Figure 8): 0.12 x 0.12 x 0.45 bodies, 0.3 apart, times `scale`.
Mesh makeTowers(const Eigen::Vector3d& anchor, double scale);
/// The scene's up: a yellow arrow of `length` standing on the ground at `base` along +z.
Mesh makeUpArrow(const Eigen::Vector3d& base, double length);
/// The scene frame: red x, green y, blue z arrows of length 0.4 * scale from `origin`.
Mesh makeAxes(const Eigen::Vector3d& origin, double scale);
/// A square grid on the ground plane centred at `centre`, `half_extent` wide each way, a line
/// every `step`.
LineSet makeGroundGrid(const Eigen::Vector3d& centre, double half_extent, double step);

}  // namespace epitrack::render
