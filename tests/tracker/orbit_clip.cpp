#include "tests/tracker/orbit_clip.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <set>

#include "tests/support/well_conditioned.hpp"
#include "tools/synth/random.hpp"

namespace epitrack::test {

RenderedClip renderClip(const synth::SynthOptions& options) {
  RenderedClip clip;
  const synth::SyntheticSequence seq(options);
  synth::FrameRenderer renderer(seq);
  clip.frames.resize(static_cast<std::size_t>(options.frames));
  clip.landmarks.resize(static_cast<std::size_t>(options.frames));
  clip.well_conditioned.resize(static_cast<std::size_t>(options.frames));
  for (int f = 0; f < options.frames; ++f) {
    renderer.render(f, clip.frames[static_cast<std::size_t>(f)]);
    const auto& lms = clip.landmarks[static_cast<std::size_t>(f)];
    seq.visibleLandmarks(f, clip.landmarks[static_cast<std::size_t>(f)]);
    auto& wc = clip.well_conditioned[static_cast<std::size_t>(f)];
    for (const auto& l : lms)
      wc.push_back(
          wellConditioned(seq, seq.scene().landmarks[static_cast<std::size_t>(l.id)], f) ? 1 : 0);
  }
  return clip;
}

const RenderedClip& orbitClip() {
  static const RenderedClip clip = [] {
    synth::SynthOptions o;
    o.kind = synth::SceneKind::kOrbit;
    o.frames = 340;
    o.width = 704;
    o.height = 576;
    o.focal = 600.0;
    o.seed = 1;
    return renderClip(o);
  }();
  return clip;
}

RenderedClip addNoise(const RenderedClip& clip, double sigma, uint64_t seed) {
  RenderedClip out;
  // GCC 12 for aarch64 reports a false -Wnull-dereference inside the inlined vector copy.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wnull-dereference"
  out.landmarks = clip.landmarks;
#pragma GCC diagnostic pop
  out.well_conditioned = clip.well_conditioned;
  out.frames.resize(clip.frames.size());
  for (std::size_t f = 0; f < clip.frames.size(); ++f) {
    const Image<uint8_t>& src = clip.frames[f];
    Image<uint8_t>& dst = out.frames[f];
    dst.allocate(src.width(), src.height());
    synth::SplitMix64 rng(synth::mixSeed(seed, f));
    for (int y = 0; y < src.height(); ++y) {
      for (int x = 0; x < src.width(); ++x) {
        const double v = src(x, y) + sigma * rng.gaussian();
        dst(x, y) = static_cast<uint8_t>(std::clamp(std::lround(v), 0L, 255L));
      }
    }
  }
  return out;
}

double percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const auto i = static_cast<std::size_t>(std::clamp(q * static_cast<double>(values.size() - 1),
                                                     0.0, static_cast<double>(values.size() - 1)));
  return values[i];
}

TrackAccuracy measureTracker(const RenderedClip& clip, const FeatureTrackerOptions& options,
                             int max_frames, double associate_px) {
  TrackAccuracy acc;
  const int frames = std::min(max_frames, static_cast<int>(clip.frames.size()));
  if (frames == 0) return acc;
  FeatureTracker tracker(options, clip.frames[0].width(), clip.frames[0].height());
  struct TrackInfo {
    int landmark = -1;  // -1: unassociated
    double off_x = 0.0;
    double off_y = 0.0;
    int birth = 0;
  };
  std::map<int32_t, TrackInfo> info;
  // Landmarks visible in every frame 0..100 (for survival).
  std::set<int> visible_through_100;
  if (frames > 100) {
    for (const auto& l : clip.landmarks[0]) visible_through_100.insert(l.id);
    for (int f = 1; f <= 100; ++f) {
      std::set<int> now;
      for (const auto& l : clip.landmarks[static_cast<std::size_t>(f)]) {
        if (visible_through_100.count(l.id) != 0) now.insert(l.id);
      }
      visible_through_100.swap(now);
    }
  }
  double total_ms = 0.0;
  for (int f = 0; f < frames; ++f) {
    const auto t0 = std::chrono::steady_clock::now();
    tracker.track(clip.frames[static_cast<std::size_t>(f)].constView());
    total_ms +=
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    const auto& lms = clip.landmarks[static_cast<std::size_t>(f)];
    std::map<int, const synth::LandmarkObservation*> by_id;
    for (const auto& l : lms) by_id[l.id] = &l;
    for (const TrackedFeature& t : tracker.features()) {
      auto it = info.find(t.id);
      if (it == info.end()) {
        TrackInfo ti;
        ti.birth = f;
        double best = associate_px * associate_px;
        for (const auto& l : lms) {
          const double tx = t.x, ty = t.y;
          const double d2 = (l.x - tx) * (l.x - tx) + (l.y - ty) * (l.y - ty);
          if (d2 <= best) {
            best = d2;
            ti.landmark = l.id;
            ti.off_x = static_cast<double>(t.x) - l.x;
            ti.off_y = static_cast<double>(t.y) - l.y;
          }
        }
        if (ti.landmark >= 0) {
          ++acc.associated_tracks;
        } else {
          ++acc.unassociated_tracks;
        }
        info[t.id] = ti;
        continue;
      }
      const TrackInfo& ti = it->second;
      if (ti.landmark < 0) continue;
      ++acc.observations;
      const auto lit = by_id.find(ti.landmark);
      if (lit == by_id.end()) {
        ++acc.occluded_observations;
        acc.errors.push_back(std::numeric_limits<double>::infinity());
        continue;
      }
      const double ex = static_cast<double>(t.x) - lit->second->x;
      const double ey = static_cast<double>(t.y) - lit->second->y;
      acc.errors.push_back(std::hypot(ex, ey));
      if (f == 100 && ti.birth == 0) {
        acc.drift_at_100.push_back(std::hypot(ex - ti.off_x, ey - ti.off_y));
        if (visible_through_100.count(ti.landmark) != 0) ++acc.survived_100;
      }
    }
  }
  if (frames > 100) {
    for (const auto& [id, ti] : info) {
      if (ti.birth == 0 && ti.landmark >= 0 && visible_through_100.count(ti.landmark) != 0) {
        ++acc.visible_100;
      }
    }
  }
  acc.median = percentile(acc.errors, 0.5);
  acc.p95 = percentile(acc.errors, 0.95);
  const auto beyond =
      std::count_if(acc.errors.begin(), acc.errors.end(), [](double e) { return e > 3.0; });
  acc.fraction_beyond_3px =
      acc.errors.empty() ? 0.0
                         : static_cast<double>(beyond) / static_cast<double>(acc.errors.size());
  acc.drift_median_100 = percentile(acc.drift_at_100, 0.5);
  acc.mean_ms = total_ms / frames;
  return acc;
}

}  // namespace epitrack::test
