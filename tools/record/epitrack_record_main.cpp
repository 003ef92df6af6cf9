// epitrack-record: records any INPUT (ARCHITECTURE.md "Inputs") to FILE.mjpeg (concatenated
// JPEGs, the camera's own JPEG bytes when it sends MJPEG) or to a directory of PGM frames
// (lossless). Corrupt frames are skipped and counted; a lost device ends the recording with
// what was captured so far.
#include <csignal>
#include <cstdio>
#include <string>

#include "hal/frame_source.hpp"
#include "hal/record/frame_recorder.hpp"
#include "tools/common/command_line.hpp"

namespace {
volatile std::sig_atomic_t g_stop = 0;
void onSignal(int) { g_stop = 1; }
}  // namespace

int main(int argc, char** argv) {
  std::string input;
  std::string out;
  int max_frames = 0;
  int quality = 92;
  int max_timeouts = 5;
  bool realtime = false;
  bool quiet = false;
  epitrack::tools::CommandLine cl(
      "epitrack-record", "INPUT --out FILE.mjpeg|DIR [--max-frames N] [--quality Q]",
      "Records INPUT (a frame directory, FILE.y4m, - for Y4M on standard input, FILE.mjpeg or\n"
      "v4l2:/dev/videoN?width=W&height=H&fps=N&format=grey|yuyv|mjpeg) as 8-bit gray frames to an\n"
      ".mjpeg file (JPEG; MJPEG cameras' frames are stored unchanged) or to DIR/000000.pgm...\n"
      "(lossless). Outputs appear atomically. Ctrl-C (SIGINT) or SIGTERM stops a recording\n"
      "cleanly: what was recorded is kept, exit 0.\n"
      "Exit: 0 done, 1 the recording failed (lost device, write error; the frames before it\n"
      "are kept), 2 bad command line or unusable INPUT/--out.");
  cl.positional("INPUT", "what to record", &input);
  cl.text("out", "FILE.mjpeg|DIR", "output file (.mjpeg/.mjpg) or frame directory", &out);
  cl.integer("max-frames", "N", "stop after N frames (default: all)", &max_frames, 0, 1 << 30);
  cl.integer("quality", "Q", "JPEG quality for re-encoded frames (default 92)", &quality, 1, 100);
  cl.integer("max-timeouts", "N",
             "give up after N consecutive timeouts of a live source (default 5)", &max_timeouts, 1,
             1000000);
  cl.flag("realtime", "replay files at their nominal frame rate", &realtime);
  cl.flag("quiet", "no progress on stderr", &quiet);
  cl.require("out");
  if (const auto r = cl.parse(argc, argv); r != epitrack::tools::CommandLine::Result::kOk) {
    return epitrack::tools::CommandLine::exitCode(r);
  }
  namespace hal = epitrack::hal;
  hal::SourceOptions source_options;
  source_options.realtime = realtime;
  std::string error;
  auto source = hal::openFrameSource(input, source_options, error);
  if (!source) {
    std::fprintf(stderr, "epitrack-record: %s\n", error.c_str());
    return 2;
  }
  hal::RecorderOptions recorder_options;
  recorder_options.jpeg_quality = quality;
  hal::FrameRecorder recorder;
  if (!recorder.open(out, recorder_options, error)) {
    std::fprintf(stderr, "epitrack-record: --out: %s\n", error.c_str());
    return 2;
  }
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  const hal::SourceInfo& info = source->info();
  if (!quiet) {
    std::fprintf(stderr, "epitrack-record: %s %dx%d %s %.3g fps -> %s\n", input.c_str(), info.width,
                 info.height, info.pixel_format.c_str(), info.fps, out.c_str());
  }
  hal::Frame frame;
  int64_t corrupt = 0;
  int timeouts = 0;
  int exit_code = 0;
  while (g_stop == 0 && (max_frames == 0 || recorder.framesWritten() < max_frames)) {
    const hal::FrameStatus status = source->next(frame);
    if (status == hal::FrameStatus::kOk) {
      timeouts = 0;
      if (!recorder.write(frame, error)) {
        std::fprintf(stderr, "epitrack-record: %s\n", error.c_str());
        exit_code = 1;
        break;
      }
      if (!quiet && recorder.framesWritten() % 100 == 0) {
        std::fprintf(stderr, "epitrack-record: %lld frames\n",
                     static_cast<long long>(recorder.framesWritten()));
      }
      continue;
    }
    if (status == hal::FrameStatus::kEndOfStream) break;
    if (status == hal::FrameStatus::kCorruptFrame) {
      ++corrupt;
      std::fprintf(stderr, "epitrack-record: skipped corrupt frame: %s\n",
                   source->lastError().c_str());
      continue;
    }
    if (status == hal::FrameStatus::kTimeout && ++timeouts < max_timeouts) continue;
    std::fprintf(stderr, "epitrack-record: %s: %s\n", hal::frameStatusName(status),
                 source->lastError().c_str());
    // A lost device keeps what was recorded; other failures too, but exit 1.
    exit_code = 1;
    break;
  }
  if (!recorder.finish(error)) {
    std::fprintf(stderr, "epitrack-record: %s\n", error.c_str());
    return 1;
  }
  if (!quiet) {
    std::fprintf(stderr,
                 "epitrack-record: wrote %lld frames (%llu bytes) to %s, %lld corrupt skipped\n",
                 static_cast<long long>(recorder.framesWritten()),
                 static_cast<unsigned long long>(recorder.bytesWritten()), out.c_str(),
                 static_cast<long long>(corrupt));
  }
  return exit_code;
}
