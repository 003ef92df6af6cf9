// epitrack-bench pyramid: image pyramid build time per frame (and Scharr gradients of the base),
// against OpenCV's buildOpticalFlowPyramid / pyrDown when the comparison is built.
#include <string>
#include <vector>

#include "algo/image/image.hpp"
#include "algo/image/pyramid.hpp"
#include "algo/image/scharr.hpp"
#include "hal/frame_source.hpp"
#include "tools/bench/bench_input.hpp"
#include "tools/bench/bench_registry.hpp"
#include "tools/common/command_line.hpp"

#ifdef EPITRACK_HAVE_OPENCV
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#endif

namespace epitrack::bench {
namespace {

int runPyramid(int argc, const char* const* argv) {
  std::string input;
  int repeat = 5;
  int threads = 1;
  int levels = 4;
  int max_frames = 100;
  tools::CommandLine cl(
      "epitrack-bench pyramid", "[INPUT] [--repeat N] [--levels L]",
      "Times building a pyramid (and Scharr gradients of the base) per frame. Without INPUT,\n"
      "renders a 704x576 synthetic orbit clip in memory.");
  cl.positional("INPUT", "frames to use (any INPUT form); default: synthetic 704x576", &input,
                false);
  cl.integer("repeat", "N", "passes over the frames (default 5)", &repeat, 1, 1000);
  cl.integer("threads", "N", "threads (only 1 is supported: every figure is single-core)", &threads,
             1, 1);
  cl.integer("levels", "L", "pyramid levels including the base (default 4)", &levels, 1,
             Pyramid::kMaxLevels);
  cl.integer("max-frames", "N", "frames to load (default 100)", &max_frames, 1, 100000);
  if (const auto r = cl.parse(argc, argv); r != tools::CommandLine::Result::kOk)
    return tools::CommandLine::exitCode(r);
  std::vector<Image<uint8_t>> frames;
  std::string error;
  if (!loadBenchFrames(input, max_frames, frames, error)) {
    std::fprintf(stderr, "epitrack-bench pyramid: %s\n", error.c_str());
    return 2;  // INPUT named on the command line is unusable
  }
  const int w = frames.front().width();
  const int h = frames.front().height();
  Pyramid pyr(w, h, levels);
  Image<int16_t> dx(w, h);
  Image<int16_t> dy(w, h);
  std::vector<double> pyr_ms;
  std::vector<double> grad_ms;
  for (int r = 0; r < repeat; ++r) {
    for (const auto& f : frames) {
      Stopwatch sw;
      pyr.build(f.constView());
      pyr_ms.push_back(sw.ms());
      sw.restart();
      scharrGradients(pyr.level(0), dx.view(), dy.view());
      grad_ms.push_back(sw.ms());
    }
  }
  const TimingStats ps = summarize(pyr_ms);
  const TimingStats gs = summarize(grad_ms);
  JsonLine()
      .add("bench", "pyramid")
      .add("impl", "epitrack")
      .add("ms_median", ps.median)
      .add("ms_mean", ps.mean)
      .add("ms_p95", ps.p95)
      .add("frames", frames.size())
      .add("width", w)
      .add("height", h)
      .add("levels", levels)
      .timing("scharr_ms", gs)
      .print();
#ifdef EPITRACK_HAVE_OPENCV
  cv::setNumThreads(1);
  std::vector<cv::Mat> cv_pyr(static_cast<std::size_t>(levels));
  std::vector<double> cv_ms;
  std::vector<double> cv_grad_ms;
  cv::Mat cdx;
  cv::Mat cdy;
  for (int r = 0; r < repeat; ++r) {
    for (const auto& f : frames) {
      const cv::Mat src(h, w, CV_8UC1, const_cast<uint8_t*>(f.row(0)),
                        static_cast<std::size_t>(f.stride()));
      Stopwatch sw;
      src.copyTo(cv_pyr[0]);  // epitrack copies the base too
      for (int l = 1; l < levels; ++l)
        cv::pyrDown(cv_pyr[static_cast<std::size_t>(l - 1)], cv_pyr[static_cast<std::size_t>(l)]);
      cv_ms.push_back(sw.ms());
      sw.restart();
      cv::Scharr(cv_pyr[0], cdx, CV_16S, 1, 0);
      cv::Scharr(cv_pyr[0], cdy, CV_16S, 0, 1);
      cv_grad_ms.push_back(sw.ms());
    }
  }
  const TimingStats cs = summarize(cv_ms);
  const TimingStats cg = summarize(cv_grad_ms);
  JsonLine()
      .add("bench", "pyramid")
      .add("impl", "opencv")
      .add("ms_median", cs.median)
      .add("ms_mean", cs.mean)
      .add("ms_p95", cs.p95)
      .add("frames", frames.size())
      .timing("scharr_ms", cg)
      .print();
  JsonLine()
      .add("bench", "pyramid")
      .add("impl", "ratio")
      .add("ratio", cs.median / ps.median)
      .add("scharr_ratio", cg.median / gs.median)
      .print();
#endif
  return 0;
}

const BenchRegistrar kRegister("pyramid", "image pyramid build and Scharr gradients per frame",
                               runPyramid);

}  // namespace
}  // namespace epitrack::bench
