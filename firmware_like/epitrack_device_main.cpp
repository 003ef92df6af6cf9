// epitrack-device: the on-device live tracker (ARCHITECTURE.md "Commands"). Configuration is read
// once; every buffer is reserved before the first frame; the loop then runs frame source ->
// FeatureTracker -> LiveMap -> one JSON line per frame, without heap allocation, until the stream
// ends, --max-frames is reached, or SIGINT/SIGTERM asks it to stop (a final statistics line).

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "algo/geometry/camera_intrinsics.hpp"
#include "algo/sfm/live_tracker.hpp"
#include "firmware_like/device_config.hpp"
#include "firmware_like/frame_statistics.hpp"
#include "firmware_like/pose_output.hpp"
#include "hal/cpu/cpu_features.hpp"
#include "hal/frame_source.hpp"
#include "hal/io/text_formats.hpp"
#include "hal/record/frame_recorder.hpp"

namespace {

volatile std::sig_atomic_t g_stop_signal = 0;

extern "C" void onStopSignal(int signal_number) { g_stop_signal = signal_number; }

void installSignalHandlers() {
  struct sigaction action {};
  action.sa_handler = onStopSignal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = 0;  // no SA_RESTART: a blocking capture returns and the loop sees the flag
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

/// Peak resident set size (VmHWM) in KiB, or -1.
long peakResidentKib() {
  std::FILE* f = std::fopen("/proc/self/status", "r");
  if (f == nullptr) return -1;
  char line[256];
  long kib = -1;
  while (std::fgets(line, sizeof(line), f) != nullptr) {
    if (std::strncmp(line, "VmHWM:", 6) == 0) kib = std::strtol(line + 6, nullptr, 10);
  }
  std::fclose(f);
  return kib;
}

int usageError(const std::string& message) {
  std::fprintf(stderr, "epitrack-device: %s (see --help)\n", message.c_str());
  return 2;
}

// The command-line options: most set a configuration key of the same name ('-' for '_').
struct CommandOption {
  const char* name;
  const char* metavar;  // empty: a flag
  const char* key;      // configuration key, nullptr for --config and --set
  const char* help;     // nullptr: the key's own help
};

constexpr CommandOption kCommandOptions[] = {
    {"source", "INPUT", "source", nullptr},
    {"intrinsics", "FILE", "intrinsics", nullptr},
    {"config", "FILE", nullptr, "read 'key = value' lines (# comments); the command line wins"},
    {"poses", "-|FILE", "poses", nullptr},
    {"record", "FILE.mjpeg|DIR", "record", nullptr},
    {"max-frames", "N", "max_frames", nullptr},
    {"features", "N", "features", nullptr},
    {"focal", "PX", "focal", nullptr},
    {"realtime", "", "realtime", "pace replay at the nominal rate; late frames are dropped"},
    {"set", "KEY=VALUE", nullptr, "set any configuration key below (repeatable)"},
};

const CommandOption* findCommandOption(const std::string& name) {
  for (const auto& o : kCommandOptions)
    if (name == o.name) return &o;
  return nullptr;
}

void printHelp() {
  std::printf(
      "usage: epitrack-device --source INPUT [--intrinsics FILE] [--config FILE] [--poses -|FILE]\n"
      "                       [--record FILE.mjpeg|DIR] [--max-frames N] [--realtime] [--features "
      "N]\n"
      "                       [--focal PX] [--set KEY=VALUE ...]\n\n"
      "Live camera tracking on the device: one JSON line per frame (frame, t, status, features,\n"
      "q [qx,qy,qz,qw] and p [x,y,z] of T_wc when tracking, ms) and a final statistics line.\n"
      "All memory is reserved before the first frame. SIGINT/SIGTERM stop cleanly (the final\n"
      "line says \"stopped_by\"; exit 0). Without --intrinsics or --focal the focal is\n"
      "self-calibrated over the first seconds of motion.\n"
      "A camera (v4l2:) always drops frames it cannot keep up with; a replay with --realtime.\n"
      "Exit: 0 done, 1 the stream failed (lost device, size change, write error), 2 bad command\n"
      "line, configuration or unusable --source/--intrinsics/--config/--poses/--record.\n\n"
      "options:\n");
  const auto& keys = epitrack::device::configKeys();
  for (const auto& o : kCommandOptions) {
    std::string help = o.help != nullptr ? o.help : "";
    std::string range;
    if (o.key != nullptr) {
      range = epitrack::device::configKeyRange(o.key);
      if (o.help == nullptr) {
        for (const auto& [key, key_help] : keys)
          if (key == o.key)
            help = key_help.substr(0, key_help.size() - (range.empty() ? 0 : range.size() + 1));
      }
      help += std::string(help.empty() ? "" : "; ") + "key " + o.key;
    }
    std::printf("  --%s%s%s%s\n      %s\n", o.name, *o.metavar ? " " : "", o.metavar,
                range.empty() ? "" : ("  " + range).c_str(), help.c_str());
  }
  std::printf(
      "  --help\n      print this help and exit\n\nconfiguration keys (--set KEY=VALUE or "
      "'key = value' in --config FILE):\n");
  for (const auto& [key, help] : keys) std::printf("  %-24s %s\n", key.c_str(), help.c_str());
}

// One setting from the command line: the key, its value and how it was written (for messages).
struct Override {
  std::string key;
  std::string value;
  std::string origin;  // "--features" or "--set features=5"
};

using epitrack::device::DeviceConfig;

// ---- stage 1: the configuration, read once: the command line (as key/value pairs) over the file

/// Fills `config` from the command line and the --config file under it. Returns the exit code
/// when the command ends here (0 after --help, 2 on a usage or configuration error, the message
/// printed), or -1 to go on.
int readConfiguration(int argc, char** argv, DeviceConfig& config) {
  std::vector<Override> overrides;
  std::string config_path;
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      printHelp();
      return 0;
    }
    if (arg.rfind("--", 0) != 0) return usageError("unexpected argument '" + arg + "'");
    std::string name = arg.substr(2);
    std::string value;
    bool have_value = false;
    if (const auto eq = name.find('='); eq != std::string::npos) {
      value = name.substr(eq + 1);
      name = name.substr(0, eq);
      have_value = true;
    }
    const CommandOption* option = findCommandOption(name);
    if (option == nullptr) return usageError("unknown option '--" + name + "'");
    if (*option->metavar == '\0') {  // a flag; --realtime=false is accepted too
      overrides.push_back({option->key, have_value ? value : "true", "--" + name});
      continue;
    }
    if (!have_value) {
      if (i + 1 >= argc)
        return usageError("option '--" + name + "' needs a value " + option->metavar);
      value = argv[++i];
    }
    if (name == "config") {
      config_path = value;
    } else if (name == "set") {
      const auto eq = value.find('=');
      if (eq == std::string::npos || eq == 0)
        return usageError("--set: expected KEY=VALUE, got '" + value + "'");
      overrides.push_back({value.substr(0, eq), value.substr(eq + 1), "--set " + value});
    } else {
      overrides.push_back({option->key, value, "--" + name});
    }
  }
  std::string error;
  if (!config_path.empty()) {
    std::string text;
    if (!epitrack::hal::readTextFile(config_path, text, error)) return usageError(error);
    if (!epitrack::device::applyConfigText(config, text, config_path, error))
      return usageError(error);
  }
  for (const auto& o : overrides) {
    std::string why;
    if (!epitrack::device::applyConfigValueReason(config, o.key, o.value, why))
      return usageError(o.origin + ": " + why);
  }
  if (!epitrack::device::validateConfig(config, error)) return usageError(error);
  return -1;
}

