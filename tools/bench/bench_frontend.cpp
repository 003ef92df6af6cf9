// epitrack-bench frontend: the whole 2D front end per frame (pyramid, LK, Kalman gate, amortized
// re-detection) at 704x576 / 300 features / 21x21 window / 3 levels by default, against OpenCV's
// goodFeaturesToTrack + calcOpticalFlowPyrLK with the same settings and re-detection policy when
// the comparison is built (-DEPITRACK_BENCH_OPENCV=ON). Both trackers' error is measured against
// the synthetic landmarks when INPUT is omitted (a rendered orbit clip).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <map>
#include <string>
#include <vector>

#include "algo/image/image.hpp"
#include "algo/tracking/feature_tracker.hpp"
#include "tools/bench/bench_input.hpp"
#include "tools/bench/bench_registry.hpp"
#include "tools/bench/opencv_tracker.hpp"
#include "tools/common/command_line.hpp"
#include "tools/synth/synthetic_sequence.hpp"

namespace epitrack::bench {
namespace {

/// Processor time of the process in milliseconds (std::clock): both trackers run single-threaded
/// on this thread, and on a shared machine processor time measures the work, not the waiting.
class CpuStopwatch {
 public:
  CpuStopwatch() : start_(std::clock()) {}
  [[nodiscard]] double ms() const {
    return 1000.0 * static_cast<double>(std::clock() - start_) /
           static_cast<double>(CLOCKS_PER_SEC);
  }

 private:
  std::clock_t start_;
};

struct Observation {
  int32_t id;
  float x;
  float y;
};

/// Error of tracks against landmarks: a track is associated with the nearest landmark within
/// 1 px of its first observation; later observations are compared with that landmark (an
/// occluded landmark counts as infinitely far).
class TrackScorer {
 public:
  explicit TrackScorer(const std::vector<std::vector<synth::LandmarkObservation>>* truth)
      : truth_(truth) {}
  void add(int frame, const std::vector<Observation>& obs) {
    if (truth_ == nullptr) return;
    const auto& lms = (*truth_)[static_cast<std::size_t>(frame)];
    std::map<int, const synth::LandmarkObservation*> by_id;
    for (const auto& l : lms) by_id[l.id] = &l;
    for (const Observation& o : obs) {
      const auto it = landmark_of_.find(o.id);
      if (it == landmark_of_.end()) {
        int best_id = -1;
        double best = 1.0;
        for (const auto& l : lms) {
          const double d =
              std::hypot(l.x - static_cast<double>(o.x), l.y - static_cast<double>(o.y));
          if (d < best) {
            best = d;
            best_id = l.id;
          }
        }
        landmark_of_[o.id] = best_id;
        continue;
      }
      if (it->second < 0) continue;
      const auto l = by_id.find(it->second);
      errors_.push_back(l == by_id.end() ? 1e9
                                         : std::hypot(l->second->x - static_cast<double>(o.x),
                                                      l->second->y - static_cast<double>(o.y)));
    }
  }
  [[nodiscard]] bool active() const { return truth_ != nullptr && !errors_.empty(); }
  JsonLine& report(JsonLine& j) const {
    if (!active()) return j;
    std::vector<double> e = errors_;
    std::sort(e.begin(), e.end());
    const double beyond =
        static_cast<double>(std::count_if(e.begin(), e.end(), [](double v) { return v > 3.0; }));
    return j.add("err_median_px", e[e.size() / 2])
        .add("err_p95_px", e[std::min(e.size() - 1, e.size() * 95 / 100)])
        .add("err_beyond_3px_pct", 100.0 * beyond / static_cast<double>(e.size()))
        .add("err_observations", e.size());
  }

