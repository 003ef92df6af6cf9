#pragma once

#include <cstdint>
#include <span>
#include <unordered_map>
#include <vector>

namespace epitrack {

/// One 2D observation of a track in a frame (pixel coordinates).
struct TrackObservation {
  int32_t frame = 0;
  int32_t track = 0;  ///< dense track index (see TrackTable::trackId for the original id)
  double x = 0.0;
  double y = 0.0;
};

/// The 2D tracks of a whole clip, the solver's input: observations grouped by frame (in the order
/// added) and, after `finalize`, by track. Original track ids (tracks.csv, FeatureTracker ids) are
/// mapped to dense indices. Capacity is reserved up front from the clip length and feature count.
class TrackTable {
 public:
  void reserve(int frames, std::size_t observations) {
    frame_offset_.reserve(static_cast<std::size_t>(frames) + 1);
    obs_.reserve(observations);
  }
  /// Appends one observation; frames must be added in non-decreasing order.
  void add(int frame, int64_t track_id, double x, double y);
  /// Declares the clip length (frames without observations count too).
  void setFrameCount(int frames);
  /// Builds the per-track index; call once after the last `add`.
  void finalize();

  [[nodiscard]] int frameCount() const { return frame_count_; }
  [[nodiscard]] int trackCount() const { return static_cast<int>(track_ids_.size()); }
  [[nodiscard]] std::span<const TrackObservation> frame(int f) const;
  /// Indices into `observations()` of track t, by frame.
  [[nodiscard]] std::span<const int> track(int t) const;
  [[nodiscard]] std::span<const TrackObservation> observations() const { return obs_; }
  [[nodiscard]] int64_t trackId(int t) const { return track_ids_[static_cast<std::size_t>(t)]; }
  /// The observation of track t in frame f, or nullptr.
  [[nodiscard]] const TrackObservation* find(int t, int f) const;

 private:
  std::vector<TrackObservation> obs_;
  std::vector<int> frame_offset_;  // obs_ of frame f: [frame_offset_[f], frame_offset_[f+1])
  std::vector<int> track_offset_, track_obs_;
  std::vector<int64_t> track_ids_;
  std::unordered_map<int64_t, int32_t> id_to_index_;
  int frame_count_ = 0;
};

}  // namespace epitrack
