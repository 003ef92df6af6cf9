#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "hal/io/file_util.hpp"
#include "hal/io/image_codec.hpp"
#include "tools/common/interrupt.hpp"
#include "tools/render/avi_writer.hpp"
#include "tools/render/object_placement.hpp"
#include "tools/render/overlay_renderer.hpp"
#include "tools/render/track_overlay.hpp"
#include "tools/solve/solve_run.hpp"

// The second pass of epitrack-solve: every frame read again (or taken from memory for stdin),
// drawn with the solved camera (the object and its ground grid; with --overlay tracks beside the
// 2D tracks), written as augmented/NNNNNN.jpg and into augmented.avi; the middle solved frame
// once more with the up arrow as scene_frame.jpg.

namespace epitrack::tools {

using render::LineSet;
using render::makeGroundGrid;
using render::Mesh;
using render::MjpegAviWriter;
using render::OverlayRenderer;
using render::Rgb8;

namespace {

// The camera-to-scene transform of a solved camera (what the renderer draws with).
Eigen::Isometry3d cameraToScene(const io::SolvedCamera& cam) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = cam.R_wc;
  T.translation() = cam.p_wc;
  return T;
}

// With a rolling shutter (rec.readout_frames > 0, docs/rolling-shutter.md) the renderer draws
// every row at its own pose, from the frame's middle-row pose and its motion over the readout, so
// that the object shears with the plate; a global-shutter solve draws with the one pose.
void setCameraShutter(OverlayRenderer& renderer, const io::Reconstruction& rec,
                      const io::SolvedCamera& cam) {
  RollingShutterMotion motion;
  motion.angular = cam.rs_angular;
  motion.linear = cam.rs_linear;
  renderer.setRollingShutter(RollingShutter::fromReadout(rec.readout_frames, rec.intrinsics.height,
                                                         rec.readout_reference_row),
                             motion);
}

// The solved frame nearest the middle of the solved ones (-1: none): the report's scene-frame
// picture (the object is placed for the middle of the clip, see object_placement.hpp).
int middleSolvedFrame(const io::Reconstruction& rec) {
  std::vector<int> solved;
  for (const auto& c : rec.cameras)
    if (c.solved) solved.push_back(static_cast<int>(c.frame));
  return solved.empty() ? -1 : solved[solved.size() / 2];
}

// DIR/scene_frame.jpg (issue 23): `plate` with the ground grid, the object and the scene's up as
// a yellow arrow beside the object (offset along the camera's right, so it stands clear of it).
bool writeSceneFrameImage(const io::Reconstruction& rec, int frame, const Mesh& object,
                          const LineSet& grid, OverlayRenderer& renderer, ImageView<Rgb8> plate,
                          hal::JpegEncoder& encoder, const std::string& path, std::string& error) {
  const auto& cam = rec.cameras[static_cast<std::size_t>(frame)];
  Eigen::Vector3d right(cam.R_wc(0, 0), cam.R_wc(1, 0), 0.0);
  right = right.norm() > 1e-9 ? Eigen::Vector3d(right.normalized()) : Eigen::Vector3d::UnitX();
  const double scale = rec.object.scale;
  const double length = std::isfinite(rec.object.height) ? 1.3 * rec.object.height : 0.6 * scale;
  const Eigen::Isometry3d T = cameraToScene(cam);
  renderer.clear();
  setCameraShutter(renderer, rec, cam);
  renderer.drawLines(grid, T);
  renderer.drawMesh(object, T);
  renderer.drawMesh(render::makeUpArrow(rec.object.at + 0.45 * scale * right, length), T);
  renderer.composite(plate);
  return encoder.encodeRgb(reinterpret_cast<const uint8_t*>(plate.data), plate.width, plate.height,
                           plate.stride * static_cast<std::ptrdiff_t>(sizeof(Rgb8)), 90, error) &&
         hal::writeFileAtomic(path, encoder.data(), encoder.size(), error);
}

// Draws the frames of the second pass: the gray frame as RGB, the object and its ground grid with
// the frame's solved camera, and with --overlay tracks the tracked features on a panel beside it
// (each observation classified by its reprojection error in the exported model, the threshold of
// the report's statistics). Buffers are made once, in the constructor.
class FrameDrawer {
 public:
  explicit FrameDrawer(const SolveRun& run)
      : run_(run),
        renderer_(run.rec.intrinsics),
        mesh_(render::makeObjectMesh(run.o.render, run.rec.object.at, run.rec.object.scale)),
        grid_(run.o.render == "none" ? LineSet{}
                                     : makeGroundGrid(run.rec.object.at, 1.0 * run.rec.object.scale,
                                                      0.25 * run.rec.object.scale)),
        rgb_(run.width, run.height),
        with_tracks_(run.o.overlay == "tracks"),
        scene_frame_(run.o.render == "none" ? -1 : middleSolvedFrame(run.rec)) {
    if (scene_frame_ >= 0) scene_plate_.allocate(run.width, run.height);
    if (!with_tracks_) return;
    kinds_.assign(run.tracks.observations().size(), render::TrackKind::kUnused);
    for (std::size_t i = 0; i < kinds_.size(); ++i) {
      const int k = run.rec_observation[i];
      if (k < 0) continue;
      const double r = run.rec.observations[static_cast<std::size_t>(k)].residual_px;
      if (std::isfinite(r))
        kinds_[i] = r <= run.outlierPx() ? render::TrackKind::kInlier : render::TrackKind::kOutlier;
    }
    panel_.allocate(run.width, run.height);
    both_.allocate(2 * run.width, run.height);
  }

  [[nodiscard]] int outputWidth() const { return with_tracks_ ? 2 * run_.width : run_.width; }
  [[nodiscard]] int sceneFrame() const { return scene_frame_; }