// ---- stage 2: everything reserved before the first frame ----------------------------------------

/// What the loop reads from and writes to, opened before the first frame.
struct DeviceIo {
  std::unique_ptr<epitrack::hal::FrameSource> source;
  epitrack::CameraIntrinsics intrinsics;
  const char* focal_source = "none yet";  ///< "given", "none yet", later the calibration's
  epitrack::hal::FrameRecorder recorder;
  std::FILE* poses = stdout;
};

/// Opens the source, reads or sets up the intrinsics (self-calibration when none are given: sets
/// config.map.self_calibrate) and opens the recorder. What the command line or the configuration
/// names and cannot be used ends here: false, the message printed (exit 2).
bool openInputs(DeviceConfig& config, DeviceIo& io) {
  epitrack::hal::SourceOptions source_options;
  source_options.realtime = config.realtime;
  source_options.default_fps = config.fps;
  std::string error;
  io.source = epitrack::hal::openFrameSource(config.source, source_options, error);
  if (!io.source) {
    std::fprintf(stderr, "epitrack-device: %s\n", error.c_str());
    return false;
  }
  const auto& info = io.source->info();
  if (!config.intrinsics_path.empty()) {
    if (!epitrack::hal::readIntrinsicsFile(config.intrinsics_path, io.intrinsics, error)) {
      std::fprintf(stderr, "epitrack-device: --intrinsics: %s\n", error.c_str());
      return false;
    }
    if (io.intrinsics.width != info.width || io.intrinsics.height != info.height) {
      std::fprintf(stderr,
                   "epitrack-device: --intrinsics: %s is for %dx%d, the source gives %dx%d\n",
                   config.intrinsics_path.c_str(), io.intrinsics.width, io.intrinsics.height,
                   info.width, info.height);
      return false;
    }
  } else if (config.focal > 0.0) {
    io.intrinsics = epitrack::CameraIntrinsics::centered(info.width, info.height, config.focal);
  } else {
    // Self-calibration over the first seconds (centred pinhole, square pixels); the focal here
    // is only a placeholder until then.
    io.intrinsics = epitrack::CameraIntrinsics::centered(info.width, info.height,
                                                         1.2 * std::max(info.width, info.height));
    config.map.self_calibrate = true;
    std::fprintf(
        stderr,
        "epitrack-device: no intrinsics given: the focal is self-calibrated from the first "
        "seconds of motion (centred pinhole)\n");
  }
  io.focal_source = !config.intrinsics_path.empty() || config.focal > 0.0 ? "given" : "none yet";
  if (!config.record.empty()) {
    if (!io.recorder.open(config.record, epitrack::hal::RecorderOptions{}, error)) {
      std::fprintf(stderr, "epitrack-device: --record: %s\n", error.c_str());
      return false;
    }
  }
  return true;
}

