#include "tools/export/progress.hpp"

#include <algorithm>

#include <unistd.h>

namespace epitrack::io {
namespace {
constexpr int kBarWidth = 30;
constexpr int kLineStepPercent = 5;
}  // namespace

ProgressReporter::ProgressReporter(Mode mode, std::FILE* stream) : mode_(mode), stream_(stream) {
  if (stream_ == nullptr) mode_ = Mode::kQuiet;
  if (mode_ == Mode::kAuto) mode_ = ::isatty(::fileno(stream_)) != 0 ? Mode::kBar : Mode::kLines;
}

void ProgressReporter::begin(const std::string& stage, long total) {
  if (bar_open_) end();
  stage_ = stage;
  total_ = total;
  done_ = 0;
  last_step_ = -1;
  last_printed_ = -1;
  if (mode_ == Mode::kBar) {
    drawBar(0);
  } else if (mode_ == Mode::kLines) {
    if (total_ > 0) {
      std::fprintf(stream_, "%s: 0/%ld\n", stage_.c_str(), total_);
      last_step_ = 0;
      last_printed_ = 0;
    } else {
      std::fprintf(stream_, "%s: started\n", stage_.c_str());
    }
    std::fflush(stream_);
  }
}

void ProgressReporter::update(long done) {
  done_ = std::clamp(done, 0L, total_ > 0 ? total_ : done);
  if (mode_ == Mode::kBar) {
    drawBar(done_);
  } else if (mode_ == Mode::kLines && total_ > 0) {
    const int step = static_cast<int>(done_ * 100 / total_) / kLineStepPercent;
    if (step > last_step_) {
      last_step_ = step;
      last_printed_ = done_;
      std::fprintf(stream_, "%s: %ld/%ld\n", stage_.c_str(), done_, total_);
      std::fflush(stream_);
    }
  }
}

void ProgressReporter::end() {
  if (mode_ == Mode::kBar) {
    if (!bar_open_) drawBar(done_);
    std::fputc('\n', stream_);
    std::fflush(stream_);
    bar_open_ = false;
  } else if (mode_ == Mode::kLines) {
    if (total_ <= 0) {
      std::fprintf(stream_, "%s: done\n", stage_.c_str());
    } else if (last_printed_ != done_) {  // the final state is always shown once
      std::fprintf(stream_, "%s: %ld/%ld\n", stage_.c_str(), done_, total_);
    }
    std::fflush(stream_);
  }
  last_step_ = -1;
}

void ProgressReporter::message(const std::string& text) {
  if (mode_ == Mode::kQuiet) return;
  if (bar_open_) {
    std::fputc('\n', stream_);
    bar_open_ = false;
    last_step_ = -1;  // redraw the bar on the next update
  }
  std::fprintf(stream_, "%s\n", text.c_str());
  std::fflush(stream_);
}

void ProgressReporter::drawBar(long done) {
  const int percent = total_ > 0 ? static_cast<int>(done * 100 / total_) : 0;
  if (bar_open_ && percent == last_step_) return;  // redraw only when the percentage changes
  last_step_ = percent;
  bar_open_ = true;
  char bar[kBarWidth + 1];
  const int filled = total_ > 0 ? static_cast<int>(done * kBarWidth / total_) : 0;
  for (int i = 0; i < kBarWidth; ++i) bar[i] = i < filled ? '#' : '.';
  bar[kBarWidth] = '\0';
  if (total_ > 0) {
    std::fprintf(stream_, "\r%-12s [%s] %3d%% %ld/%ld\x1b[K", stage_.c_str(), bar, percent, done,
                 total_);
  } else {
    std::fprintf(stream_, "\r%-12s ...\x1b[K", stage_.c_str());
  }
  std::fflush(stream_);
}

}  // namespace epitrack::io
