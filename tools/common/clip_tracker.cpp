#include "tools/common/clip_tracker.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace epitrack::tools {

namespace {

uint8_t grayAt(ImageView<const uint8_t> img, double x, double y) {
  const int ix = std::clamp(static_cast<int>(std::lround(x)), 0, img.width - 1);
  const int iy = std::clamp(static_cast<int>(std::lround(y)), 0, img.height - 1);
  return img(ix, iy);
}

}  // namespace

const char* matcherName(Matcher m) {
  switch (m) {
    case Matcher::kLk:
      return "lk";
    case Matcher::kDescriptors:
      return "descriptors";
    case Matcher::kAuto:
      return "auto";
  }
  return "unknown";
}

bool parseMatcher(const std::string& text, Matcher& m) {
  for (const Matcher c : {Matcher::kLk, Matcher::kDescriptors, Matcher::kAuto}) {
    if (text == matcherName(c)) {
      m = c;
      return true;
    }
  }
  return false;
}

bool parseMatchWindow(const std::string& text, int& window, std::string& error) {
  if (text == "auto") {
    window = kMatchWindowAuto;
    return true;
  }
  if (text == "all") {
    window = DescriptorTrackerOptions::kAllPairs;
    return true;
  }
  char* end = nullptr;
  const long v = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || end == nullptr || *end != '\0' || v < 1 || v > 50) {
    error = "expected auto, all or a number of frames 1-50, got '" + text + "'";
    return false;
  }
  window = static_cast<int>(v);
  return true;
}

int resolveMatchWindow(int window, long expected_frames) {
  if (window != kMatchWindowAuto) return window;
  return expected_frames > 1 && expected_frames <= kAllPairsMaxFrames
             ? DescriptorTrackerOptions::kAllPairs
             : kChainMatchWindow;
}

double trackSurvival(const TrackTable& table, int frames, double* lowest_after_first) {
  std::vector<double> survival;
  for (int f = 0; f + 1 < std::min(frames, table.frameCount()); ++f) {
    const auto obs = table.frame(f);
    if (obs.empty()) {
      survival.push_back(0.0);
      continue;
    }
    int kept = 0;
    for (const auto& o : obs) kept += table.find(o.track, f + 1) != nullptr ? 1 : 0;
    survival.push_back(static_cast<double>(kept) / static_cast<double>(obs.size()));
  }
  if (lowest_after_first != nullptr)
    *lowest_after_first =
        survival.size() > 1 ? *std::min_element(survival.begin() + 1, survival.end()) : 1.0;
  if (survival.empty()) return 1.0;
  std::sort(survival.begin(), survival.end());
  const std::size_t n = survival.size();
  return n % 2 == 1 ? survival[n / 2] : 0.5 * (survival[n / 2 - 1] + survival[n / 2]);
}

ClipTracker::ClipTracker(Matcher matcher, const FeatureTrackerOptions& lk,
                         const DescriptorTrackerOptions& descriptors, int width, int height,
                         int expected_frames, const MatcherProbeOptions& probe)
    : requested_(matcher),
      chosen_(matcher),
      lk_options_(lk),
      descriptor_options_(descriptors),
      probe_(probe),
      width_(width),
      height_(height),
      expected_frames_(std::max(1, expected_frames)) {
  descriptor_options_.window = resolveMatchWindow(descriptors.window, expected_frames);
  if (matcher == Matcher::kDescriptors) {
    descriptors_ =
        std::make_unique<DescriptorTracker>(descriptor_options_, width_, height_, expected_frames_);
    decision_ = "descriptors (--matcher descriptors)";
  } else {
    lk_ = std::make_unique<FeatureTracker>(lk_options_, width_, height_);
    rows_.reserve(static_cast<std::size_t>(expected_frames_) *
                  static_cast<std::size_t>(std::max(1, lk_options_.max_features)));
    if (matcher == Matcher::kLk) decision_ = "lk (--matcher lk)";
  }
}

ClipTracker::~ClipTracker() = default;

void ClipTracker::trackLk(ImageView<const uint8_t> luma, ImageView<const uint8_t> mask) {
  const auto live = lk_->features();
  for (const auto& f : live) {
    rows_.push_back(Row{frames_, f.id, f.x, f.y});
    lk_gray_.try_emplace(f.id, grayAt(luma, static_cast<double>(f.x), static_cast<double>(f.y)));
  }
  lk_live_.push_back(static_cast<int>(live.size()));
  (void)mask;
}

void ClipTracker::trackDescriptors(ImageView<const uint8_t> luma, ImageView<const uint8_t> mask) {
  descriptors_->addFrame(luma, mask);
  for (const auto& k : descriptors_->keypoints(descriptors_->frameCount() - 1))
    keypoint_gray_.push_back(grayAt(luma, static_cast<double>(k.x), static_cast<double>(k.y)));
}