/// Opens the pose stream (--poses: standard output or a file), line-buffered in a static buffer so
/// that writing a line never allocates. False, the message printed, when the file cannot be
/// written (exit 2).
bool openPoseOutput(const DeviceConfig& config, DeviceIo& io) {
  if (config.poses != "-") {
    io.poses = std::fopen(config.poses.c_str(), "w");
    if (io.poses == nullptr) {
      std::fprintf(stderr, "epitrack-device: --poses: cannot write %s: %s\n", config.poses.c_str(),
                   std::strerror(errno));
      return false;
    }
  }
  static char buffer[1 << 16];
  std::setvbuf(io.poses, buffer, _IOLBF, sizeof(buffer));  // one line at a time, no malloc
  return true;
}

// ---- stage 3: the loop
// ----------------------------------------------------------------------------

/// Late frames are dropped from a live camera always, from a replay with --realtime: a frame more
/// than one period behind the clock is skipped, so the backlog never exceeds the driver's own
/// (fixed) buffer ring.
class FramePacer {
 public:
  explicit FramePacer(double fps) : period_s_(1.0 / fps) {}

  /// True when the frame stamped `timestamp_s` is more than one period older than the clock says
  /// the newest is (processing lags: drop it and take the next one).
  bool late(double timestamp_s) {
    const auto now = std::chrono::steady_clock::now();
    if (!have_first_) {
      have_first_ = true;
      first_t_ = timestamp_s;
      first_wall_ = now;
      return false;
    }
    const double wall = std::chrono::duration<double>(now - first_wall_).count();
    const double late_s = wall - (timestamp_s - first_t_);
    if (late_s < 0.0) {
      // Fresher than the first frame was: that one had waited in the driver's queue (the start
      // after STREAMON is slow on a small board), and measuring from it would pass frames that
      // old as current. Measure from this frame instead.
      first_t_ = timestamp_s;
      first_wall_ = now;
      return false;
    }
    return late_s > period_s_;
  }

 private:
  double period_s_;
  bool have_first_ = false;
  double first_t_ = 0.0;
  std::chrono::steady_clock::time_point first_wall_{};
};

