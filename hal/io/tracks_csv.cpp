#include "hal/io/tracks_csv.hpp"

#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "hal/io/file_util.hpp"
#include "hal/io/text_formats.hpp"

namespace epitrack::hal {

std::string formatTracksCsv(const std::vector<TrackRow>& rows) {
  std::string out = kTracksCsvHeader;
  out += '\n';
  out.reserve(out.size() + rows.size() * 32);
  char line[96];
  for (const TrackRow& r : rows) {
    const int n = std::snprintf(line, sizeof(line), "%" PRId64 ",%" PRId32 ",%.3f,%.3f\n", r.frame,
                                r.track_id, r.x, r.y);
    if (n < 0) continue;
    if (static_cast<std::size_t>(n) < sizeof(line)) {
      out.append(line, static_cast<std::size_t>(n));
      continue;
    }
    // A huge coordinate prints to hundreds of digits: format it at its full length rather than
    // cut the line (a cut line loses its newline and merges with the next one).
    const std::size_t start = out.size();
    out.resize(start + static_cast<std::size_t>(n) + 1);
    std::snprintf(out.data() + start, static_cast<std::size_t>(n) + 1,
                  "%" PRId64 ",%" PRId32 ",%.3f,%.3f\n", r.frame, r.track_id, r.x, r.y);
    out.resize(start + static_cast<std::size_t>(n));
  }
  return out;
}

namespace {

bool parseRow(const std::string& line, TrackRow& row) {
  const char* p = line.c_str();
  char* end = nullptr;
  errno = 0;
  const long long frame = std::strtoll(p, &end, 10);
  if (end == p || *end != ',' || errno != 0 || frame < 0) return false;
  p = end + 1;
  const long long id = std::strtoll(p, &end, 10);
  if (end == p || *end != ',' || errno != 0 || id < INT32_MIN || id > INT32_MAX) return false;
  p = end + 1;
  const double x = std::strtod(p, &end);
  if (end == p || *end != ',') return false;
  p = end + 1;
  const double y = std::strtod(p, &end);
  if (end == p) return false;
  while (*end == ' ' || *end == '\t' || *end == '\r') ++end;
  if (*end != '\0' || !std::isfinite(x) || !std::isfinite(y)) return false;
  row = TrackRow{frame, static_cast<int32_t>(id), x, y};
  return true;
}

}  // namespace

bool parseTracksCsv(const std::string& text, std::vector<TrackRow>& rows, std::string& error) {
  rows.clear();
  std::size_t pos = 0;
  int line_no = 0;
  bool header_seen = false;
  while (pos < text.size()) {
    std::size_t eol = text.find('\n', pos);
    if (eol == std::string::npos) eol = text.size();
    std::string line = text.substr(pos, eol - pos);
    pos = eol + 1;
    ++line_no;
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    if (line.empty()) continue;
    if (!header_seen) {
      if (line != kTracksCsvHeader) {
        error =
            "line " + std::to_string(line_no) + ": expected the header '" + kTracksCsvHeader + "'";
        return false;
      }
      header_seen = true;
      continue;
    }
    TrackRow row;
    if (!parseRow(line, row)) {
      error =
          "line " + std::to_string(line_no) + ": expected 'frame,track_id,x,y', got '" + line + "'";
      return false;
    }
    rows.push_back(row);
  }
  if (!header_seen) {
    error = "empty file: expected the header '" + std::string(kTracksCsvHeader) + "'";
    return false;
  }
  return true;
}

bool writeTracksCsv(const std::string& path, const std::vector<TrackRow>& rows,
                    std::string& error) {
  return writeTextAtomic(path, formatTracksCsv(rows), error);
}

bool readTracksCsv(const std::string& path, std::vector<TrackRow>& rows, std::string& error) {
  std::string text;
  if (!readTextFile(path, text, error)) return false;
  if (!parseTracksCsv(text, rows, error)) {
    error = path + ": " + error;
    return false;
  }
  return true;
}

}  // namespace epitrack::hal
