// --overlay tracks (tools/render/track_overlay): anti-aliased discs and segments cover their
// analytic area, tracks are drawn at their positions in the colour of their kind with trails
// through earlier frames only, and the side-by-side frame holds both halves unchanged.
#include "tools/render/track_overlay.hpp"

#include <cmath>
#include <vector>

#include <catch2/catch.hpp>

#include "algo/image/image.hpp"

using epitrack::Image;
using epitrack::render::Rgb8;
using epitrack::render::TrackKind;

namespace {

constexpr double kPi = 3.14159265358979323846;

// Sum over the image of the drawn fraction per pixel (white drawn over black, red channel).
double coveredArea(const Image<Rgb8>& img) {
  double sum = 0.0;
  for (int y = 0; y < img.height(); ++y)
    for (int x = 0; x < img.width(); ++x) sum += img.constView()(x, y).r / 255.0;
  return sum;
}

// Coverage-weighted centroid of the drawn pixels.
Eigen::Vector2d centroid(const Image<Rgb8>& img) {
  double sum = 0.0, sx = 0.0, sy = 0.0;
  for (int y = 0; y < img.height(); ++y)
    for (int x = 0; x < img.width(); ++x) {
      const double a = img.constView()(x, y).r / 255.0;
      sum += a;
      sx += a * x;
      sy += a * y;
    }
  return {sx / sum, sy / sum};
}

}  // namespace

TEST_CASE("anti-aliased disc and segment cover their analytic area at their position",
          "[render][tracks]") {
  Image<Rgb8> img(64, 48);
  for (const double r : {2.4, 5.0, 11.3}) {
    img.fill(Rgb8{});
    const double cx = 30.37, cy = 21.81;
    epitrack::render::drawDisc(img.view(), cx, cy, r, Rgb8{255, 255, 255});
    INFO("radius " << r);
    // Box-filtered rim: the area is exact to a few percent of the rim length.
    CHECK(coveredArea(img) == Approx(kPi * r * r).margin(0.05 * 2.0 * kPi * r));
    const Eigen::Vector2d c = centroid(img);
    CHECK(c.x() == Approx(cx).margin(0.02));
    CHECK(c.y() == Approx(cy).margin(0.02));
  }
  img.fill(Rgb8{});
  // 30 px long, 2 px wide, round caps: 30 * 2 + pi * 1^2.
  const double x0 = 12.2, y0 = 10.6, x1 = x0 + 30.0 * std::cos(0.4), y1 = y0 + 30.0 * std::sin(0.4);
  epitrack::render::drawSegment(img.view(), x0, y0, x1, y1, 2.0, Rgb8{255, 255, 255});
  CHECK(coveredArea(img) == Approx(60.0 + kPi).margin(3.0));
  const Eigen::Vector2d c = centroid(img);
  CHECK(c.x() == Approx(0.5 * (x0 + x1)).margin(0.05));
  CHECK(c.y() == Approx(0.5 * (y0 + y1)).margin(0.05));
  // Clipped at the image border without touching memory outside (ASan would tell).
  epitrack::render::drawDisc(img.view(), -3.0, 47.5, 6.0, Rgb8{255, 0, 0});
  epitrack::render::drawSegment(img.view(), -20, -20, 100, 80, 3.0, Rgb8{255, 0, 0});
}

TEST_CASE("tracks are drawn where they are, coloured by kind, trails from earlier frames only",
          "[render][tracks]") {
  epitrack::TrackTable tracks;
  // Track 7 moves right 4 px a frame over frames 0-5; track 9 appears in frame 4; track 11 only in
  // frame 6 (after the drawn frame).
  for (int f = 0; f <= 6; ++f) {
    if (f <= 5) tracks.add(f, 7, 10.0 + 4.0 * f, 20.0);
    if (f >= 4 && f <= 5) tracks.add(f, 9, 50.0, 40.0 + 0.0 * f);
    if (f == 6) tracks.add(f, 11, 5.0, 5.0);
  }
  tracks.setFrameCount(7);
  tracks.finalize();
  std::vector<TrackKind> kinds(tracks.observations().size(), TrackKind::kUnused);
  for (std::size_t i = 0; i < kinds.size(); ++i) {
    const auto& ob = tracks.observations()[i];
    if (tracks.trackId(ob.track) == 7) kinds[i] = TrackKind::kInlier;
    if (tracks.trackId(ob.track) == 9) kinds[i] = TrackKind::kOutlier;
  }
  epitrack::render::TrackStyle style;
  style.trail_frames = 3;
  Image<Rgb8> img(64, 48);
  img.fill(Rgb8{});
  epitrack::render::drawTracks(img.view(), tracks, kinds, 5, style);
  const auto at = [&](int x, int y) { return img.constView()(x, y); };
  CHECK(at(30, 20) == style.inlier);   // track 7 now (frame 5)
  CHECK(at(50, 40) == style.outlier);  // track 9 now
  CHECK(at(5, 5) == Rgb8{});           // track 11 is not in frame 5
  // Trail of track 7 back 3 frames, to x = 18; nothing before.
  CHECK(at(20, 20).g > 100);
  CHECK(at(18, 20).g > 100);
  CHECK(at(15, 20) == Rgb8{});
  CHECK(at(10, 20) == Rgb8{});
  // The trail fades: older pieces are darker.
  CHECK(at(20, 20).g < at(27, 20).g);
  // Frame 6: only the unused track 11 (red dot), no trails.
  img.fill(Rgb8{});
  epitrack::render::drawTracks(img.view(), tracks, kinds, 6, style);
  CHECK(at(5, 5) == style.unused);
  CHECK(at(30, 20) == Rgb8{});
}

TEST_CASE("side by side puts both halves next to each other unchanged", "[render][tracks]") {
  Image<Rgb8> left(5, 3), right(5, 3), both(10, 3);
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 5; ++x) {
      left.view()(x, y) = Rgb8{static_cast<uint8_t>(x), static_cast<uint8_t>(y), 1};
      right.view()(x, y) = Rgb8{static_cast<uint8_t>(x), static_cast<uint8_t>(y), 2};
    }
  epitrack::render::sideBySide(left.constView(), right.constView(), both.view());
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 10; ++x) {
      const Rgb8 want{static_cast<uint8_t>(x % 5), static_cast<uint8_t>(y),
                      static_cast<uint8_t>(x < 5 ? 1 : 2)};
      CHECK(both.constView()(x, y) == want);
    }
}
