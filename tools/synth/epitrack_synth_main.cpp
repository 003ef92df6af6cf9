// epitrack-synth: renders a synthetic clip with exact ground truth (ARCHITECTURE.md "Commands").
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Geometry>

#include "hal/io/file_util.hpp"
#include "hal/io/image_codec.hpp"
#include "hal/io/text_formats.hpp"
#include "tools/common/command_line.hpp"
#include "tools/synth/synthetic_sequence.hpp"

using epitrack::tools::CommandLine;
namespace synth = epitrack::synth;
namespace hal = epitrack::hal;

namespace {

// Shortest round-trip-free rendering of an option value for the ground-truth headers ("1.5").
std::string formatNumber(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", v);
  return buf;
}

// What the command line asked for.
struct SynthCommand {
  synth::SynthOptions options;
  std::string scene = "orbit";
  std::string size = "704x576";
  std::string out_dir;
  int seed = 1;
  int threads = 1;
  bool quiet = false;
};

// Registers every option; the strings that need parsing after the command line land in `distortion`
// and `rolling_shutter`.
void declareOptions(CommandLine& cl, SynthCommand& c, std::string& distortion,
                    std::string& rolling_shutter, double& fps) {
  synth::SynthOptions& o = c.options;
  cl.choice("scene",
            {"orbit", "dolly", "pan", "handheld", "planar", "shake", "fastpan", "occlusion"},
            "camera motion: orbit = arc around a look-at target (0.25 deg/frame, radius 6 m); "
            "dolly = forward\n"
            "      motion (<= 1.5 cm/frame); pan = pure rotation; handheld = sideways walk plus "
            "gentle shake; planar = one\n"
            "      textured plane; shake = distant room, slow drift, hand-held jitter at 1-8 Hz "
            "(30 fps) with jerks;\n"
            "      fastpan = back-and-forth pan up to ~3.5 deg/frame with a small drift; "
            "occlusion = orbit around\n"
            "      pillars at several depths (default orbit)",
            &c.scene);
  cl.integer("frames", "N", "number of frames (default 100)", &o.frames, 1, 100000);
  cl.text("size", "WxH", "image size in pixels (default 704x576)", &c.size);
  cl.real("focal", "F", "focal length in pixels (default 600); principal point at the centre",
          &o.focal, 1.0, 1e6);
  cl.real("noise", "SIGMA", "Gaussian noise standard deviation in gray levels (default 0)",
          &o.noise_sigma, 0.0, 128.0);
  cl.real("blur", "EXPOSURE",
          "motion blur: exposure in frame intervals, 0 = none, 1 = the whole interval (default 0)",
          &o.blur, 0.0, 16.0);
  cl.text("distortion", "K1,K2", "radial distortion applied by the lens (default none)",
          &distortion);
  cl.real("target-wander", "METRES",
          "orbit: amplitude of the look-at target's motion; 0 makes every optical axis meet in one "
          "point,\n"
          "      a critical motion for focal self-calibration (default 0)",
          &o.target_wander, 0.0, 10.0);
  cl.real("orbit-speed", "DEG",
          "orbit: degrees of arc per frame (default 0.25; 0.75 is the fast orbit of the "
          "rolling-shutter tests)",
          &o.orbit_speed_deg, -10.0, 10.0);
  cl.real("shake", "DEG",
          "shake: peak rotational jitter per axis in degrees; the jerks scale with it "
          "(default 2)",
          &o.shake_deg, 0.0, 10.0);
  cl.real("walk", "METRES",
          "fastpan: sideways walk of the camera centre per frame (default 0.012); 0 = the same "
          "pan on a tripod",
          &o.walk_m, 0.0, 1.0);
  cl.text("rolling-shutter", "READOUT",
          "rolling shutter: time from the first row's exposure to the last row's, in frame "
          "intervals (0.9)\n"
          "      or milliseconds (30ms, with --fps), at most one frame interval; every row is "
          "rendered at its own\n"
          "      pose; groundtruth.txt holds the middle row's pose, landmarks.txt each corner at "
          "its row's time\n"
          "      (default 0: global shutter)",
          &rolling_shutter);
  cl.real("fps", "F", "frame rate that converts --rolling-shutter in ms (default 30)", &fps, 0.1,
          10000.0);
  cl.integer("seed", "S", "seed of the scene layout, textures, shake and noise (default 1)",
             &c.seed, 0, 2147483647);
  cl.integer("threads", "N", "rendering threads (default: all cores)", &c.threads, 1, 256);
  cl.text("out", "DIR", "output directory (created)", &c.out_dir);
  cl.flag("quiet", "no progress on stderr", &c.quiet);
  cl.require("out");
}

// The readout of --rolling-shutter in frame intervals ("0.9", or "30ms" at `fps`); false when it
// is not a number in [0, 1] frame intervals.
bool parseReadout(std::string number, double fps, double& readout) {
  const bool in_ms = number.size() > 2 && number.compare(number.size() - 2, 2, "ms") == 0;
  if (in_ms) number.resize(number.size() - 2);
  char* end = nullptr;
  const double value = std::strtod(number.c_str(), &end);
  readout = in_ms ? value * fps / 1000.0 : value;
  return !number.empty() && end == number.c_str() + number.size() && std::isfinite(value) &&
         readout >= 0.0 && readout <= 1.0;
}

// Parses the command line into `c`; returns -1 to go on, else the exit code.
int parseCommand(int argc, char** argv, SynthCommand& c) {
  std::string distortion;
  std::string rolling_shutter;
  double fps = 30.0;
  c.threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  CommandLine cl(
      "epitrack-synth", "--scene KIND --frames N --size WxH --focal F --out DIR [options]",
      "Renders a static scene of textured planes and boxes along a camera path, with exact\n"
      "ground truth: DIR/frames/000000.pgm..., groundtruth.txt (T_wc per frame), intrinsics.txt,\n"
      "points3d.txt (id X Y Z of every texture corner) and landmarks.txt (frame id x y of every\n"
      "corner visible in that frame). Deterministic for a seed on every platform.");
  declareOptions(cl, c, distortion, rolling_shutter, fps);
  if (const auto r = cl.parse(argc, argv); r != CommandLine::Result::kOk)
    return CommandLine::exitCode(r);
  synth::SynthOptions& o = c.options;
  synth::parseSceneKind(c.scene, o.kind);
  if (!epitrack::tools::parseSize(c.size, o.width, o.height))
    return cl.usageError("--size: expected WxH, got '" + c.size + "'");
  if (o.width < 16 || o.height < 16) return cl.usageError("--size: at least 16x16");
  if (!distortion.empty()) {
    std::vector<double> k;
    if (!epitrack::tools::parseDoubleList(distortion, k) || k.size() != 2 || std::abs(k[0]) > 1.0 ||
        std::abs(k[1]) > 1.0) {
      return cl.usageError("--distortion: expected K1,K2 with |k| <= 1, got '" + distortion + "'");
    }
    o.k1 = k[0];
    o.k2 = k[1];
  }
  o.seed = static_cast<uint64_t>(c.seed);
  if (!rolling_shutter.empty() && !parseReadout(rolling_shutter, fps, o.readout)) {
    return cl.usageError(
        "--rolling-shutter: expected a readout of 0-1 frame intervals (0.9) or milliseconds "
        "up to one frame period (30ms at --fps 30), got '" +
        rolling_shutter + "'");
  }
  return -1;
}

// Renders every frame to DIR/frames in parallel (the workers write the files) and collects each
// frame's landmark lines (one string per frame, sized by the caller); false with `error` when a
// file cannot be written.
bool renderFrames(const SynthCommand& c, const synth::SyntheticSequence& seq,
                  std::vector<std::string>& landmark_lines, std::string& error) {
  const int frames = c.options.frames;
  std::atomic<int> next{0};
  std::atomic<int> done{0};
  std::atomic<bool> failed{false};
  std::mutex error_mutex;
  const auto worker = [&]() {
    synth::FrameRenderer renderer(seq);
    epitrack::Image<uint8_t> image;
    std::vector<synth::LandmarkObservation> obs;
    std::string err;
    char name[64];
    for (int f = next++; f < frames && !failed; f = next++) {
      renderer.render(f, image);
      std::snprintf(name, sizeof(name), "/frames/%06d.pgm", f);
      if (!hal::writePgm(c.out_dir + name, image.constView(), err)) {
        std::lock_guard<std::mutex> lock(error_mutex);
        error = err;
        failed = true;
        return;
      }
      seq.visibleLandmarks(f, obs);
      std::string& lines = landmark_lines[static_cast<std::size_t>(f)];
      char buf[96];
      for (const auto& l : obs) {
        std::snprintf(buf, sizeof(buf), "%d %d %.4f %.4f\n", f, l.id, l.x, l.y);
        lines += buf;
      }
      const int d = ++done;
      if (!c.quiet && (d % 20 == 0 || d == frames))
        std::fprintf(stderr, "\repitrack-synth: %d/%d frames", d, frames);
    }
  };
  std::vector<std::thread> pool;
  for (int i = 0; i < c.threads; ++i) pool.emplace_back(worker);
  for (auto& t : pool) t.join();
  if (!c.quiet) std::fprintf(stderr, "\n");
  return !failed;
}

// The command that made the clip, for the ground-truth headers (only the options that matter).
std::string describeCommand(const SynthCommand& c) {
  const synth::SynthOptions& o = c.options;
  return std::string("epitrack-synth --scene ") + c.scene + " --frames " +
         std::to_string(o.frames) + " --size " + c.size + " --seed " + std::to_string(c.seed) +
         (o.kind == synth::SceneKind::kShake ? " --shake " + formatNumber(o.shake_deg)
                                             : std::string()) +
         (o.kind == synth::SceneKind::kFastPan && o.walk_m != 0.012
              ? " --walk " + formatNumber(o.walk_m)
              : std::string()) +
         (o.kind == synth::SceneKind::kOrbit && o.orbit_speed_deg != 0.25
              ? " --orbit-speed " + formatNumber(o.orbit_speed_deg)
              : std::string()) +
         (o.readout > 0.0 ? " --rolling-shutter " + formatNumber(o.readout) +
                                " (frame intervals; each pose is the middle row's)"
                          : std::string());
}

// groundtruth.txt: T_wc of every frame (the middle row's pose under a rolling shutter).
std::string formatGroundTruth(const synth::SyntheticSequence& seq, int frames,
                              const std::string& what) {
  std::vector<hal::TrajectoryEntry> traj;
  for (int f = 0; f < frames; ++f) {
    const synth::Pose p = seq.pose(f);
    hal::TrajectoryEntry e;
    e.t = f;
    e.position = p.t_wc;
    e.rotation = Eigen::Quaterniond(p.R_wc);
    if (e.rotation.w() < 0) e.rotation.coeffs() *= -1.0;
    traj.push_back(e);
  }
  return hal::formatTrajectory(traj, what);
}

// points3d.txt: every texture corner of the scene.
std::string formatScenePoints(const synth::SyntheticSequence& seq) {
  std::string points = "# id X Y Z  (world, metres; z up; texture corners)\n";
  char buf[128];
  for (const auto& l : seq.scene().landmarks) {
    std::snprintf(buf, sizeof(buf), "%d %.6f %.6f %.6f\n", l.id, l.position.x(), l.position.y(),
                  l.position.z());
    points += buf;
  }
  return points;
}

// Writes groundtruth.txt, intrinsics.txt, points3d.txt and landmarks.txt (each atomically).
bool writeGroundTruth(const SynthCommand& c, const synth::SyntheticSequence& seq,
                      const std::vector<std::string>& landmark_lines, std::string& error) {
  const synth::SynthOptions& o = c.options;
  const std::string what = describeCommand(c);
  epitrack::CameraIntrinsics k = epitrack::CameraIntrinsics::centered(o.width, o.height, o.focal);
  k.k1 = o.k1;
  k.k2 = o.k2;
  std::string landmarks =
      o.readout > 0.0
          ? "# frame id x y  (true projection of each visible scene corner at the exposure time "
            "of its row, pixels; rolling shutter, readout " +
                formatNumber(o.readout) + " frame intervals)\n"
          : "# frame id x y  (true projection of each visible scene corner, pixels)\n";
  for (const auto& l : landmark_lines) landmarks += l;
  return hal::writeTextAtomic(c.out_dir + "/groundtruth.txt",
                              formatGroundTruth(seq, o.frames, what), error) &&
         hal::writeTextAtomic(c.out_dir + "/intrinsics.txt", hal::formatIntrinsics(k, what),
                              error) &&
         hal::writeTextAtomic(c.out_dir + "/points3d.txt", formatScenePoints(seq), error) &&
         hal::writeTextAtomic(c.out_dir + "/landmarks.txt", landmarks, error);
}

}  // namespace

int main(int argc, char** argv) {
  SynthCommand c;
  if (const int exit_code = parseCommand(argc, argv, c); exit_code >= 0) return exit_code;
  std::string error;
  if (!hal::makeDirectories(c.out_dir + "/frames", error)) {
    std::fprintf(stderr, "epitrack-synth: --out: %s\n", error.c_str());
    return 2;  // the directory named on the command line cannot be created
  }
  const auto t0 = std::chrono::steady_clock::now();
  const synth::SyntheticSequence seq(c.options);
  std::vector<std::string> landmark_lines(static_cast<std::size_t>(c.options.frames));
  if (!renderFrames(c, seq, landmark_lines, error) ||
      !writeGroundTruth(c, seq, landmark_lines, error)) {
    std::fprintf(stderr, "epitrack-synth: %s\n", error.c_str());
    return 1;
  }
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!c.quiet) {
    std::fprintf(stderr, "epitrack-synth: %d frames %dx%d (%s) in %.2f s, %zu landmarks -> %s\n",
                 c.options.frames, c.options.width, c.options.height, c.scene.c_str(), secs,
                 seq.scene().landmarks.size(), c.out_dir.c_str());
  }
  return 0;
}
