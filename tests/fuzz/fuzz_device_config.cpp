// libFuzzer harness: the device and option strings users type — epitrack-device's configuration
// file and its `key value` options (firmware_like/device_config.cpp, `--config FILE` and the
// command line), the `v4l2:` INPUT
// (`v4l2:/dev/videoN?width=W&height=H&fps=N&format=grey|yuyv|mjpeg&buffers=B&timeout_ms=T`, in
// hal/v4l2) and the value parsers of tools/common (`WxH` sizes, comma-separated number lists).
// Invariants: accepted values are inside their documented ranges; refusals carry a message.
#include <cmath>
#include <string>
#include <vector>

#include <linux/videodev2.h>

#include "firmware_like/device_config.hpp"
#include "hal/io/image_codec.hpp"
#include "hal/v4l2/v4l2_capture_source.hpp"
#include "tests/fuzz/fuzz_support.hpp"
#include "tools/common/command_line.hpp"

namespace hal = epitrack::hal;
namespace device = epitrack::device;

namespace {

// What every accepted configuration satisfies, whatever the keys that were applied.
void checkConfigInvariants(const device::DeviceConfig& config) {
  FUZZ_CHECK(config.max_frames >= 0);
  FUZZ_CHECK(config.warmup_frames >= 0);
  FUZZ_CHECK(std::isfinite(config.fps) && config.fps > 0.0);
  FUZZ_CHECK(std::isfinite(config.focal) && config.focal >= 0.0);
  std::string error;
  if (!device::validateConfig(config, error)) FUZZ_CHECK(!error.empty());
}

// The input as a configuration file (`key = value` lines), then each line's value for every key,
// as the command line passes `--key value`.
void fuzzDeviceConfig(const std::string& text) {
  device::DeviceConfig config;
  std::string error;
  if (device::applyConfigText(config, text, "fuzz.conf", error)) {
    checkConfigInvariants(config);
  } else {
    FUZZ_CHECK(error.rfind("fuzz.conf:", 0) == 0);
  }
  const std::string value = text.substr(0, text.find('\n'));
  for (const auto& [key, help] : device::configKeys()) {
    device::DeviceConfig one;
    std::string reason;
    if (device::applyConfigValueReason(one, key, value, reason)) {
      checkConfigInvariants(one);
    } else {
      FUZZ_CHECK(!reason.empty());
    }
  }
  std::string unknown;
  FUZZ_CHECK(!device::applyConfigValue(config, "no-such-key", value, unknown) && !unknown.empty());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  fuzzDeviceConfig(text);

  for (const std::string& input : {text, "v4l2:" + text}) {
    hal::V4l2Options options;
    std::string error;
    if (!hal::parseV4l2Input(input, options, error)) {
      FUZZ_CHECK(!error.empty());
      continue;
    }
    FUZZ_CHECK(!options.device.empty());
    FUZZ_CHECK(options.device.find('?') == std::string::npos);
    FUZZ_CHECK((options.width == 0) == (options.height == 0));
    FUZZ_CHECK(options.width >= 0 && options.width <= hal::kMaxImageDimension);
    FUZZ_CHECK(options.height >= 0 && options.height <= hal::kMaxImageDimension);
    FUZZ_CHECK(options.fps == 0.0 || (options.fps > 0.0 && options.fps <= 1000.0));
    FUZZ_CHECK(options.fourcc == 0 || options.fourcc == V4L2_PIX_FMT_GREY ||
               options.fourcc == V4L2_PIX_FMT_YUYV || options.fourcc == V4L2_PIX_FMT_MJPEG);
    FUZZ_CHECK(options.buffers >= 2 && options.buffers <= hal::V4l2CaptureSource::kMaxBuffers);
    FUZZ_CHECK(options.timeout_ms >= 1 && options.timeout_ms <= 600000);
    FUZZ_CHECK(hal::fourccName(options.fourcc).size() <= 4);
  }

  int width = -1;
  int height = -1;
  if (epitrack::tools::parseSize(text, width, height)) {
    FUZZ_CHECK(width >= 1 && width <= 16384 && height >= 1 && height <= 16384);
  }
  std::vector<double> values;
  if (epitrack::tools::parseDoubleList(text, values)) {
    FUZZ_CHECK(!values.empty());
    for (const double v : values) FUZZ_CHECK(std::isfinite(v));
  }
  if (size >= 4) {
    const uint32_t fourcc = uint32_t{data[0]} | (uint32_t{data[1]} << 8) |
                            (uint32_t{data[2]} << 16) | (uint32_t{data[3]} << 24);
    FUZZ_CHECK(hal::fourccName(fourcc).size() <= 4);
  }
  return 0;
}
