#pragma once

#include <chrono>
#include <cstdint>
#include <thread>

namespace epitrack::hal {

/// Paces replay at a nominal frame rate: frame i is released no earlier than start + i / fps.
class ReplayPacer {
 public:
  void configure(bool enabled, double fps) {
    enabled_ = enabled && fps > 0.0;
    period_s_ = fps > 0.0 ? 1.0 / fps : 0.0;
  }
  void wait(int64_t frame_number) {
    if (!enabled_) return;
    const auto now = std::chrono::steady_clock::now();
    if (frame_number == 0 || !started_) {
      start_ = now;
      started_ = true;
      return;
    }
    const auto due =
        start_ + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                     std::chrono::duration<double>(period_s_ * static_cast<double>(frame_number)));
    if (due > now) std::this_thread::sleep_until(due);
  }

 private:
  bool enabled_ = false;
  bool started_ = false;
  double period_s_ = 0.0;
  std::chrono::steady_clock::time_point start_{};
};

}  // namespace epitrack::hal
