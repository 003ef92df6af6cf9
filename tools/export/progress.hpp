#pragma once

// Progress of a long command on stderr (ARCHITECTURE.md: "progress on stderr"): a bar redrawn in
// place when the stream is a terminal, plain lines `stage: i/n` (at most one per ~5 %) when it is
// not (logs, CI), nothing when quiet.

#include <cstdio>
#include <string>

namespace epitrack::io {

class ProgressReporter {
 public:
  enum class Mode {
    kAuto,   ///< kBar when the stream is a terminal (isatty), kLines otherwise
    kBar,    ///< `\r stage [#####.....]  45% 123/270` redrawn in place
    kLines,  ///< `stage: 123/270` lines, one per 5 % step (and the last)
    kQuiet,  ///< nothing
  };

  explicit ProgressReporter(Mode mode = Mode::kAuto, std::FILE* stream = stderr);

  /// Starts a stage of `total` steps (total <= 0: unknown length, only begin/end are shown).
  void begin(const std::string& stage, long total);
  /// Reports that `done` steps of the current stage are complete (0..total).
  void update(long done);
  /// Ends the stage (prints the final state: 100 % when done == total).
  void end();
  /// A one-off message line (not shown when quiet); finishes a bar line first.
  void message(const std::string& text);

  [[nodiscard]] Mode mode() const { return mode_; }

 private:
  void drawBar(long done);

  Mode mode_;
  std::FILE* stream_;
  std::string stage_;
  long total_ = 0;
  long done_ = 0;
  int last_step_ = -1;      // last printed 5 % step (lines) or percent (bar)
  long last_printed_ = -1;  // done count of the last printed line (lines mode)
  bool bar_open_ = false;
};

}  // namespace epitrack::io
