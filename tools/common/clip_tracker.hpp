#pragma once

// The 2D tracks of a whole clip for epitrack-solve and epitrack-track (`--matcher`): pyramidal LK
// (FeatureTracker, video), descriptor matching (DescriptorTracker, key frames), or the one the
// first frames call for (auto).

#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "algo/image/image.hpp"
#include "algo/matching/descriptor_tracker.hpp"
#include "algo/sfm/track_table.hpp"
#include "algo/tracking/feature_tracker.hpp"

namespace epitrack::tools {

enum class Matcher { kLk, kDescriptors, kAuto };

/// LK features the offline solve (epitrack-solve, epitrack-bench solve) tracks by default: twice
/// the live tracker's 300. An offline solve has time for more tracks, and every real sequence and
/// rendered clip gains from them (README, "The 3D solver": templeRing 12-30 0.130 -> 0.083 %,
/// KITTI highway 1.35 -> 1.15 %, the rendered orbit 0.0051 -> 0.0031 %) at about 1.7x the time.
inline constexpr int kSolveFeatures = 600;

/// --match-window: `auto` resolves to every pair (DescriptorTrackerOptions::kAllPairs) for a
/// clip of at most kAllPairsMaxFrames frames, to the previous kChainMatchWindow frames otherwise.
/// 47 views matched pair by pair take 40 s here (docs/tracker.md, "The view graph"); the pairs
/// grow with the square of the frames.
inline constexpr int kMatchWindowAuto = -1;
inline constexpr int kAllPairsMaxFrames = 60;
inline constexpr int kChainMatchWindow = 2;

/// "auto", "all" or a number of previous frames (1-50) into `window`; false with `error` set.
bool parseMatchWindow(const std::string& text, int& window, std::string& error);
/// The window the descriptor tracker uses for a clip of `expected_frames` frames (<= 1: unknown).
int resolveMatchWindow(int window, long expected_frames);

/// "lk", "descriptors", "auto".
const char* matcherName(Matcher m);
bool parseMatcher(const std::string& text, Matcher& m);

/// How `auto` decides, from LK run over the first `probe_frames` frames: the survival of a frame
/// pair is the fraction of the tracks live in the first frame that are still live in the second;
/// descriptors when the median survival over the probe's pairs is below `min_survival`. Video
/// keeps 60-100 % of its tracks from frame to frame (KITTI at 10 Hz and 1-2 m per frame: 55-65 %;
/// the rendered clips: 95-100 %); key frames that LK cannot bridge keep almost none (TUM cabinet
/// key frames: 8-18 %).
///
/// A photo set can keep most of its LK tracks from one file to the next and still not be a path:
/// the 47 templeRing views keep 65-73 % over views 0-4 (median over the first 16 frames 53 %) but
/// only 21 % and 14 % across the jumps between views 4-5 and 11-12 (0.4-1.1 m, the ring's order
/// is not the files'); video keeps its overlap (KITTI 54-76 % after its first pair, whose freshly
/// detected road corners die at once: 25 %). So a pair after the first that keeps fewer than
/// `min_pair_survival` of its tracks (a cut in the file order) also picks descriptors, whose
/// view graph matches every pair.
struct MatcherProbeOptions {
  int probe_frames = 16;
  double min_survival = 0.35;
  double min_pair_survival = 0.3;
};

/// Frame-to-frame survival (see MatcherProbeOptions) of the tracks in `table` over its frames
/// [0, frames): the median over every pair, and the lowest over the pairs after the first (1
/// when there is no such pair). The median is 1 when there is no pair.
double trackSurvival(const TrackTable& table, int frames, double* lowest_after_first = nullptr);

/// Tracks a clip frame by frame with the chosen matcher. In auto mode LK runs from the first
/// frame and the first probe_frames frames are kept (with their masks); once they are tracked
/// the survival decides: LK goes on unchanged (its results are those of `lk`), or the kept frames
/// are replayed into the descriptor tracker, which takes the rest of the clip.
class ClipTracker {
 public:
  enum class Status { kOk, kSizeMismatch };

  ClipTracker(Matcher matcher, const FeatureTrackerOptions& lk,
              const DescriptorTrackerOptions& descriptors, int width, int height,
              int expected_frames, const MatcherProbeOptions& probe = {});
  ~ClipTracker();
  ClipTracker(const ClipTracker&) = delete;
  ClipTracker& operator=(const ClipTracker&) = delete;

  /// The next frame (frames are numbered from 0 in the order given).
  Status track(ImageView<const uint8_t> luma, ImageView<const uint8_t> mask);
  /// Frames lost in the input (LK's motion model skips them; descriptors need nothing).
  void skipFrames(int n);
  /// Features after the last frame: LK's live tracks, or the descriptor tracker's keypoints.
  [[nodiscard]] int liveFeatures() const;

  /// Ends the clip: every track into `table` (setFrameCount and finalize done), the features per
  /// frame (LK: live tracks; descriptors: observations of tracks), and each track's gray value
  /// at its first observation (for point colours).
  void finish(TrackTable& table, std::vector<int>& features_per_frame,
              std::unordered_map<int64_t, uint8_t>& first_gray);

  /// kLk or kDescriptors once decided (auto: kAuto until the probe ends).
  [[nodiscard]] Matcher chosen() const { return chosen_; }
  /// One line on what was chosen and why ("" before the decision).
  [[nodiscard]] const std::string& decision() const { return decision_; }
  /// The LK tracker while it runs (its frame statistics), else nullptr.
  [[nodiscard]] const FeatureTracker* lkTracker() const { return lk_.get(); }
  /// The descriptor tracker when chosen (its pair statistics), else nullptr.
  [[nodiscard]] const DescriptorTracker* descriptorTracker() const { return descriptors_.get(); }

 private:
  struct Row {
    int frame;
    int64_t id;
    float x, y;
  };
  void trackLk(ImageView<const uint8_t> luma, ImageView<const uint8_t> mask);
  void trackDescriptors(ImageView<const uint8_t> luma, ImageView<const uint8_t> mask);
  void decide();

  Matcher requested_;
  Matcher chosen_;
  FeatureTrackerOptions lk_options_;
  DescriptorTrackerOptions descriptor_options_;
  MatcherProbeOptions probe_;
  int width_, height_, expected_frames_;
  int frames_ = 0;
  std::unique_ptr<FeatureTracker> lk_;
  std::unique_ptr<DescriptorTracker> descriptors_;
  std::vector<Row> rows_;               // LK observations
  std::vector<int> lk_live_;            // LK live tracks per frame
  std::vector<uint8_t> keypoint_gray_;  // descriptors: gray of every keypoint, frame by frame
  std::unordered_map<int64_t, uint8_t> lk_gray_;
  std::vector<Image<uint8_t>> kept_frames_, kept_masks_;  // auto: the probe's frames
  std::string decision_;
};

}  // namespace epitrack::tools