 private:
  const std::vector<std::vector<synth::LandmarkObservation>>* truth_;
  std::map<int32_t, int> landmark_of_;
  std::vector<double> errors_;
};

int runFrontend(int argc, const char* const* argv) {
  std::string input;
  int repeat = 3;
  int threads = 1;
  int max_frames = 200;
  FeatureTrackerOptions o;
  tools::CommandLine cl("epitrack-bench frontend", "[INPUT] [--repeat N] [--features N] ...",
                        "Times the 2D front end per frame (pyramid, LK, Kalman gate, amortized\n"
                        "re-detection). Without INPUT, renders a 704x576 orbit and also reports\n"
                        "each tracker's error against the true landmark projections.");
  cl.positional("INPUT", "frames to use (any INPUT form); default: synthetic 704x576 orbit", &input,
                false);
  cl.integer("repeat", "N", "passes over the frames (default 3)", &repeat, 1, 1000);
  cl.integer("threads", "N", "threads (only 1: every figure is single-core)", &threads, 1, 1);
  cl.integer("max-frames", "N", "frames to load (default 200)", &max_frames, 2, 100000);
  cl.integer("features", "N", "features (default 300)", &o.max_features, 1, 10000);
  cl.integer("window", "PX", "LK window (default 21)", &o.window, 3, 99);
  cl.integer("levels", "L", "pyramid levels beyond the base (default 3)", &o.levels, 0, 7);
  cl.integer("redetect-cells", "N", "re-detect in grid cells, about N (default 0: whole frame)",
             &o.redetect_cells, 0, 10000);
  cl.integer("redetect-min-gap", "N", "frames between re-detections (default 1)",
             &o.redetect_min_gap, 1, 1000);
  if (const auto r = cl.parse(argc, argv); r != tools::CommandLine::Result::kOk)
    return tools::CommandLine::exitCode(r);

  std::vector<Image<uint8_t>> frames;
  std::vector<std::vector<synth::LandmarkObservation>> truth;
  std::string error;
  if (input.empty()) {
    synth::SynthOptions so;
    so.frames = max_frames;
    const synth::SyntheticSequence seq(so);
    synth::FrameRenderer renderer(seq);
    frames.resize(static_cast<std::size_t>(max_frames));
    truth.resize(static_cast<std::size_t>(max_frames));
    for (int i = 0; i < max_frames; ++i) {
      renderer.render(i, frames[static_cast<std::size_t>(i)]);
      seq.visibleLandmarks(i, truth[static_cast<std::size_t>(i)]);
    }
  } else if (!loadBenchFrames(input, max_frames, frames, error)) {
    std::fprintf(stderr, "epitrack-bench frontend: %s\n", error.c_str());
    return 2;  // INPUT named on the command line is unusable
  }
  const int w = frames.front().width();
  const int h = frames.front().height();
  const auto* truth_ptr = truth.empty() ? nullptr : &truth;

  // ---- epitrack
  std::vector<double> total_ms, pyr_ms, lk_ms, det_ms, det_call_ms;
  std::vector<Observation> obs;
  TrackScorer ep_score(truth_ptr);
  double live_sum = 0.0;
  long detect_calls = 0;
  long iterations = 0;
  for (int r = 0; r < repeat; ++r) {
    FeatureTracker tracker(o, w, h);
    for (std::size_t f = 0; f < frames.size(); ++f) {
      CpuStopwatch sw;
      tracker.track(frames[f].constView());
      total_ms.push_back(sw.ms());
      const FrameStats& s = tracker.lastStats();
      pyr_ms.push_back(s.pyramid_ms);
      lk_ms.push_back(s.lk_ms);
      det_ms.push_back(s.detect_ms);
      if (s.detect_ms > 0.0) {
        det_call_ms.push_back(s.detect_ms);
        ++detect_calls;
      }
      iterations += s.lk_iterations;
      live_sum += static_cast<double>(tracker.features().size());
      if (r == 0) {
        obs.clear();
        for (const auto& t : tracker.features()) obs.push_back({t.id, t.x, t.y});
        ep_score.add(static_cast<int>(f), obs);
      }
    }
  }
  const TimingStats es = summarize(total_ms);
  double det_mean = 0.0;
  for (double v : det_ms) det_mean += v;
  det_mean /= static_cast<double>(det_ms.size());
  JsonLine ej;
  ej.add("bench", "frontend")
      .add("impl", "epitrack")
      .add("clock", "process-cpu")
      .add("ms_median", es.median)
      .add("ms_mean", es.mean)
      .add("ms_p95", es.p95)
      .add("frames", frames.size())
      .add("features", o.max_features)
      .add("width", w)
      .add("height", h)
      .add("window", o.window)
      .add("levels", o.levels)
      .add("live_mean", live_sum / static_cast<double>(total_ms.size()))
      .add("pyramid_ms_median", summarize(pyr_ms).median)
      .add("lk_ms_median", summarize(lk_ms).median)
      .add("detect_ms_per_call_median", summarize(det_call_ms).median)
      .add("detect_ms_amortized", det_mean)
      .add("detect_calls_per_100_frames",
           100.0 * static_cast<double>(detect_calls) / static_cast<double>(total_ms.size()))
      .add("lk_iterations_per_frame",
           static_cast<double>(iterations) / static_cast<double>(total_ms.size()));
  ep_score.report(ej).print();

#ifdef EPITRACK_HAVE_OPENCV
  cv::setNumThreads(1);
  std::vector<double> cv_ms, cv_lk_ms, cv_det_call_ms;
  TrackScorer cv_score(truth_ptr);
  for (int r = 0; r < repeat; ++r) {
    OpenCvTracker cv_tracker(w, h, o);
    for (std::size_t f = 0; f < frames.size(); ++f) {
      const cv::Mat img = OpenCvTracker::wrap(frames[f]);
      CpuStopwatch sw;
      cv_tracker.flow(img);
      cv_lk_ms.push_back(sw.ms());
      CpuStopwatch ds;
      if (cv_tracker.redetect(img)) cv_det_call_ms.push_back(ds.ms());
      cv_tracker.endFrame();
      cv_ms.push_back(sw.ms());
      if (r == 0) {
        obs.clear();
        const auto& pts = cv_tracker.points();
        const auto& ids = cv_tracker.ids();
        for (std::size_t i = 0; i < pts.size(); ++i) obs.push_back({ids[i], pts[i].x, pts[i].y});
        cv_score.add(static_cast<int>(f), obs);
      }
    }
  }
  const TimingStats cs = summarize(cv_ms);
  JsonLine cj;
  cj.add("bench", "frontend")
      .add("impl", "opencv")
      .add("clock", "process-cpu")
      .add("ms_median", cs.median)
      .add("ms_mean", cs.mean)
      .add("ms_p95", cs.p95)
      .add("frames", frames.size())
      .add("features", o.max_features)
      .add("pyramid_lk_ms_median", summarize(cv_lk_ms).median)
      .add("detect_ms_per_call_median", summarize(cv_det_call_ms).median)
      .add("detect_calls_per_100_frames",
           100.0 * static_cast<double>(cv_det_call_ms.size()) / static_cast<double>(cv_ms.size()));
  cv_score.report(cj).print();
  JsonLine()
      .add("bench", "frontend")
      .add("impl", "ratio")
      .add("ratio", cs.median / es.median)
      .add("ratio_mean", cs.mean / es.mean)
      .print();
#endif
  return 0;
}

const BenchRegistrar kRegister("frontend",
                               "2D front end per frame: pyramid, LK, Kalman gate, re-detection",
                               runFrontend);

}  // namespace
}  // namespace epitrack::bench
