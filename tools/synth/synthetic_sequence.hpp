#pragma once

#include <cstdint>
#include <vector>

#include "algo/image/image.hpp"
#include "tools/synth/camera_model.hpp"
#include "tools/synth/scene.hpp"
#include "tools/synth/trajectory.hpp"

namespace epitrack::synth {

struct SynthOptions {
  SceneKind kind = SceneKind::kOrbit;
  int frames = 100;
  int width = 704;
  int height = 576;
  double focal = 600.0;
  double noise_sigma = 0.0;  ///< Gaussian noise, gray levels
  double blur = 0.0;         ///< exposure in frame intervals (0: none; 1: open the whole interval)
  double k1 = 0.0;           ///< radial distortion
  double k2 = 0.0;
  double target_wander = 0.0;  ///< orbit: look-at target motion amplitude (m)
  double shake_deg = 2.0;      ///< shake: peak rotational jitter per axis (degrees)
  uint64_t seed = 1;
};

/// The true projection of a landmark in one frame.
struct LandmarkObservation {
  int id = 0;
  double x = 0.0;
  double y = 0.0;
};

/// A rendered clip's ground truth: scene, camera, poses, visible landmarks. Thread-safe to query.
class SyntheticSequence {
 public:
  explicit SyntheticSequence(const SynthOptions& options);

  [[nodiscard]] const SynthOptions& options() const { return options_; }
  [[nodiscard]] const Scene& scene() const { return scene_; }
  [[nodiscard]] const CameraModel& camera() const { return camera_; }
  [[nodiscard]] const TrajectoryParams& trajectory() const { return trajectory_; }
  [[nodiscard]] Pose pose(double t) const { return trajectoryPose(trajectory_, t); }

  /// Landmarks visible in frame `frame` (in front, inside the image, facing the camera and not
  /// occluded by another surface), with their true pixel projections.
  void visibleLandmarks(int frame, std::vector<LandmarkObservation>& out) const;

 private:
  SynthOptions options_;
  Scene scene_;
  CameraModel camera_;
  TrajectoryParams trajectory_;
};

/// Ray-casting renderer of a SyntheticSequence; one per thread. Buffers are sized at construction.
/// Anti-aliasing: each pixel's texture value is the exact box integral of the cell texture over
/// the pixel's footprint on the surface (mip-mapped cell grid); pixels next to a change of surface
/// (silhouettes, box edges) are supersampled 4x4.
class FrameRenderer {
 public:
  explicit FrameRenderer(const SyntheticSequence& sequence);
  /// Renders frame `frame` (with the sequence's blur, noise and distortion) into `out`, which is
  /// sized to the camera if needed.
  void render(int frame, Image<uint8_t>& out);
  /// Renders the noise-free radiance at pose `pose` into `out` (width x height floats).
  void renderRadiance(const Pose& pose, ImageView<float> out);

 private:
  struct QuadInCamera {
    Eigen::Vector3d n, au, av;
    double nd = 0.0;   // plane: n . X = nd (camera frame)
    double auo = 0.0;  // au . origin
    double avo = 0.0;
    double su = 0.0;
    double sv = 0.0;
  };
  struct Hit {
    int quad = -1;
    double t = 0.0;
    double u = 0.0;
    double v = 0.0;
  };
  void prepareFrame(const Pose& pose);
  Hit castRay(const Eigen::Vector3d& r, const std::vector<int>& candidates) const;
  float shade(const Hit& hit, const Eigen::Vector3d& r, const Eigen::Vector3d& dr_dx,
              const Eigen::Vector3d& dr_dy) const;
  [[nodiscard]] Eigen::Vector3d pixelRay(double x, double y) const;

  const SyntheticSequence& seq_;
  int tiles_x_ = 0;
  int tiles_y_ = 0;
  std::vector<Eigen::Vector4d> tile_bounds_;  // normalized-coordinate bbox per tile
  std::vector<std::vector<int>> tile_quads_;
  std::vector<QuadInCamera> quads_cam_;
  std::vector<Eigen::Vector2d>
      ray_table_;  // undistorted normalized ray per pixel (distortion only)
  std::vector<int16_t> ids_;
  Image<float> radiance_;
  Image<float> accum_;
};

/// Tile size of the renderer's culling grid, in pixels.
inline constexpr int kRenderTile = 16;

}  // namespace epitrack::synth
