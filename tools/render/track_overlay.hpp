#pragma once

// The right half of `epitrack-solve --overlay tracks`: the tracked features of a frame drawn over
// it, each with a trail through its last positions, coloured by what the solve made of it. Plus
// the anti-aliased 2D primitives this needs and the side-by-side composition.
//
//   render::drawTracks(panel.view(), tracks, kinds, frame, style);
//   render::sideBySide(augmented.constView(), panel.constView(), both.view());

#include <cstdint>
#include <span>

#include "algo/image/image_view.hpp"
#include "algo/sfm/track_table.hpp"
#include "tools/render/overlay_renderer.hpp"

namespace epitrack::render {

/// What the solve made of one 2D observation.
enum class TrackKind : uint8_t {
  kUnused,   ///< no 3D point (too short, never triangulated, or the frame is unsolved)
  kInlier,   ///< its 3D point reprojects within the outlier threshold in this frame
  kOutlier,  ///< its 3D point reprojects farther than the threshold
};

struct TrackStyle {
  int trail_frames = 12;  ///< trail through the positions of the last N frames
  double dot_radius_px = 2.4;
  double trail_width_px = 1.3;
  Rgb8 inlier{60, 230, 80};
  Rgb8 outlier{255, 150, 30};
  Rgb8 unused{230, 60, 60};
};

/// A filled disc with anti-aliased rim (coverage = clamp(radius + 1/2 - distance, 0, 1), the
/// box-filtered edge), blended over the image with `opacity`.
void drawDisc(ImageView<Rgb8> image, double cx, double cy, double radius, Rgb8 color,
              float opacity = 1.0F);
/// A segment of constant width with round caps, anti-aliased the same way.
void drawSegment(ImageView<Rgb8> image, double x0, double y0, double x1, double y1, double width,
                 Rgb8 color, float opacity = 1.0F);

/// Draws every observation of `frame` in `tracks`: the trail (positions in the previous
/// `style.trail_frames` frames where the track was seen) fading out, then a dot at the current
/// position. `kinds[i]` classifies `tracks.observations()[i]`.
void drawTracks(ImageView<Rgb8> image, const TrackTable& tracks, std::span<const TrackKind> kinds,
                int frame, const TrackStyle& style = TrackStyle{});

/// `out` (2W x H) = `left` (W x H) next to `right` (W x H).
void sideBySide(ImageView<const Rgb8> left, ImageView<const Rgb8> right, ImageView<Rgb8> out);

}  // namespace epitrack::render
