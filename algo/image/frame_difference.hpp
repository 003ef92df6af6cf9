#pragma once

#include <cstdint>

#include "algo/image/image_view.hpp"

namespace epitrack {

/// True when two frames of the same size differ by at most `max_mean_abs_diff_q8` / 256 grey
/// levels per pixel on average (mean absolute difference, unsigned Q8: 64 = 0.25 grey level).
/// Integer arithmetic only, so every platform decides alike; the scan stops as soon as the
/// bound is exceeded, so a frame that moved costs a few rows. Frames of different sizes (or
/// empty ones) are never equal. Never allocates.
///
/// Why: a camera or a file can hand the same picture twice (a capture loop faster than its source,
/// 3:2 pulldown, variable-frame-rate phone video re-timed to a fixed rate, a driver that repeats
/// the last buffer). A tracker that predicts motion treats such a frame as every track stopping
/// at once (docs/tracker.md, "Repeated frames").
[[nodiscard]] bool framesNearlyEqual(ImageView<const uint8_t> a, ImageView<const uint8_t> b,
                                     uint32_t max_mean_abs_diff_q8);

}  // namespace epitrack
