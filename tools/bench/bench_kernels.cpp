// epitrack-bench kernels: the LK inner loops one by one (algo/flow/lk_kernels.hpp), nanoseconds
// per iteration of a 21x21 window, every variant this machine runs (the dispatched ones fall back
// where the processor lacks them): the translation kernel (scalar, 128-bit) and the affine one
// (scalar, 128-bit SSE2 / NEON, AVX2, AVX-512). Shapes near the identity, as in tracking.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <ctime>
#include <vector>

#include "algo/flow/lk_kernels.hpp"
#include "algo/math/random.hpp"
#include "tools/bench/bench_registry.hpp"
#include "tools/common/command_line.hpp"

namespace epitrack::bench {
namespace {

/// Processor time of the process in nanoseconds.
double cpuNs() {
  return 1e9 * static_cast<double>(std::clock()) / static_cast<double>(CLOCKS_PER_SEC);
}

int runKernels(int argc, const char* const* argv) {
  int repeat = 7;
  int side = 21;
  tools::CommandLine cl("epitrack-bench kernels", "[--repeat N] [--window PX]",
                        "Times the LK kernels per iteration (ns, processor time): the best of N\n"
                        "passes over 1000 random windows of a random 704x576 image.");
  cl.integer("repeat", "N", "passes (default 7; the fastest counts)", &repeat, 1, 1000);
  cl.integer("window", "PX", "window side (default 21)", &side, 1, 80);
  if (const auto r = cl.parse(argc, argv); r != tools::CommandLine::Result::kOk)
    return tools::CommandLine::exitCode(r);

  constexpr int kWidth = 704;
  constexpr int kHeight = 576;
  SplitMix64 rng(2026);
  std::vector<uint8_t> pixels(static_cast<std::size_t>(kWidth) * kHeight);
  for (auto& p : pixels) p = static_cast<uint8_t>(rng.below(256));
  const ImageView<const uint8_t> image(pixels.data(), kWidth, kHeight);
  const int tstride = (side + 7) / 8 * 8;
  std::vector<int16_t> T(static_cast<std::size_t>(side * tstride), 0);
  std::vector<int16_t> Sx(T.size(), 0);
  std::vector<int16_t> Sy(T.size(), 0);
  for (int v = 0; v < side; ++v) {
    for (int u = 0; u < side; ++u) {
      const auto i = static_cast<std::size_t>(v * tstride + u);
      T[i] = static_cast<int16_t>(rng.below(8161));
      Sx[i] = static_cast<int16_t>(static_cast<int>(rng.below(8161)) - 4080);
      Sy[i] = static_cast<int16_t>(static_cast<int>(rng.below(8161)) - 4080);
    }
  }
  // Windows away from the border, shapes within 3 % of the identity (16.16 fixed point).
  constexpr std::size_t kWindows = 1000;
  std::vector<LkAffineWarp> warps(kWindows);
  std::vector<int32_t> rows(2 * kWindows * static_cast<std::size_t>(side));
  const auto fixed = [](double v) { return static_cast<int32_t>(std::lround(v * 65536.0)); };
  for (std::size_t i = 0; i < kWindows; ++i) {
    LkAffineWarp& w = warps[i];
    const double a00 = 1.0 + 0.06 * (rng.uniform() - 0.5), a01 = 0.06 * (rng.uniform() - 0.5);
    const double a10 = 0.06 * (rng.uniform() - 0.5), a11 = 1.0 + 0.06 * (rng.uniform() - 0.5);
    const double x = 2 * side + rng.below(static_cast<uint32_t>(kWidth - 4 * side)) + rng.uniform();
    const double y =
        2 * side + rng.below(static_cast<uint32_t>(kHeight - 4 * side)) + rng.uniform();
    int32_t* row_x = rows.data() + 2 * i * static_cast<std::size_t>(side);
    int32_t* row_y = row_x + side;
    for (int v = 0; v < side; ++v) {
      row_x[v] = fixed(x + a01 * v);
      row_y[v] = fixed(y + a11 * v);
    }
    w.row_x = row_x;
    w.row_y = row_y;
    w.xu = fixed(a00);
    w.yu = fixed(a10);
  }
  using Affine = void (*)(ImageView<const uint8_t>, const LkAffineWarp&, int, const int16_t*,
                          const int16_t*, const int16_t*, int, LkAffineSums&);
  const auto timeAffine = [&](const char* name, Affine kernel) {
    double best = 1e300;
    int64_t check = 0;
    for (int r = 0; r < repeat; ++r) {
      const double t0 = cpuNs();
      for (const auto& w : warps) {
        LkAffineSums s;
        kernel(image, w, side, T.data(), Sx.data(), Sy.data(), tstride, s);
        check += s.gx_e + s.sum_sq;
      }
      best = std::min(best, (cpuNs() - t0) / static_cast<double>(warps.size()));
    }
    JsonLine()
        .add("bench", "kernels")
        .add("kernel", "affine")
        .add("variant", name)
        .add("window", side)
        .add("ns_per_iteration", best)
        .add("checksum", static_cast<long>(check))
        .print();
  };
  timeAffine("scalar", lkAffineSumsScalar);
  timeAffine(lkVectorIsa(), lkAffineSums128);
  if (lkHaveAvx2()) timeAffine("avx2", lkAffineSumsAvx2);
  if (lkHaveAvx512()) timeAffine("avx512", lkAffineSumsAvx512);

  using Translation = void (*)(const uint8_t*, std::ptrdiff_t, int, const LkBilinear&,
                               const int16_t*, const int16_t*, const int16_t*, int, LkWindowSums&);
  const auto timeTranslation = [&](const char* name, Translation kernel) {
    double best = 1e300;
    int64_t check = 0;
    for (int r = 0; r < repeat; ++r) {
      const double t0 = cpuNs();
      for (const auto& w : warps) {
        const LkBilinear b = lkBilinear((w.row_x[0] >> 2) & 0x3fff, (w.row_y[0] >> 2) & 0x3fff);
        const uint8_t* window = image.row(w.row_y[0] >> 16) + (w.row_x[0] >> 16);
        LkWindowSums s;
        kernel(window, image.stride, side, b, T.data(), Sx.data(), Sy.data(), tstride, s);
        check += s.gx_e + s.sum_sq;
      }
      best = std::min(best, (cpuNs() - t0) / static_cast<double>(warps.size()));
    }
    JsonLine()
        .add("bench", "kernels")
        .add("kernel", "translation")
        .add("variant", name)
        .add("window", side)
        .add("ns_per_iteration", best)
        .add("checksum", static_cast<long>(check))
        .print();
  };
  timeTranslation("scalar", lkTranslationSumsScalar);
  timeTranslation(lkVectorIsa(), lkTranslationSumsVector);
  return 0;
}

const BenchRegistrar kRegister("kernels",
                               "LK kernels per iteration, every variant this machine runs",
                               runKernels);

}  // namespace
}  // namespace epitrack::bench
