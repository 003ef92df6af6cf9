#include <catch2/catch.hpp>

#include <cstdio>
#include <vector>

#include "algo/image/image.hpp"
#include "algo/sfm/live_tracker.hpp"
#include "tests/alloc/counting_allocator.hpp"
#include "tools/synth/synthetic_sequence.hpp"

// The device loop (FeatureTracker + LiveMap, exactly what epitrack-device runs per frame) makes no
// heap allocation from the first frame on: 500 replayed frames of a rendered orbit, including the
// initialisation, keyframes with triangulation and windowed bundle adjustment, a tracking loss
// (blank frames) and the re-initialisation after it; with self-calibration; with a rolling-shutter
// readout. The map's track predictions (LiveMapOptions::map_prediction, on by default) run on
// every tracked frame.

using epitrack::Image;
using epitrack::test::AllocationScope;

TEST_CASE("The live device loop allocates nothing over 500 replayed frames", "[alloc][device]") {
  constexpr int kFrames = 500;
  constexpr int kWidth = 256;
  constexpr int kHeight = 192;
  // 160 rendered frames replayed forth and back (the camera reverses along its orbit): 500 frames
  // of tracking for a third of the rendering (the test also runs under qemu).
  constexpr int kRendered = 160;
  epitrack::synth::SynthOptions so;
  so.kind = epitrack::synth::SceneKind::kOrbit;
  so.frames = kRendered;
  so.width = kWidth;
  so.height = kHeight;
  so.focal = 220.0;
  so.target_wander = 0.5;
  so.noise_sigma = 1.0;
  const epitrack::synth::SyntheticSequence sequence(so);
  epitrack::synth::FrameRenderer renderer(sequence);
  std::vector<Image<uint8_t>> rendered;
  rendered.reserve(kRendered);
  for (int i = 0; i < kRendered; ++i) {
    rendered.emplace_back(kWidth, kHeight);
    renderer.render(i, rendered.back());
  }
  std::vector<Image<uint8_t>> frames;
  frames.reserve(kFrames);
  for (int i = 0; i < kFrames; ++i) {
    const int period = 2 * (kRendered - 1);
    const int k = i % period;
    const auto& src = rendered[static_cast<std::size_t>(k < kRendered ? k : period - k)];
    frames.emplace_back(kWidth, kHeight);
    for (int y = 0; y < kHeight; ++y)
      for (int x = 0; x < kWidth; ++x) frames.back().view()(x, y) = src.constView()(x, y);
  }
  // Frames 300..304 blank: every track dies, tracking is lost and the map restarts.
  for (int i = 300; i < 305; ++i) {
    auto v = frames[static_cast<std::size_t>(i)].view();
    for (int y = 0; y < kHeight; ++y)
      for (int x = 0; x < kWidth; ++x) v(x, y) = 128;
  }

  epitrack::FeatureTrackerOptions to;
  to.max_features = 150;
  epitrack::LiveMapOptions mo;
  mo.max_features = 150;
  mo.max_points = 1000;
  const auto K = epitrack::CameraIntrinsics::centered(kWidth, kHeight, so.focal);
  epitrack::LiveTracker tracker(to, mo, K);
  epitrack::LiveFrameOutput out;

  REQUIRE(mo.map_prediction);
  int tracking = 0, lost = 0, initializations = 0, keyframes = 0;
  long predicted = 0;  // tracks aligned from a map prediction
  std::size_t allocations = 0;
  for (int i = 0; i < kFrames; ++i) {
    AllocationScope scope;
    REQUIRE(tracker.process(frames[static_cast<std::size_t>(i)].constView(), out) ==
            epitrack::LiveTracker::Status::kOk);
    allocations += scope.count();
    tracking += out.map.status == epitrack::LiveStatus::kTracking ? 1 : 0;
    lost += out.map.status == epitrack::LiveStatus::kLost ? 1 : 0;
    initializations += out.map.initialized ? 1 : 0;
    keyframes += out.map.keyframe ? 1 : 0;
    predicted += tracker.tracker().lastStats().predicted;
  }
  std::printf(
      "device alloc: %d tracking, %d lost, %d initialisations, %d keyframes, %d points, "
      "%ld tracks predicted by the map, map %.2f MiB reserved\n",
      tracking, lost, initializations, keyframes, tracker.map().pointCount(), predicted,
      static_cast<double>(tracker.map().reservedBytes()) / (1024.0 * 1024.0));
  // The run covered every path of the loop.
  CHECK(initializations >= 2);
  CHECK(lost >= 1);
  CHECK(keyframes >= 10);
  CHECK(tracking > 400);
  CHECK(predicted > 100L * tracking);  // the prediction path ran on the tracked frames
  CHECK(allocations == 0);

  // Without intrinsics: self-calibration (F and H RANSAC per pair, the multi-pair focal search)
  // and then the same loop, still without allocation.
  mo.self_calibrate = true;
  const auto K_guess = epitrack::CameraIntrinsics::centered(kWidth, kHeight, 1.2 * kWidth);
  epitrack::LiveTracker selfcal(to, mo, K_guess);
  std::size_t sc_allocations = 0;
  int calibrated_at = -1;
  int sc_tracking = 0;
  for (int i = 0; i < 250; ++i) {
    AllocationScope scope;
    REQUIRE(selfcal.process(frames[static_cast<std::size_t>(i)].constView(), out) ==
            epitrack::LiveTracker::Status::kOk);
    sc_allocations += scope.count();
    if (out.map.calibrated) calibrated_at = i;
    sc_tracking += out.map.status == epitrack::LiveStatus::kTracking ? 1 : 0;
  }
  std::printf("device alloc, self-calibrated: focal %.1f (true %.1f) at frame %d, %d tracking\n",
              selfcal.map().intrinsics().fx, so.focal, calibrated_at, sc_tracking);
  CHECK(calibrated_at > 0);
  CHECK_FALSE(selfcal.map().focalFallback());
  CHECK(sc_tracking > 100);
  CHECK(sc_allocations == 0);

  // With a rolling-shutter readout (epitrack-device readout_ms): each tracked frame's pose and
  // motion refined after the PnP, the keyframes' motions in the windowed adjustment, the loss and
  // the restart; still no allocation.
  mo.self_calibrate = false;
  mo.readout_frames = 0.9;
  epitrack::LiveTracker rolling(to, mo, K);
  std::size_t rs_allocations = 0;
  int rs_tracking = 0, rs_lost = 0, rs_keyframes = 0;
  for (int i = 0; i < 350; ++i) {
    AllocationScope scope;
    REQUIRE(rolling.process(frames[static_cast<std::size_t>(i)].constView(), out) ==
            epitrack::LiveTracker::Status::kOk);
    rs_allocations += scope.count();
    rs_tracking += out.map.status == epitrack::LiveStatus::kTracking ? 1 : 0;
    rs_lost += out.map.status == epitrack::LiveStatus::kLost ? 1 : 0;
    rs_keyframes += out.map.keyframe ? 1 : 0;
  }
  std::printf("device alloc, rolling shutter: %d tracking, %d lost, %d keyframes\n", rs_tracking,
              rs_lost, rs_keyframes);
  CHECK(rs_tracking > 250);
  CHECK(rs_lost >= 1);
  CHECK(rs_keyframes >= 10);
  CHECK(rs_allocations == 0);
}
