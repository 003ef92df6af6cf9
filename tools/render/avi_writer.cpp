#include "tools/render/avi_writer.hpp"

#include <cmath>
#include <cstring>

#include <unistd.h>

namespace epitrack::render {
namespace {

void put32(std::vector<uint8_t>& b, uint32_t v) {
  for (int i = 0; i < 4; ++i) b.push_back(static_cast<uint8_t>(v >> (8 * i)));
}
void put16(std::vector<uint8_t>& b, uint16_t v) {
  b.push_back(static_cast<uint8_t>(v));
  b.push_back(static_cast<uint8_t>(v >> 8));
}
void fourcc(std::vector<uint8_t>& b, const char* c) { b.insert(b.end(), c, c + 4); }

constexpr uint32_t kAviHasIndex = 0x10;
constexpr uint32_t kAviKeyframe = 0x10;
constexpr uint64_t kMaxAviBytes = 0x7FFFFFFFull;

}  // namespace

MjpegAviWriter::~MjpegAviWriter() {
  if (file_ != nullptr) {
    std::fclose(file_);
    ::unlink(tmp_path_.c_str());
  }
}

bool MjpegAviWriter::open(const std::string& path, int width, int height, double fps,
                          std::string& error) {
  if (width <= 0 || height <= 0 || !(fps > 0.0)) {
    error = "invalid AVI size or frame rate";
    return false;
  }
  path_ = path;
  tmp_path_ = path + ".tmp";
  width_ = width;
  height_ = height;
  fps_ = fps;
  index_.clear();
  max_frame_bytes_ = 0;
  file_ = std::fopen(tmp_path_.c_str(), "wb");
  if (file_ == nullptr) {
    error = "cannot create '" + tmp_path_ + "': " + std::strerror(errno);
    return false;
  }
  return writeHeaders(error);
}

// Header layout (AVI 1.0): RIFF('AVI ' LIST('hdrl' avih LIST('strl' strh strf)) LIST('movi' ...)
// idx1). Sizes are rewritten by finish(); the header is fixed-length so it can be rewritten in
// place.
bool MjpegAviWriter::writeHeaders(std::string& error) {
  const auto frames = static_cast<uint32_t>(index_.size());
  const auto us_per_frame = static_cast<uint32_t>(std::lround(1e6 / fps_));
  // Frame rate as a rational: rate / scale with scale = 1000 (29.97 -> 29970/1000).
  const uint32_t scale = 1000;
  const auto rate = static_cast<uint32_t>(std::lround(fps_ * scale));
  std::vector<uint8_t> h;
  fourcc(h, "RIFF");
  put32(h, 0);  // patched
  fourcc(h, "AVI ");
  fourcc(h, "LIST");
  put32(h, 4 + 8 + 56 + 8 + 4 + 8 + 56 + 8 + 40);
  fourcc(h, "hdrl");
  fourcc(h, "avih");
  put32(h, 56);
  put32(h, us_per_frame);
  put32(h, static_cast<uint32_t>(max_frame_bytes_ * fps_));  // max bytes per second
  put32(h, 0);                                               // padding granularity
  put32(h, kAviHasIndex);
  put32(h, frames);
  put32(h, 0);  // initial frames
  put32(h, 1);  // streams
  put32(h, max_frame_bytes_ + 8);
  put32(h, static_cast<uint32_t>(width_));
  put32(h, static_cast<uint32_t>(height_));
  for (int i = 0; i < 4; ++i) put32(h, 0);
  fourcc(h, "LIST");
  put32(h, 4 + 8 + 56 + 8 + 40);
  fourcc(h, "strl");
  fourcc(h, "strh");
  put32(h, 56);
  fourcc(h, "vids");
  fourcc(h, "MJPG");
  put32(h, 0);  // flags
  put16(h, 0);  // priority
  put16(h, 0);  // language
  put32(h, 0);  // initial frames
  put32(h, scale);
  put32(h, rate);
  put32(h, 0);  // start
  put32(h, frames);
  put32(h, max_frame_bytes_ + 8);
  put32(h, 0xFFFFFFFFu);  // quality: default
  put32(h, 0);            // sample size: variable
  put16(h, 0);
  put16(h, 0);
  put16(h, static_cast<uint16_t>(width_));
  put16(h, static_cast<uint16_t>(height_));
  fourcc(h, "strf");
  put32(h, 40);  // BITMAPINFOHEADER
  put32(h, 40);
  put32(h, static_cast<uint32_t>(width_));
  put32(h, static_cast<uint32_t>(height_));
  put16(h, 1);   // planes
  put16(h, 24);  // bit count
  fourcc(h, "MJPG");
  put32(h, static_cast<uint32_t>(width_ * height_ * 3));
  put32(h, 0);
  put32(h, 0);
  put32(h, 0);
  put32(h, 0);
  fourcc(h, "LIST");
  put32(h, 0);  // movi size, patched
  movi_start_ = static_cast<long>(h.size());
  fourcc(h, "movi");
  if (std::fseek(file_, 0, SEEK_SET) != 0 ||
      std::fwrite(h.data(), 1, h.size(), file_) != h.size()) {
    error = "cannot write '" + tmp_path_ + "'";
    return false;
  }
  return true;
}

bool MjpegAviWriter::addFrame(const uint8_t* jpeg, std::size_t size, std::string& error) {
  if (file_ == nullptr) {
    error = "AVI writer is not open";
    return false;
  }
  const long pos = std::ftell(file_);
  const std::size_t padded = size + (size & 1);
  if (static_cast<uint64_t>(pos) + 8 + padded + 16 * (index_.size() + 1) + 8 > kMaxAviBytes) {
    error = "AVI would exceed 2 GiB (AVI 1.0 limit); write fewer or smaller frames";
    return false;
  }
  std::vector<uint8_t> head;
  fourcc(head, "00dc");
  put32(head, static_cast<uint32_t>(size));
  const uint8_t pad = 0;
  if (std::fwrite(head.data(), 1, 8, file_) != 8 || std::fwrite(jpeg, 1, size, file_) != size ||
      ((size & 1) != 0 && std::fwrite(&pad, 1, 1, file_) != 1)) {
    error = "cannot write '" + tmp_path_ + "': " + std::strerror(errno);
    return false;
  }
  index_.push_back({static_cast<uint32_t>(pos - movi_start_), static_cast<uint32_t>(size)});
  max_frame_bytes_ = std::max(max_frame_bytes_, static_cast<uint32_t>(size));
  return true;
}

bool MjpegAviWriter::finish(std::string& error) {
  if (file_ == nullptr) {
    error = "AVI writer is not open";
    return false;
  }
  const long movi_end = std::ftell(file_);
  std::vector<uint8_t> idx;
  fourcc(idx, "idx1");
  put32(idx, static_cast<uint32_t>(16 * index_.size()));
  for (const auto& e : index_) {
    fourcc(idx, "00dc");
    put32(idx, kAviKeyframe);
    put32(idx, e.offset);
    put32(idx, e.size);
  }
  bool ok = std::fwrite(idx.data(), 1, idx.size(), file_) == idx.size();
  const long end = std::ftell(file_);
  ok = ok && writeHeaders(error);  // frame counts and max sizes
  std::vector<uint8_t> v;
  put32(v, static_cast<uint32_t>(end - 8));
  ok = ok && std::fseek(file_, 4, SEEK_SET) == 0 && std::fwrite(v.data(), 1, 4, file_) == 4;
  v.clear();
  put32(v, static_cast<uint32_t>(movi_end - movi_start_));
  ok = ok && std::fseek(file_, movi_start_ - 4, SEEK_SET) == 0 &&
       std::fwrite(v.data(), 1, 4, file_) == 4;
  ok = std::fclose(file_) == 0 && ok;
  file_ = nullptr;
  if (!ok) {
    error = "cannot write '" + tmp_path_ + "'";
    ::unlink(tmp_path_.c_str());
    return false;
  }
  if (std::rename(tmp_path_.c_str(), path_.c_str()) != 0) {
    error = "cannot rename '" + tmp_path_ + "' to '" + path_ + "': " + std::strerror(errno);
    return false;
  }
  return true;
}

}  // namespace epitrack::render