  /// Frame `f` drawn (valid until the next call).
  ImageView<const Rgb8> draw(ImageView<const uint8_t> luma, int f) {
    for (int y = 0; y < run_.height; ++y)
      for (int x = 0; x < run_.width; ++x) {
        const uint8_t v = luma(x, y);
        rgb_.view()(x, y) = Rgb8{v, v, v};
      }
    if (with_tracks_) copyPixels<Rgb8>(rgb_.constView(), panel_.view());
    if (f == scene_frame_) copyPixels<Rgb8>(rgb_.constView(), scene_plate_.view());
    const auto& cam = run_.rec.cameras[static_cast<std::size_t>(f)];
    if (cam.solved && (!mesh_.triangles.empty() || !grid_.from.empty())) {
      const Eigen::Isometry3d T = cameraToScene(cam);
      renderer_.clear();
      setCameraShutter(renderer_, run_.rec, cam);
      renderer_.drawLines(grid_, T);
      renderer_.drawMesh(mesh_, T);
      renderer_.composite(rgb_.view());
    }
    if (!with_tracks_) return rgb_.constView();
    render::drawTracks(panel_.view(), run_.tracks, kinds_, f);
    render::sideBySide(rgb_.constView(), panel_.constView(), both_.view());
    return both_.constView();
  }

  /// scene_frame.jpg from the plate kept by draw(sceneFrame()).
  bool writeSceneFrame(hal::JpegEncoder& encoder, const std::string& path, std::string& error) {
    return writeSceneFrameImage(run_.rec, scene_frame_, mesh_, grid_, renderer_,
                                scene_plate_.view(), encoder, path, error);
  }

 private:
  const SolveRun& run_;
  OverlayRenderer renderer_;
  Mesh mesh_;
  LineSet grid_;
  Image<Rgb8> rgb_;
  bool with_tracks_;
  int scene_frame_;
  Image<Rgb8> scene_plate_;
  std::vector<render::TrackKind> kinds_;
  Image<Rgb8> panel_, both_;
};

// One drawn frame into augmented.avi and augmented/NNNNNN.jpg (NNNNNN: `index`).
bool writeAugmentedFrame(ImageView<const Rgb8> out, int index, const std::string& aug_dir,
                         hal::JpegEncoder& encoder, MjpegAviWriter& avi, std::string& error) {
  char name[32];
  std::snprintf(name, sizeof(name), "/%06d.jpg", index);
  return encoder.encodeRgb(reinterpret_cast<const uint8_t*>(out.data), out.width, out.height,
                           out.stride * static_cast<std::ptrdiff_t>(sizeof(Rgb8)), 90, error) &&
         avi.addFrame(encoder.data(), encoder.size(), error) &&
         hal::writeFileAtomic(aug_dir + name, encoder.data(), encoder.size(), error);
}

// The files written, listed for the report and summary.json.
void listAugmentedFiles(SolveRun& run, int count) {
  for (int i = 0; i < count; ++i) {
    char rel[40];
    std::snprintf(rel, sizeof(rel), "augmented/%06d.jpg", i);
    run.report.augmented_frames.emplace_back(i, rel);
    run.rec.files.emplace_back(rel);
  }
  run.report.video = "augmented.avi";
  run.rec.files.emplace_back("augmented.avi");
}

}  // namespace

StageResult renderAugmented(SolveRun& run, int solved_frames) {
  if (!run.draw_frames || solved_frames == 0 || !run.stop_stage.empty()) return std::nullopt;
  const SolveCommandOptions& o = run.o;
  std::string& error = run.error;
  const auto failed = [&]() -> StageResult {
    fail(error.c_str());
    return 1;
  };
  const std::string aug_dir = o.out_dir + "/augmented";
  if (!hal::makeDirectories(aug_dir, error)) return failed();
  std::unique_ptr<hal::FrameSource> replay;
  if (!run.keep_frames) {
    replay = hal::openFrameSource(o.input, run.source_options, error);
    if (!replay) return failed();
  }
  FrameDrawer drawer(run);
  hal::JpegEncoder encoder;
  MjpegAviWriter avi;
  const double fps = run.source->info().fps > 0.0 ? run.source->info().fps : 30.0;
  if (!avi.open(o.out_dir + "/augmented.avi", drawer.outputWidth(), run.height, fps, error))
    return failed();
  run.progress.begin("rendering", run.frames);
  hal::Frame frame;
  int index = 0;
  for (int f = 0; f < run.frames;) {
    if (interruptRequested()) {  // the frames rendered so far stay, the video ends with them
      run.stop_stage = "rendering";
      break;
    }
    ImageView<const uint8_t> luma;
    if (run.keep_frames) {
      luma = run.kept[static_cast<std::size_t>(f)].constView();
    } else {
      const auto st = replay->next(frame);
      if (st == hal::FrameStatus::kEndOfStream) break;
      if (st != hal::FrameStatus::kOk) continue;  // the tracking pass skipped it too
      luma = frame.luma;
    }
    if (!writeAugmentedFrame(drawer.draw(luma, f), index, aug_dir, encoder, avi, error))
      return failed();
    if (f == drawer.sceneFrame()) {
      if (!drawer.writeSceneFrame(encoder, o.out_dir + "/scene_frame.jpg", error)) return failed();
      run.report.scene_frame_image = "scene_frame.jpg";
      run.report.scene_frame_index = f;
      run.rec.files.emplace_back("scene_frame.jpg");
    }
    ++index;
    ++f;
    run.progress.update(f);
  }
  run.progress.end();
  if (!avi.finish(error)) return failed();
  listAugmentedFiles(run, index);
  run.clock.lap("rendering");
  return std::nullopt;
}

}  // namespace epitrack::tools
