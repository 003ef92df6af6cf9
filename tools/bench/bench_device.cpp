// epitrack-bench device: per-frame time of the on-device live loop (FeatureTracker + LiveMap, the
// exact per-frame work of epitrack-device), median / p95 / max after warm-up, on one core.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <string>
#include <vector>

#include "algo/geometry/camera_intrinsics.hpp"
#include "algo/image/image.hpp"
#include "algo/sfm/live_tracker.hpp"
#include "hal/io/text_formats.hpp"
#include "tools/bench/bench_input.hpp"
#include "tools/bench/bench_registry.hpp"
#include "tools/common/command_line.hpp"
#include "tools/synth/synthetic_sequence.hpp"

namespace epitrack::bench {
namespace {

/// CPU time of this thread in milliseconds: on a machine shared with other work the wall clock
/// counts the time the thread waited for a core; this does not.
double threadCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

bool parseSize(const std::string& text, int& w, int& h) {
  return std::sscanf(text.c_str(), "%dx%d", &w, &h) == 2 && w >= 64 && h >= 64 && w <= 8192 &&
         h <= 8192;
}

int runDevice(int argc, const char* const* argv) {
  std::string input;
  std::string intrinsics_path;
  std::string size = "704x576";
  std::string scene = "orbit";
  int repeat = 3;
  int threads = 1;
  int features = 300;
  int frames_wanted = 300;
  int warmup = 30;
  double focal = 0.0;
  std::string lk_affine = "true";
  std::string redetect_fill = "share";
  std::string map_prediction = "on";
  tools::CommandLine cl(
      "epitrack-bench device",
      "[INPUT --intrinsics FILE] [--size WxH] [--scene orbit|handheld|...] [--features N] "
      "[--frames N] [--repeat N]",
      "Times the live loop of epitrack-device per frame (2D tracker + live map: PnP, keyframes,\n"
      "triangulation, windowed adjustment). Each pass starts a new map, so initialisation and\n"
      "every keyframe are in the figures; the first --warmup frames of each pass are left out.\n"
      "Without INPUT, renders a synthetic clip in memory at --size.");
  cl.positional("INPUT", "frames to use (any INPUT form); default: synthetic clip", &input, false);
  cl.text("intrinsics", "FILE", "intrinsics of INPUT (required with INPUT)", &intrinsics_path);
  cl.text("size", "WxH", "synthetic clip size (default 704x576)", &size);
  cl.text("scene", "KIND", "synthetic scene: orbit, handheld, dolly, pan, planar (default orbit)",
          &scene);
  cl.real("focal", "PX", "synthetic focal (default 0.85 x width)", &focal, 0.0, 1e6);
  cl.integer("features", "N", "tracked features (default 300)", &features, 16, 4000);
  cl.integer("frames", "N", "frames per pass (default 300)", &frames_wanted, 10, 100000);
  cl.integer("warmup", "N", "frames of each pass left out of the timing (default 30)", &warmup, 0,
             100000);
  cl.integer("repeat", "N", "passes, each with a fresh map (default 3)", &repeat, 1, 1000);
  cl.integer("threads", "N", "threads (only 1 is supported: every figure is single-core)", &threads,
             1, 1);
  FeatureTrackerOptions to = FeatureTrackerOptions{}.wholeWindow();  // the device default
  cl.integer("window", "PX", "LK window side (default 21; pi4.conf: 15)", &to.window, 5, 61);
  cl.choice("lk-affine", {"true", "false"}, "affine LK at the base level (default true)",
            &lk_affine);
  cl.real("redetect-fraction", "F", "re-detect below this fraction of features (default 0.9)",
          &to.redetect_fraction, 0.0, 1.0);
  cl.integer("redetect-cells", "N", "re-detect in grid cells, about N (default 0: whole frame)",
             &to.redetect_cells, 0, 10000);
  cl.integer("redetect-min-gap", "N", "frames between re-detections (default 1)",
             &to.redetect_min_gap, 1, 1000);
  cl.choice("redetect-fill", {"share", "all"},
            "with --redetect-cells: a searched cell takes corners up to its share (default) or "
            "the strongest of the searched cells up to the feature count",
            &redetect_fill);
  cl.choice("map-prediction", {"on", "off"},
            "predict the tracks with the map's points under a constant-velocity pose (default on)",
            &map_prediction);
  cl.real("map-prediction-radius", "PX", "how far LK may land from a map prediction (default 4)",
          &to.prediction_radius_px, 0.5, 200.0);
  if (const auto r = cl.parse(argc, argv); r != tools::CommandLine::Result::kOk)
    return tools::CommandLine::exitCode(r);

  std::vector<Image<uint8_t>> frames;
  CameraIntrinsics K;
  std::string error;
  if (!input.empty()) {
    if (intrinsics_path.empty()) {
      return cl.usageError("INPUT needs --intrinsics FILE");
    }
    if (!loadBenchFrames(input, frames_wanted, frames, error) ||
        !hal::readIntrinsicsFile(intrinsics_path, K, error)) {
      std::fprintf(stderr, "epitrack-bench device: %s\n", error.c_str());
      return 2;  // INPUT or --intrinsics named on the command line is unusable
    }
  } else {
    synth::SynthOptions so;
    if (!parseSize(size, so.width, so.height)) {
      return cl.usageError("--size: expected WxH, got '" + size + "'");
    }
    if (!synth::parseSceneKind(scene, so.kind)) {
      return cl.usageError("--scene: unknown scene '" + scene + "'");
    }
    so.frames = frames_wanted;
    so.focal = focal > 0.0 ? focal : 0.85 * so.width;
    so.target_wander = so.kind == synth::SceneKind::kOrbit ? 0.5 : 0.0;
    so.noise_sigma = 1.0;
    const synth::SyntheticSequence sequence(so);
    synth::FrameRenderer renderer(sequence);
    frames.reserve(static_cast<std::size_t>(so.frames));
    for (int i = 0; i < so.frames; ++i) {
      frames.emplace_back(so.width, so.height);
      renderer.render(i, frames.back());
    }
    K = CameraIntrinsics::centered(so.width, so.height, so.focal);
  }
  to.max_features = features;
  to.affine = lk_affine == "true";
  to.redetect_fill_share = redetect_fill == "share";
  LiveMapOptions mo;
  mo.max_features = features;
  mo.map_prediction = map_prediction == "on";

  std::vector<double> total_ms, cpu_ms, track_ms, map_ms, keyframe_ms;
  int tracking = 0, lost = 0, timed = 0;
  // LK work per timed frame: all iterations, and the tracks started from a map prediction.
  double lk_iterations = 0.0, predicted = 0.0, predicted_iterations = 0.0, fallbacks = 0.0;
  for (int r = 0; r < repeat; ++r) {
    LiveTracker tracker(to, mo, K);
    LiveFrameOutput out;
    for (std::size_t i = 0; i < frames.size(); ++i) {
      // Timed as epitrack-device times its loop: the 2D tracker, then the map.
      const double cpu_start = threadCpuMs();
      const auto start = std::chrono::steady_clock::now();
      const auto status = tracker.track(frames[i].constView());
      const auto tracked = std::chrono::steady_clock::now();
      if (status != LiveTracker::Status::kOk) {
        std::fprintf(stderr, "epitrack-bench device: frame %zu has another size\n", i);
        return 1;
      }
      tracker.locate(out);
      const auto end = std::chrono::steady_clock::now();
      const double cpu = threadCpuMs() - cpu_start;
      if (static_cast<int>(i) < warmup) continue;
      ++timed;
      const double ms = std::chrono::duration<double, std::milli>(end - start).count();
      const double ms_track = std::chrono::duration<double, std::milli>(tracked - start).count();
      total_ms.push_back(ms);
      cpu_ms.push_back(cpu);
      track_ms.push_back(ms_track);
      map_ms.push_back(ms - ms_track);
      if (out.map.keyframe) keyframe_ms.push_back(ms);
      const FrameStats& fs = tracker.tracker().lastStats();
      lk_iterations += static_cast<double>(fs.lk_iterations);
      predicted += fs.predicted;
      predicted_iterations += static_cast<double>(fs.predicted_iterations);
      fallbacks += fs.prediction_fallbacks;
      tracking += out.map.status == LiveStatus::kTracking ? 1 : 0;
      lost += out.map.status == LiveStatus::kLost ? 1 : 0;
    }
  }
  const TimingStats t = summarize(total_ms);
  const TimingStats k = summarize(keyframe_ms);
  const TimingStats c = summarize(cpu_ms);
  const double per_frame = 1.0 / std::max(timed, 1);
  JsonLine()
      .add("bench", "device")
      .add("impl", "epitrack")
      .add("ms_median", t.median)
      .add("ms_mean", t.mean)
      .add("ms_p95", t.p95)
      .add("ms_max", t.max)
      .add("cpu_ms_median", c.median)
      .add("cpu_ms_p95", c.p95)
      .add("cpu_ms_max", c.max)
      .add("frames", timed)
      .add("features", features)
      .add("window", to.window)
      .add("lk_affine", to.affine)
      .add("redetect_cells", to.redetect_cells)
      .add("width", K.width)
      .add("height", K.height)
      .add("tracking_frames", tracking)
      .add("lost_frames", lost)
      .timing("track_ms", summarize(track_ms))
      .timing("map_ms", summarize(map_ms))
      .add("keyframes", keyframe_ms.size())
      .add("keyframe_ms_median", k.median)
      .add("keyframe_ms_max", k.max)
      .add("map_prediction", mo.map_prediction)
      .add("lk_iterations_per_frame", lk_iterations * per_frame)
      .add("map_predicted_per_frame", predicted * per_frame)
      .add("map_predicted_iterations_per_frame", predicted_iterations * per_frame)
      .add("map_prediction_fallbacks_per_frame", fallbacks * per_frame)
      .print();
  return 0;
}

const BenchRegistrar kRegister("device", "per-frame time of epitrack-device's live loop",
                               runDevice);

}  // namespace
}  // namespace epitrack::bench
