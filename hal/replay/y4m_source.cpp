// YUV4MPEG2 reader. Format: one header line `YUV4MPEG2` followed by space-separated tags (W width,
// H height, F num:den frame rate, I interlacing, A aspect, C colour space, X comment), then for
// each frame a line `FRAME` (optionally with tags) and the planes Y, Cb, Cr (and alpha for
// 444alpha), each row-major without padding (mjpegtools yuv4mpeg(5); ffmpeg
// libavformat/yuv4mpegdec).
#include "hal/replay/y4m_source.hpp"

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include <sys/stat.h>

#include "hal/io/file_util.hpp"
#include "hal/io/image_codec.hpp"

namespace epitrack::hal {
namespace {

constexpr std::size_t kMaxHeaderLine = 4096;
constexpr std::size_t kMaxFrameLine = 4096;
constexpr std::size_t kSkipChunkBytes = std::size_t{1} << 16;  // chroma is skipped 64 KB at a time
constexpr char kMagic[] = "YUV4MPEG2";

bool parsePositiveInt(const std::string& text, int& value) {
  if (text.empty() || text.size() > 9) return false;
  long v = 0;
  for (char c : text) {
    if (c < '0' || c > '9') return false;
    v = v * 10 + (c - '0');
  }
  value = static_cast<int>(v);
  return value > 0;
}

/// Chroma layout: planes after luma, as a fraction of the luma size (sub-sampling per axis).
struct ChromaLayout {
  const char* prefix;
  int planes;   // chroma planes
  int shift_x;  // horizontal sub-sampling (log2)
  int shift_y;  // vertical sub-sampling (log2)
  bool alpha;   // an extra full-size plane
};

constexpr ChromaLayout kLayouts[] = {
    {"420jpeg", 2, 1, 1, false}, {"420paldv", 2, 1, 1, false}, {"420mpeg2", 2, 1, 1, false},
    {"444alpha", 2, 0, 0, true}, {"420", 2, 1, 1, false},      {"411", 2, 2, 0, false},
    {"422", 2, 1, 0, false},     {"444", 2, 0, 0, false},      {"mono", 0, 0, 0, false},
};

std::size_t subsampled(int size, int shift) {
  return (static_cast<std::size_t>(size) + ((std::size_t{1} << shift) - 1)) >> shift;
}

}  // namespace

bool parseY4mHeader(const std::string& line, Y4mHeader& header, std::string& error) {
  if (line.compare(0, sizeof(kMagic) - 1, kMagic) != 0 ||
      (line.size() > sizeof(kMagic) - 1 && line[sizeof(kMagic) - 1] != ' ')) {
    error = "not a Y4M stream (no YUV4MPEG2 signature)";
    return false;
  }
  header = Y4mHeader{};
  std::size_t pos = sizeof(kMagic) - 1;
  while (pos < line.size()) {
    while (pos < line.size() && line[pos] == ' ') ++pos;
    if (pos >= line.size()) break;
    std::size_t end = line.find(' ', pos);
    if (end == std::string::npos) end = line.size();
    const char tag = line[pos];
    const std::string value = line.substr(pos + 1, end - pos - 1);
    pos = end;
    switch (tag) {
      case 'W':
        if (!parsePositiveInt(value, header.width)) {
          error = "bad Y4M width 'W" + value + "'";
          return false;
        }
        break;
      case 'H':
        if (!parsePositiveInt(value, header.height)) {
          error = "bad Y4M height 'H" + value + "'";
          return false;
        }
        break;
      case 'F': {
        const std::size_t colon = value.find(':');
        if (colon == std::string::npos ||
            !parsePositiveInt(value.substr(0, colon), header.fps_num) ||
            !parsePositiveInt(value.substr(colon + 1), header.fps_den)) {
          error = "bad Y4M frame rate 'F" + value + "'";
          return false;
        }
        break;
      }
      case 'C':
        header.chroma = value;
        break;
      default:  // I (interlacing), A (aspect), X (comments): not needed for luma
        break;
    }
  }
  if (header.width == 0 || header.height == 0) {
    error = "Y4M header without W and H";
    return false;
  }
  if (header.width > kMaxImageDimension || header.height > kMaxImageDimension) {
    error = "Y4M size " + std::to_string(header.width) + "x" + std::to_string(header.height) +
            " outside 1.." + std::to_string(kMaxImageDimension);
    return false;
  }
  const ChromaLayout* layout = nullptr;
  for (const ChromaLayout& l : kLayouts) {
    if (header.chroma.compare(0, std::strlen(l.prefix), l.prefix) == 0) {
      layout = &l;
      break;
    }
  }
  if (layout == nullptr) {
    error = "unsupported Y4M colour space 'C" + header.chroma + "'";
    return false;
  }
  const std::string suffix = header.chroma.substr(std::strlen(layout->prefix));
  header.bit_depth = 8;
  // The suffix is empty (8 bits), "pN" (N bits), a bare N after "mono", or a 4:2:0 siting name;
  // parsing a depth sets header.bit_depth.
  const bool mono = std::strcmp(layout->prefix, "mono") == 0;
  const bool known_suffix =
      suffix.empty() ||
      (suffix[0] == 'p' && !mono && parsePositiveInt(suffix.substr(1), header.bit_depth)) ||
      (mono && parsePositiveInt(suffix, header.bit_depth)) ||
      (std::strcmp(layout->prefix, "420") == 0 &&
       (suffix == "jpeg" || suffix == "paldv" || suffix == "mpeg2"));
  if (!known_suffix) {
    error = "unsupported Y4M colour space 'C" + header.chroma + "'";
    return false;
  }
  if (header.bit_depth < 8 || header.bit_depth > 16) {
    error = "unsupported Y4M bit depth in 'C" + header.chroma + "'";
    return false;
  }
  const std::size_t sample_bytes = header.bit_depth > 8 ? 2 : 1;
  const std::size_t chroma_plane =
      subsampled(header.width, layout->shift_x) * subsampled(header.height, layout->shift_y);
  header.other_plane_bytes =
      sample_bytes * (static_cast<std::size_t>(layout->planes) * chroma_plane +
                      (layout->alpha ? static_cast<std::size_t>(header.width) *
                                           static_cast<std::size_t>(header.height)
                                     : 0));
  return true;
}

Y4mSource::Y4mSource(const std::string& path, const SourceOptions& options) : name_(path) {
  if (path == "-") {
    name_ = "standard input";
    stream_ = stdin;
    owns_stream_ = false;
    openStream(options, -1);
    return;
  }
  stream_ = std::fopen(path.c_str(), "rbe");
  if (stream_ == nullptr) {
    error_ = "cannot open '" + path + "': " + errnoText(errno);
    return;
  }
  owns_stream_ = true;
  struct stat st {};
  const std::int64_t size =
      ::fstat(::fileno(stream_), &st) == 0 && S_ISREG(st.st_mode) ? st.st_size : -1;
  openStream(options, size);
}

Y4mSource::Y4mSource(std::FILE* stream, bool owns_stream, const std::string& name,
                     const SourceOptions& options)
    : stream_(stream), owns_stream_(owns_stream), name_(name) {
  openStream(options, -1);
}

Y4mSource::~Y4mSource() {
  if (owns_stream_ && stream_ != nullptr) std::fclose(stream_);
}

void Y4mSource::openStream(const SourceOptions& options, std::int64_t file_size) {
  // A large stdio buffer: pipes from ffmpeg deliver a frame in many small reads.
  // Not value-initialised: clearing 1 MB on every open was most of the time of a short stream.
  constexpr std::size_t kStreamBufferBytes = std::size_t{1} << 20;
  stream_buffer_.reset(new char[kStreamBufferBytes]);
  std::setvbuf(stream_, stream_buffer_.get(), _IOFBF, kStreamBufferBytes);
  line_.reserve(kMaxHeaderLine);
  if (!readLine(line_, kMaxHeaderLine)) {
    error_ = "'" + name_ + "': " +
             (offset_ == 0 ? std::string("empty stream, not a Y4M file")
                           : std::string("not a Y4M stream (no complete header line)"));
    return;
  }
  if (!parseY4mHeader(line_, header_, error_)) {
    error_ = "'" + name_ + "': " + error_;
    return;
  }
  if (!luma_.allocate(header_.width, header_.height)) {
    error_ = "'" + name_ + "': cannot allocate frames";
    return;
  }
  const std::size_t row_scratch =
      header_.bit_depth > 8 ? 2 * static_cast<std::size_t>(header_.width) : 0;
  // The chroma and alpha planes are read and dropped in chunks of the scratch buffer, so a large
  // header does not make the source allocate and clear every plane (a 16384x16384 444alpha p16
  // header asked for 1.6 GB of scratch; found by fuzzing).
  scratch_.resize(std::max(row_scratch, std::min(header_.other_plane_bytes, kSkipChunkBytes)));
  info_.width = header_.width;
  info_.height = header_.height;
  info_.fps = header_.fps_num > 0 ? static_cast<double>(header_.fps_num) / header_.fps_den
                                  : options.default_fps;
  info_.pixel_format = "Y4M " + header_.chroma;
  info_.real_timestamps = false;
  // Frames of a regular file, assuming plain "FRAME\n" lines (the usual case).
  const std::size_t luma_bytes = static_cast<std::size_t>(header_.width) *
                                 static_cast<std::size_t>(header_.height) *
                                 (header_.bit_depth > 8 ? 2 : 1);
  const std::size_t frame_bytes = 6 + luma_bytes + header_.other_plane_bytes;
  if (file_size > 0 && static_cast<std::uint64_t>(file_size) >= offset_ &&
      (static_cast<std::uint64_t>(file_size) - offset_) % frame_bytes == 0) {
    info_.frame_count =
        static_cast<std::int64_t>((static_cast<std::uint64_t>(file_size) - offset_) / frame_bytes);
  }
  pacer_.configure(options.realtime, info_.fps);
  line_.reserve(kMaxFrameLine);
  ok_ = true;
}

bool Y4mSource::readLine(std::string& line, std::size_t max_length) {
  line.clear();
  for (;;) {
    const int c = std::getc(stream_);
    if (c == EOF) return false;
    ++offset_;
    if (c == '\n') return true;
    if (line.size() >= max_length) return false;
    line.push_back(static_cast<char>(c));
  }
}

std::size_t Y4mSource::readBytes(void* dst, std::size_t size) {
  const std::size_t n = std::fread(dst, 1, size, stream_);
  offset_ += n;
  return n;
}

FrameStatus Y4mSource::next(Frame& frame) {
  if (!ok_) return FrameStatus::kError;
  if (ended_) return FrameStatus::kEndOfStream;
  const std::int64_t index = next_index_;
  const std::uint64_t frame_offset = offset_;
  if (!readLine(line_, kMaxFrameLine)) {
    ended_ = true;
    if (offset_ == frame_offset) return FrameStatus::kEndOfStream;  // clean end
    error_ = "'" + name_ + "': truncated frame header of frame " + std::to_string(index) +
             " at byte " + std::to_string(frame_offset);
    return FrameStatus::kCorruptFrame;
  }
  if (line_.compare(0, 5, "FRAME") != 0 || (line_.size() > 5 && line_[5] != ' ')) {
    // Without a frame marker the stream cannot be resynchronised.
    ended_ = true;
    error_ = "'" + name_ + "': bad frame marker at byte " + std::to_string(frame_offset) +
             " (frame " + std::to_string(index) + ")";
    return FrameStatus::kError;
  }
  ++next_index_;
  pacer_.wait(index);
  bool complete = true;
  const auto w = static_cast<std::size_t>(header_.width);
  if (header_.bit_depth == 8) {
    for (int y = 0; y < header_.height && complete; ++y) {
      complete = readBytes(luma_.row(y), w) == w;
    }
  } else {
    const int shift = header_.bit_depth - 8;
    for (int y = 0; y < header_.height && complete; ++y) {
      complete = readBytes(scratch_.data(), 2 * w) == 2 * w;
      uint8_t* dst = luma_.row(y);
      for (std::size_t x = 0; x < w; ++x) {  // little-endian samples (ffmpeg's layout)
        const unsigned v = static_cast<unsigned>(scratch_[2 * x]) |
                           (static_cast<unsigned>(scratch_[2 * x + 1]) << 8);
        const unsigned v8 = v >> shift;
        dst[x] = static_cast<uint8_t>(v8 > 255 ? 255 : v8);
      }
    }
  }
  for (std::size_t left = header_.other_plane_bytes; complete && left > 0;) {
    const std::size_t chunk = std::min(left, scratch_.size());
    complete = readBytes(scratch_.data(), chunk) == chunk;
    left -= chunk;
  }
  if (!complete) {
    ended_ = true;
    error_ = "'" + name_ + "': frame " + std::to_string(index) + " truncated at byte " +
             std::to_string(offset_) + " (stream ended inside the frame)";
    return FrameStatus::kCorruptFrame;
  }
  frame.luma = luma_.constView();
  frame.index = index;
  frame.timestamp_s = static_cast<double>(index) / info_.fps;
  return FrameStatus::kOk;
}

}  // namespace epitrack::hal