/// Counts a processed frame's status in `stats`.
void countFrame(const epitrack::LiveFrameResult& map, epitrack::device::FrameStatistics& stats) {
  ++stats.frames;
  switch (map.status) {
    case epitrack::LiveStatus::kTracking:
      ++stats.tracking;
      break;
    case epitrack::LiveStatus::kInitializing:
      ++stats.initializing;
      break;
    case epitrack::LiveStatus::kLost:
      ++stats.lost;
      break;
  }
  if (map.initialized) ++stats.initializations;
}

/// Frames from the source through the tracker to one pose line each, until the stream ends,
/// --max-frames is reached or SIGINT/SIGTERM asks to stop. Never allocates. Returns the exit code
/// so far: 0, or 1 when the stream, the recording or a frame's size failed (the message printed).
int runLoop(const DeviceConfig& config, DeviceIo& io, epitrack::LiveTracker& tracker,
            epitrack::device::FrameStatistics& stats) {
  const auto& info = io.source->info();
  const double fps = info.fps > 0.0 ? info.fps : config.fps;
  const bool pace = config.realtime || config.source.rfind("v4l2:", 0) == 0;
  FramePacer pacer(fps);
  int64_t last_index = -1;
  std::string error;
  char line[512];
  epitrack::hal::Frame frame;
  epitrack::LiveFrameOutput result;
  while (g_stop_signal == 0 && (config.max_frames == 0 || stats.frames < config.max_frames)) {
    const auto status = io.source->next(frame);
    if (status == epitrack::hal::FrameStatus::kTimeout) continue;
    if (status == epitrack::hal::FrameStatus::kCorruptFrame) {
      ++stats.corrupt;
      continue;
    }
    if (status == epitrack::hal::FrameStatus::kEndOfStream) break;
    if (status == epitrack::hal::FrameStatus::kDeviceLost ||
        status == epitrack::hal::FrameStatus::kError) {
      if (g_stop_signal != 0) break;  // interrupted capture
      std::fprintf(stderr, "epitrack-device: %s: %s\n", epitrack::hal::frameStatusName(status),
                   io.source->lastError().c_str());
      return 1;
    }
    // Frames the source skipped (a live driver overwrote them) count as dropped.
    if (last_index >= 0 && frame.index > last_index + 1)
      stats.dropped += frame.index - last_index - 1;
    last_index = frame.index;
    // Every captured frame is recorded, also those processing has to drop: the recording
    // replays what the camera gave. The pose line names the frame's number in the recording
    // (record_frame), since the source's numbers (a driver's sequence) can have gaps and the
    // dropped frames are in the recording but have no pose line.
    int64_t record_frame = -1;
    if (!config.record.empty()) {
      if (!io.recorder.write(frame, error)) {
        std::fprintf(stderr, "epitrack-device: --record: %s\n", error.c_str());
        return 1;
      }
      record_frame = io.recorder.framesWritten() - 1;
    }
    if (pace && pacer.late(frame.timestamp_s)) {
      ++stats.dropped;
      continue;
    }
    const auto start = std::chrono::steady_clock::now();
    if (tracker.process(frame.luma, result) != epitrack::LiveTracker::Status::kOk) {
      std::fprintf(stderr, "epitrack-device: frame %lld is %dx%d, expected %dx%d\n",
                   static_cast<long long>(frame.index), frame.luma.width, frame.luma.height,
                   io.intrinsics.width, io.intrinsics.height);
      return 1;
    }
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    countFrame(result.map, stats);
    if (result.map.calibrated) {
      io.focal_source = tracker.map().focalFallback() ? "fallback" : "self-calibrated";
      std::fprintf(stderr, "epitrack-device: frame %lld: focal %s: %.1f px (%d pairs)\n",
                   static_cast<long long>(frame.index), io.focal_source,
                   tracker.map().intrinsics().fx, tracker.map().calibrationPairs());
    }
    if (stats.frames > config.warmup_frames) stats.addTiming(ms);
    const int n = epitrack::device::formatPoseLine(
        line, sizeof(line), frame.index, record_frame, frame.timestamp_s, result.map.status,
        result.features, result.map.pose, ms, result.map.init);
    if (n > 0 && static_cast<std::size_t>(n) < sizeof(line))
      std::fwrite(line, 1, static_cast<std::size_t>(n), io.poses);
  }
  return 0;
}

