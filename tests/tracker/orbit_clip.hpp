#pragma once

// A rendered synthetic clip with its ground truth, shared by the TEST_CASEs of one process
// (rendering the 340-frame 704x576 orbit takes seconds; it is done once, on first use), and the
// accuracy measures of a tracker run against the true landmark projections.

#include <cstdint>
#include <map>
#include <vector>

#include "algo/image/image.hpp"
#include "algo/tracking/feature_tracker.hpp"
#include "tools/synth/synthetic_sequence.hpp"

namespace epitrack::test {

struct RenderedClip {
  std::vector<Image<uint8_t>> frames;
  std::vector<std::vector<synth::LandmarkObservation>> landmarks;  // per frame
  /// Per frame, parallel to `landmarks`: 1 when the corner is well conditioned for sub-pixel
  /// localisation (its texture cells span >= 9 px on screen, its edges >= 45 degrees apart).
  std::vector<std::vector<uint8_t>> well_conditioned;
};

/// Renders `options` (all frames) with its landmarks.
RenderedClip renderClip(const synth::SynthOptions& options);

/// The 340-frame 704x576 noise-free orbit (focal 600, seed 1), rendered once per process.
const RenderedClip& orbitClip();

/// A copy of `clip` with seeded Gaussian noise of `sigma` gray levels added (clamped, rounded).
RenderedClip addNoise(const RenderedClip& clip, double sigma, uint64_t seed);

/// Accuracy of a tracker run against the landmarks. A track is associated with the nearest
/// landmark within `associate_px` of its first observation; afterwards each live observation is
/// compared with that landmark's true projection. An observation whose landmark is no longer
/// visible (occluded) counts as off by infinity.
struct TrackAccuracy {
  std::vector<double> errors;        // every associated live observation after the first
  std::vector<double> drift_at_100;  // |(p_k - l_k) - (p_0 - l_0)| at frame 100, tracks born at 0
  int observations = 0;
  int associated_tracks = 0;
  int unassociated_tracks = 0;
  int occluded_observations = 0;
  int visible_100 = 0;   // tracks born at frame 0 whose landmark stays visible through frame 100
  int survived_100 = 0;  // ... of which still alive at frame 100
  double median = 0.0;
  double p95 = 0.0;
  double fraction_beyond_3px = 0.0;
  double drift_median_100 = 0.0;
  double mean_ms = 0.0;
};

/// Runs a FeatureTracker over `clip` (at most `max_frames`) and measures it.
TrackAccuracy measureTracker(const RenderedClip& clip, const FeatureTrackerOptions& options,
                             int max_frames = 1 << 30, double associate_px = 1.0);

double percentile(std::vector<double> values, double q);

}  // namespace epitrack::test
