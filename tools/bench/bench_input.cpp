#include "tools/bench/bench_input.hpp"

#include "hal/frame_source.hpp"
#include "tools/synth/synthetic_sequence.hpp"

namespace epitrack::bench {

bool loadBenchFrames(const std::string& input, int max_frames, std::vector<Image<uint8_t>>& frames,
                     std::string& error) {
  frames.clear();
  if (input.empty()) {
    synth::SynthOptions o;
    o.frames = max_frames;
    o.target_wander = 0.5;
    const synth::SyntheticSequence seq(o);
    synth::FrameRenderer r(seq);
    for (int i = 0; i < max_frames; ++i) {
      frames.emplace_back();
      r.render(i, frames.back());
    }
    return true;
  }
  auto src = hal::openFrameSource(input, {}, error);
  if (!src) return false;
  hal::Frame f;
  while (static_cast<int>(frames.size()) < max_frames) {
    const hal::FrameStatus s = src->next(f);
    if (s == hal::FrameStatus::kEndOfStream) break;
    if (s == hal::FrameStatus::kCorruptFrame) continue;
    if (s != hal::FrameStatus::kOk) {
      error = src->lastError();
      return false;
    }
    frames.emplace_back(f.luma.width, f.luma.height);
    copyPixels(f.luma, frames.back().view());
  }
  if (frames.empty()) {
    error = "no frames in '" + input + "'";
    return false;
  }
  return true;
}

TrackTable trackFrames(const std::vector<Image<uint8_t>>& frames,
                       const FeatureTrackerOptions& options) {
  FeatureTracker tracker(options, frames.front().width(), frames.front().height());
  TrackTable tracks;
  tracks.reserve(static_cast<int>(frames.size()),
                 frames.size() * static_cast<std::size_t>(options.max_features));
  for (std::size_t f = 0; f < frames.size(); ++f) {
    tracker.track(frames[f].constView());
    for (const auto& ft : tracker.features()) tracks.add(static_cast<int>(f), ft.id, ft.x, ft.y);
  }
  tracks.setFrameCount(static_cast<int>(frames.size()));
  tracks.finalize();
  return tracks;
}

}  // namespace epitrack::bench
