#include "algo/sfm/track_table.hpp"

#include <algorithm>

namespace epitrack {

void TrackTable::add(int frame, int64_t track_id, double x, double y) {
  auto [it, inserted] = id_to_index_.try_emplace(track_id, static_cast<int32_t>(track_ids_.size()));
  if (inserted) track_ids_.push_back(track_id);
  obs_.push_back({frame, it->second, x, y});
  frame_count_ = std::max(frame_count_, frame + 1);
}

void TrackTable::setFrameCount(int frames) { frame_count_ = std::max(frame_count_, frames); }

void TrackTable::finalize() {
  // Observations are in frame order; stable sort guards callers that were not.
  std::stable_sort(
      obs_.begin(), obs_.end(),
      [](const TrackObservation& a, const TrackObservation& b) { return a.frame < b.frame; });
  frame_offset_.assign(static_cast<std::size_t>(frame_count_) + 1, 0);
  for (const auto& o : obs_) ++frame_offset_[static_cast<std::size_t>(o.frame) + 1];
  for (std::size_t f = 1; f < frame_offset_.size(); ++f) frame_offset_[f] += frame_offset_[f - 1];
  track_offset_.assign(track_ids_.size() + 1, 0);
  for (const auto& o : obs_) ++track_offset_[static_cast<std::size_t>(o.track) + 1];
  for (std::size_t t = 1; t < track_offset_.size(); ++t) track_offset_[t] += track_offset_[t - 1];
  track_obs_.assign(obs_.size(), 0);
  std::vector<int> cursor(track_offset_.begin(), track_offset_.end() - 1);
  for (std::size_t i = 0; i < obs_.size(); ++i)
    track_obs_[static_cast<std::size_t>(cursor[static_cast<std::size_t>(obs_[i].track)]++)] =
        static_cast<int>(i);
}

std::span<const TrackObservation> TrackTable::frame(int f) const {
  if (f < 0 || f >= frame_count_ || frame_offset_.empty()) return {};
  const auto b = static_cast<std::size_t>(frame_offset_[static_cast<std::size_t>(f)]);
  const auto e = static_cast<std::size_t>(frame_offset_[static_cast<std::size_t>(f) + 1]);
  return std::span<const TrackObservation>(obs_.data() + b, e - b);
}

std::span<const int> TrackTable::track(int t) const {
  const auto b = static_cast<std::size_t>(track_offset_[static_cast<std::size_t>(t)]);
  const auto e = static_cast<std::size_t>(track_offset_[static_cast<std::size_t>(t) + 1]);
  return std::span<const int>(track_obs_.data() + b, e - b);
}

const TrackObservation* TrackTable::find(int t, int f) const {
  const auto idx = track(t);
  // Observations of a track are in frame order: binary search.
  auto it = std::lower_bound(idx.begin(), idx.end(), f, [&](int i, int frame) {
    return obs_[static_cast<std::size_t>(i)].frame < frame;
  });
  if (it == idx.end() || obs_[static_cast<std::size_t>(*it)].frame != f) return nullptr;
  return &obs_[static_cast<std::size_t>(*it)];
}

}  // namespace epitrack
