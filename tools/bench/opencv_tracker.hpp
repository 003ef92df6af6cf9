#pragma once

// The OpenCV 2D tracking path the benchmarks compare with (bench_frontend.cpp, bench_solve.cpp):
// buildOpticalFlowPyramid + calcOpticalFlowPyrLK with the same window and levels as epitrack,
// tracks dropped when LK fails or they leave the image, goodFeaturesToTrack away from live tracks
// when they fall below the same re-detection fraction. Only with -DEPITRACK_BENCH_OPENCV=ON.

#ifdef EPITRACK_HAVE_OPENCV

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "algo/image/image.hpp"
#include "algo/tracking/feature_tracker.hpp"

namespace epitrack::bench {

class OpenCvTracker {
 public:
  OpenCvTracker(int width, int height, const FeatureTrackerOptions& options)
      : width_(width),
        height_(height),
        options_(options),
        window_(options.window, options.window),
        criteria_(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01) {}

  /// A frame as a cv::Mat header on the image's pixels (no copy).
  [[nodiscard]] static cv::Mat wrap(const Image<uint8_t>& frame) {
    return {frame.height(), frame.width(), CV_8UC1, const_cast<uint8_t*>(frame.row(0)),
            static_cast<std::size_t>(frame.stride())};
  }

  /// The pyramid of `img`, then LK of the live tracks from the previous frame.
  void flow(const cv::Mat& img) {
    cv::buildOpticalFlowPyramid(img, next_pyr_, window_, options_.levels);
    if (points_.empty()) return;
    cv::calcOpticalFlowPyrLK(prev_pyr_, next_pyr_, points_, next_points_, status_, error_, window_,
                             options_.levels, criteria_);
    std::size_t k = 0;
    for (std::size_t i = 0; i < points_.size(); ++i) {
      const cv::Point2f& p = next_points_[i];
      if (status_[i] == 0 || p.x < 0 || p.y < 0 || p.x > static_cast<float>(width_ - 1) ||
          p.y > static_cast<float>(height_ - 1))
        continue;
      next_points_[k] = p;
      ids_[k++] = ids_[i];
    }
    next_points_.resize(k);
    ids_.resize(k);
    points_.swap(next_points_);
  }

  /// New corners away from the live tracks when these fall below the re-detection fraction;
  /// true when it detected.
  bool redetect(const cv::Mat& img) {
    if (static_cast<double>(points_.size()) >= options_.redetect_fraction * options_.max_features)
      return false;
    mask_.create(height_, width_, CV_8UC1);
    mask_.setTo(255);
    for (const auto& p : points_)
      cv::circle(mask_, p, static_cast<int>(options_.min_distance), 0, -1);
    corners_.clear();
    cv::goodFeaturesToTrack(img, corners_, options_.max_features - static_cast<int>(points_.size()),
                            0.01, options_.min_distance, mask_, 3, false);
    for (const auto& c : corners_) {
      points_.push_back(c);
      ids_.push_back(next_id_++);
    }
    return true;
  }

  /// This frame's pyramid becomes the previous one.
  void endFrame() { std::swap(prev_pyr_, next_pyr_); }

  [[nodiscard]] const std::vector<cv::Point2f>& points() const { return points_; }
  [[nodiscard]] const std::vector<int32_t>& ids() const { return ids_; }

 private:
  int width_, height_;
  FeatureTrackerOptions options_;
  cv::Size window_;
  cv::TermCriteria criteria_;
  std::vector<cv::Mat> prev_pyr_, next_pyr_;
  std::vector<cv::Point2f> points_, next_points_, corners_;
  std::vector<int32_t> ids_;
  std::vector<uchar> status_;
  std::vector<float> error_;
  int32_t next_id_ = 0;
  cv::Mat mask_;
};

}  // namespace epitrack::bench

#endif  // EPITRACK_HAVE_OPENCV
