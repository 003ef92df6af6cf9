// libFuzzer harness: the YUV4MPEG2 reader (hal/replay/y4m_source.cpp) on an in-memory stream, the
// way it reads a pipe (INPUT `-`): header line, then FRAME lines and planes until the stream
// ends. Invariants: a source that opened has a size within the readers' limits; every frame has
// that size and the next index; after the end or an error nothing more is delivered.
#include <cstdio>
#include <string>

#include "hal/io/image_codec.hpp"
#include "hal/replay/y4m_source.hpp"
#include "tests/fuzz/fuzz_support.hpp"

namespace hal = epitrack::hal;

namespace {

constexpr int kMaxFramesPerInput = 64;

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  // The header parser on its own, on the first line.
  std::string first_line(reinterpret_cast<const char*>(data), size);
  first_line = first_line.substr(0, first_line.find('\n'));
  hal::Y4mHeader header;
  std::string error;
  if (hal::parseY4mHeader(first_line, header, error)) {
    FUZZ_CHECK(header.width >= 1 && header.width <= hal::kMaxImageDimension);
    FUZZ_CHECK(header.height >= 1 && header.height <= hal::kMaxImageDimension);
    FUZZ_CHECK(header.bit_depth >= 8 && header.bit_depth <= 16);
    // Larger frames only cost allocation time (a 16384x16384 open takes 0.4 s under ASan).
    if (!epitrack::fuzz::smallEnough(header.width, header.height)) return 0;
  }

  if (size == 0) return 0;
  std::FILE* stream = ::fmemopen(const_cast<uint8_t*>(data), size, "rb");  // read only
  FUZZ_CHECK(stream != nullptr);
  hal::Y4mSource source(stream, /*owns_stream=*/true, "fuzz input", hal::SourceOptions{});
  hal::Frame frame;
  if (!source.ok()) {
    FUZZ_CHECK(!source.lastError().empty());
    FUZZ_CHECK(source.next(frame) == hal::FrameStatus::kError);
    return 0;
  }
  const hal::SourceInfo& info = source.info();
  FUZZ_CHECK(info.width >= 1 && info.width <= hal::kMaxImageDimension);
  FUZZ_CHECK(info.height >= 1 && info.height <= hal::kMaxImageDimension);
  FUZZ_CHECK(info.fps > 0.0);
  int64_t expected_index = 0;
  for (int i = 0; i < kMaxFramesPerInput; ++i) {
    const hal::FrameStatus status = source.next(frame);
    if (status == hal::FrameStatus::kOk) {
      FUZZ_CHECK(frame.luma.width == info.width && frame.luma.height == info.height);
      FUZZ_CHECK(frame.index == expected_index);
      FUZZ_CHECK(frame.timestamp_s >= 0.0);
      // Touch every pixel: ASan checks the view lies inside the luma buffer.
      uint64_t sum = 0;
      for (int y = 0; y < frame.luma.height; ++y) {
        for (int x = 0; x < frame.luma.width; ++x) sum += frame.luma(x, y);
      }
      FUZZ_CHECK(sum <=
                 255u * static_cast<uint64_t>(info.width) * static_cast<uint64_t>(info.height));
      ++expected_index;
      continue;
    }
    FUZZ_CHECK(status == hal::FrameStatus::kEndOfStream ||
               status == hal::FrameStatus::kCorruptFrame || status == hal::FrameStatus::kError);
    if (status != hal::FrameStatus::kEndOfStream) FUZZ_CHECK(!source.lastError().empty());
    // The stream cannot be resynchronised: nothing more comes out.
    const hal::FrameStatus after = source.next(frame);
    FUZZ_CHECK(after == hal::FrameStatus::kEndOfStream || after == hal::FrameStatus::kError);
    break;
  }
  return 0;
}
