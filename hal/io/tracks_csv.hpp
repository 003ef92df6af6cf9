#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace epitrack::hal {

/// One row of `tracks.csv` (ARCHITECTURE.md "File formats"): a tracked feature in one frame.
struct TrackRow {
  int64_t frame = 0;
  int32_t track_id = 0;
  double x = 0.0;
  double y = 0.0;
};

/// The header line, without newline: `frame,track_id,x,y`.
inline constexpr const char* kTracksCsvHeader = "frame,track_id,x,y";

/// Formats rows under the header, coordinates with 3 decimals (1/1000 px).
std::string formatTracksCsv(const std::vector<TrackRow>& rows);
/// Parses a tracks.csv text: the header is required; blank lines are skipped; errors name the line.
bool parseTracksCsv(const std::string& text, std::vector<TrackRow>& rows, std::string& error);
/// Atomic write (temporary file + rename) and file read.
bool writeTracksCsv(const std::string& path, const std::vector<TrackRow>& rows, std::string& error);
bool readTracksCsv(const std::string& path, std::vector<TrackRow>& rows, std::string& error);

}  // namespace epitrack::hal
