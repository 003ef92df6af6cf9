#include "tools/render/track_overlay.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "algo/core/assert.hpp"

namespace epitrack::render {
namespace {

void blend(Rgb8& p, Rgb8 c, float a) {
  const auto mix = [a](uint8_t under, uint8_t over) {
    return static_cast<uint8_t>(std::clamp(
        std::lround(static_cast<float>(under) + a * (static_cast<float>(over) - under)), 0L, 255L));
  };
  p = {mix(p.r, c.r), mix(p.g, c.g), mix(p.b, c.b)};
}

// Pixel centres are at integer coordinates (the convention of the tracker and the rasterizer).
// Coverage of a pixel by a shape whose boundary is `distance` away from the centre, outside
// positive: the fraction of a unit box on the inside of a straight edge through that point.
float edgeCoverage(double signed_distance_outside) {
  return static_cast<float>(std::clamp(0.5 - signed_distance_outside, 0.0, 1.0));
}

}  // namespace

void drawDisc(ImageView<Rgb8> image, double cx, double cy, double radius, Rgb8 color,
              float opacity) {
  if (!(radius > 0.0) || !std::isfinite(cx) || !std::isfinite(cy)) return;
  const int x0 = std::max(0, static_cast<int>(std::floor(cx - radius - 1.0)));
  const int x1 = std::min(image.width - 1, static_cast<int>(std::ceil(cx + radius + 1.0)));
  const int y0 = std::max(0, static_cast<int>(std::floor(cy - radius - 1.0)));
  const int y1 = std::min(image.height - 1, static_cast<int>(std::ceil(cy + radius + 1.0)));
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) {
      const double d = std::hypot(x - cx, y - cy);
      const float a = edgeCoverage(d - radius) * opacity;
      if (a > 0.0F) blend(image(x, y), color, a);
    }
}

void drawSegment(ImageView<Rgb8> image, double x0, double y0, double x1, double y1, double width,
                 Rgb8 color, float opacity) {
  if (!(width > 0.0) || !std::isfinite(x0 + y0 + x1 + y1)) return;
  const double half = 0.5 * width;
  const int bx0 = std::max(0, static_cast<int>(std::floor(std::min(x0, x1) - half - 1.0)));
  const int bx1 =
      std::min(image.width - 1, static_cast<int>(std::ceil(std::max(x0, x1) + half + 1.0)));
  const int by0 = std::max(0, static_cast<int>(std::floor(std::min(y0, y1) - half - 1.0)));
  const int by1 =
      std::min(image.height - 1, static_cast<int>(std::ceil(std::max(y0, y1) + half + 1.0)));
  const double dx = x1 - x0, dy = y1 - y0;
  const double len2 = dx * dx + dy * dy;
  for (int y = by0; y <= by1; ++y)
    for (int x = bx0; x <= bx1; ++x) {
      // Distance from the pixel centre to the segment (round caps).
      double t = len2 > 0.0 ? ((x - x0) * dx + (y - y0) * dy) / len2 : 0.0;
      t = std::clamp(t, 0.0, 1.0);
      const double d = std::hypot(x - (x0 + t * dx), y - (y0 + t * dy));
      const float a = edgeCoverage(d - half) * opacity;
      if (a > 0.0F) blend(image(x, y), color, a);
    }
}

void drawTracks(ImageView<Rgb8> image, const TrackTable& tracks, std::span<const TrackKind> kinds,
                int frame, const TrackStyle& style) {
  if (frame < 0 || frame >= tracks.frameCount()) return;
  const auto all = tracks.observations();
  EPITRACK_ASSERT(kinds.size() == all.size());
  const auto current = tracks.frame(frame);
  const auto colorOf = [&](const TrackObservation& ob) {
    const auto i = static_cast<std::size_t>(&ob - all.data());
    switch (kinds[i]) {
      case TrackKind::kInlier:
        return style.inlier;
      case TrackKind::kOutlier:
        return style.outlier;
      case TrackKind::kUnused:
        break;
    }
    return style.unused;
  };
  // Trails first, so that no trail covers a dot.
  for (const auto& ob : current) {
    const Rgb8 color = colorOf(ob);
    const TrackObservation* newer = &ob;
    for (int back = 1; back <= style.trail_frames; ++back) {
      const TrackObservation* older = tracks.find(ob.track, frame - back);
      if (older == nullptr) break;
      const auto fade = static_cast<float>(1.0 - 0.7 * static_cast<double>(back - 1) /
                                                     std::max(1, style.trail_frames));
      drawSegment(image, older->x, older->y, newer->x, newer->y, style.trail_width_px, color, fade);
      newer = older;
    }
  }
  for (const auto& ob : current) drawDisc(image, ob.x, ob.y, style.dot_radius_px, colorOf(ob));
}

void sideBySide(ImageView<const Rgb8> left, ImageView<const Rgb8> right, ImageView<Rgb8> out) {
  EPITRACK_ASSERT(left.width == right.width && left.height == right.height);
  EPITRACK_ASSERT(out.width == 2 * left.width && out.height == left.height);
  const auto row_bytes = static_cast<std::size_t>(left.width) * sizeof(Rgb8);
  for (int y = 0; y < out.height; ++y) {
    std::memcpy(out.row(y), left.row(y), row_bytes);
    std::memcpy(out.row(y) + left.width, right.row(y), row_bytes);
  }
}

}  // namespace epitrack::render