// ---- stage 4: final statistics (also after SIGINT/SIGTERM), outputs closed
// ------------------------

/// Writes the statistics line, closes the pose stream and finishes the recording. Returns the
/// exit code: `loop_code`, or 1 when closing an output failed.
int finish(const DeviceConfig& config, DeviceIo& io, const epitrack::LiveTracker& tracker,
           const epitrack::device::FrameStatistics& stats, int loop_code) {
  int exit_code = loop_code;
  std::fprintf(io.poses,
               "{\"summary\": true, \"frames\": %lld, \"tracked\": %lld, \"initializing\": %lld, "
               "\"lost\": %lld, \"dropped\": %lld, \"corrupt\": %lld, \"initializations\": %lld, "
               "\"timed_frames\": %lld, \"ms_median\": %.3f, \"ms_p95\": %.3f, \"ms_max\": %.3f, "
               "\"focal_px\": %.3f, \"focal_source\": \"%s\", \"peak_rss_kib\": %ld, "
               "\"stopped_by\": \"%s\"}\n",
               static_cast<long long>(stats.frames), static_cast<long long>(stats.tracking),
               static_cast<long long>(stats.initializing), static_cast<long long>(stats.lost),
               static_cast<long long>(stats.dropped), static_cast<long long>(stats.corrupt),
               static_cast<long long>(stats.initializations), static_cast<long long>(stats.timed()),
               stats.percentile(0.5), stats.percentile(0.95), stats.maxMs(),
               tracker.map().focalKnown() ? tracker.map().intrinsics().fx : 0.0, io.focal_source,
               peakResidentKib(),
               g_stop_signal == SIGINT    ? "SIGINT"
               : g_stop_signal == SIGTERM ? "SIGTERM"
               : exit_code != 0           ? "error"
                                          : "end");
  std::fflush(io.poses);
  if (io.poses != stdout && std::fclose(io.poses) != 0) {
    std::fprintf(stderr, "epitrack-device: closing %s failed\n", config.poses.c_str());
    exit_code = 1;
  }
  if (!config.record.empty()) {
    std::string error;
    if (!io.recorder.finish(error)) {
      std::fprintf(stderr, "epitrack-device: --record: %s\n", error.c_str());
      exit_code = 1;
    } else {
      std::fprintf(stderr, "epitrack-device: recorded %lld frames to %s\n",
                   static_cast<long long>(io.recorder.framesWritten()), config.record.c_str());
    }
  }
  io.source.reset();  // streams off, files closed
  return exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  epitrack::hal::selectKernelsForThisCpu();
  DeviceConfig config;
  if (const int code = readConfiguration(argc, argv, config); code >= 0) return code;
  DeviceIo io;
  if (!openInputs(config, io)) return 2;
  if (config.readout_ms > 0.0) {
    // The readout in frame intervals, at the source's rate: what the live map's model counts in.
    const double rate = io.source->info().fps > 0.0 ? io.source->info().fps : config.fps;
    config.map.readout_frames = config.readout_ms * rate / 1000.0;
    if (config.map.readout_frames > 1.0) {
      std::fprintf(stderr,
                   "epitrack-device: readout_ms %.3g is longer than a frame interval at %.3g fps "
                   "(a sensor reads out within its frame time)\n",
                   config.readout_ms, rate);
      return 2;
    }
  }
  epitrack::LiveTracker tracker(config.tracker, config.map, io.intrinsics);
  if (!openPoseOutput(config, io)) return 2;
  const auto& info = io.source->info();
  std::fprintf(stderr,
               "epitrack-device: %s %dx%d (%s, %.1f fps), %d features, map %.1f MiB reserved\n",
               config.source.c_str(), info.width, info.height, info.pixel_format.c_str(),
               info.fps > 0.0 ? info.fps : config.fps, config.tracker.max_features,
               static_cast<double>(tracker.map().reservedBytes()) / (1024.0 * 1024.0));
  installSignalHandlers();
  epitrack::device::FrameStatistics stats;
  const int loop_code = runLoop(config, io, tracker, stats);
  return finish(config, io, tracker, stats, loop_code);
}