ClipTracker::Status ClipTracker::track(ImageView<const uint8_t> luma,
                                       ImageView<const uint8_t> mask) {
  if (luma.width != width_ || luma.height != height_) return Status::kSizeMismatch;
  if (chosen_ == Matcher::kDescriptors) {
    trackDescriptors(luma, mask);
    ++frames_;
    return Status::kOk;
  }
  if (lk_->track(luma, mask) != FeatureTracker::Status::kOk) return Status::kSizeMismatch;
  trackLk(luma, mask);
  ++frames_;
  if (chosen_ == Matcher::kAuto) {
    kept_frames_.emplace_back(width_, height_);
    copyPixels<uint8_t>(luma, kept_frames_.back().view());
    kept_masks_.emplace_back();
    if (!mask.empty()) {
      kept_masks_.back().allocate(mask.width, mask.height);
      copyPixels<uint8_t>(mask, kept_masks_.back().view());
    }
    if (frames_ >= probe_.probe_frames) decide();
  }
  return Status::kOk;
}

void ClipTracker::skipFrames(int n) {
  if (lk_) lk_->skipFrames(n);
}

int ClipTracker::liveFeatures() const {
  if (chosen_ == Matcher::kDescriptors)
    return descriptors_->frameCount() > 0
               ? static_cast<int>(descriptors_->keypoints(descriptors_->frameCount() - 1).size())
               : 0;
  return static_cast<int>(lk_->features().size());
}

void ClipTracker::decide() {
  // LK's tracks over the probe.
  TrackTable probe;
  probe.reserve(frames_, rows_.size());
  for (const Row& r : rows_)
    probe.add(r.frame, r.id, static_cast<double>(r.x), static_cast<double>(r.y));
  probe.setFrameCount(frames_);
  probe.finalize();
  double lowest = 1.0;
  const double survival = trackSurvival(probe, frames_, &lowest);
  char line[240];
  if (survival >= probe_.min_survival && lowest >= probe_.min_pair_survival) {
    chosen_ = Matcher::kLk;
    std::snprintf(line, sizeof(line),
                  "lk (auto: %.0f %% of the LK tracks survive from frame to frame over the first "
                  "%d frames, video)",
                  100.0 * survival, frames_);
  } else {
    chosen_ = Matcher::kDescriptors;
    if (survival < probe_.min_survival)
      std::snprintf(line, sizeof(line),
                    "descriptors (auto: only %.0f %% of the LK tracks survive from frame to frame "
                    "over the first %d frames, below %.0f %%: key frames)",
                    100.0 * survival, frames_, 100.0 * probe_.min_survival);
    else
      std::snprintf(line, sizeof(line),
                    "descriptors (auto: a frame pair among the first %d frames keeps only %.0f %% "
                    "of its LK tracks, below %.0f %%: a cut in the file order, a photo set)",
                    frames_, 100.0 * lowest, 100.0 * probe_.min_pair_survival);
    descriptors_ =
        std::make_unique<DescriptorTracker>(descriptor_options_, width_, height_, expected_frames_);
    for (std::size_t i = 0; i < kept_frames_.size(); ++i)
      trackDescriptors(kept_frames_[i].constView(), kept_masks_[i].constView());
    lk_.reset();
    rows_.clear();
    rows_.shrink_to_fit();
    lk_live_.clear();
    lk_gray_.clear();
  }
  decision_ = line;
  kept_frames_.clear();
  kept_masks_.clear();
}

void ClipTracker::finish(TrackTable& table, std::vector<int>& features_per_frame,
                         std::unordered_map<int64_t, uint8_t>& first_gray) {
  if (chosen_ == Matcher::kAuto) decide();  // a clip shorter than the probe
  features_per_frame.assign(static_cast<std::size_t>(frames_), 0);
  if (chosen_ == Matcher::kLk) {
    table.reserve(frames_, rows_.size());
    for (const Row& r : rows_)
      table.add(r.frame, r.id, static_cast<double>(r.x), static_cast<double>(r.y));
    table.setFrameCount(frames_);
    table.finalize();
    for (int f = 0; f < frames_ && f < static_cast<int>(lk_live_.size()); ++f)
      features_per_frame[static_cast<std::size_t>(f)] = lk_live_[static_cast<std::size_t>(f)];
    first_gray = lk_gray_;
    return;
  }
  descriptors_->buildTracks(table);
  std::size_t node = 0;
  for (int f = 0; f < descriptors_->frameCount(); ++f) {
    const int n = static_cast<int>(descriptors_->keypoints(f).size());
    for (int i = 0; i < n; ++i, ++node) {
      const int t = descriptors_->trackOf(f, i);
      if (t < 0) continue;
      ++features_per_frame[static_cast<std::size_t>(f)];
      if (node < keypoint_gray_.size()) first_gray.try_emplace(t, keypoint_gray_[node]);
    }
  }
}

}  // namespace epitrack::tools
