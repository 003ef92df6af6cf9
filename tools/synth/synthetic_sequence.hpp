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
  double target_wander = 0.0;     ///< orbit: look-at target motion amplitude (m)
  double orbit_speed_deg = 0.25;  ///< orbit: degrees of arc per frame
  double shake_deg = 2.0;         ///< shake: peak rotational jitter per axis (degrees)
  double walk_m = 0.012;          ///< fastpan: sideways walk of the centre per frame (0: tripod)
  /// Rolling shutter: time from the exposure of the first row to that of the last, in frame
  /// intervals (0: global shutter). The frame's pose (groundtruth.txt) is the middle row's.
  double readout = 0.0;
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
  /// Exposure time of image row `y` (continuous: pixel centres at integer rows) of the frame at
  /// `frame_time`, for a readout of `readout` frame intervals: frame_time + readout *
  /// (y / (height - 1) - 1/2), so row 0 is exposed at frame_time - readout / 2, the middle row
  /// (height - 1) / 2 at frame_time itself and the last row at frame_time + readout / 2.
  [[nodiscard]] double rowTime(double frame_time, double y, double readout) const {
    return frame_time + readout * (y / (camera_.height - 1) - 0.5);
  }

  /// Landmarks visible in frame `frame` (in front, inside the image, facing the camera and not
  /// occluded by another surface), with their true pixel projections. With a rolling shutter the
  /// projection is taken at the exposure time of the row where the corner is seen (the fixed
  /// point y = project_y(pose(rowTime(frame, y)))), and so are the visibility tests.
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
  /// Renders the noise-free radiance of a rolling-shutter frame at `frame_time`: every row at
  /// the pose of its own exposure time (SyntheticSequence::rowTime with `readout`). Readout 0
  /// gives exactly renderRadiance(pose(frame_time)).
  void renderRadianceRolling(double frame_time, double readout, ImageView<float> out);

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
  /// Brings the quads into the camera frame of `pose` and rebuilds the candidate lists of the
  /// tiles in rows [tile_row_begin, tile_row_end).
  void prepareTiles(const Pose& pose, int tile_row_begin, int tile_row_end);
  /// Pass 1 for image row y: one ray per pixel centre (records the surface ids).
  void shadeRow(int y, ImageView<float> out);
  /// Pass 2 for image row y: pixels next to a change of surface are supersampled 4x4.
  void supersampleRow(int y, ImageView<float> out);
  [[nodiscard]] bool rowHasEdge(int y) const;
  [[nodiscard]] Eigen::Vector3d rayAt(int x, int y) const;
  void rayDerivatives(int x, int y, Eigen::Vector3d& dx, Eigen::Vector3d& dy) const;
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
