#include <catch2/catch.hpp>

#include <vector>

#include "algo/sfm/live_map.hpp"
#include "tests/alloc/counting_allocator.hpp"
#include "tools/synth/synthetic_sequence.hpp"

// The live map's process() never allocates, also on the initialisation path of a plane (H-RANSAC,
// model selection, five-point E-RANSAC): every frame's tracks are made before the scope opens.

using namespace epitrack;
using epitrack::test::AllocationScope;

TEST_CASE("LiveMap allocates nothing per frame, the initialisation on a plane included",
          "[alloc][sfm]") {
  synth::SynthOptions so;
  so.kind = synth::SceneKind::kOrbit;
  so.frames = 60;
  so.target_wander = 0.5;
  synth::SyntheticSequence seq(so);
  LiveMapOptions options;
  // The landmarks in their own order, floor first: the first 300 are (nearly all) on the floor.
  std::vector<std::vector<TrackedFeature>> frames(60);
  std::vector<synth::LandmarkObservation> lm;
  seq.visibleLandmarks(0, lm);
  std::vector<int> ids;
  for (const auto& l : lm)
    if (static_cast<int>(ids.size()) < options.max_features) ids.push_back(l.id);
  for (int f = 0; f < 60; ++f) {
    seq.visibleLandmarks(f, lm);
    for (const int id : ids)
      for (const auto& l : lm)
        if (l.id == id)
          frames[static_cast<std::size_t>(f)].push_back(
              {l.id, static_cast<float>(l.x), static_cast<float>(l.y), f});
  }
  LiveMap map(options, CameraIntrinsics::centered(so.width, so.height, so.focal));
  std::size_t allocations = 0;
  bool tracked = false;
  {
    AllocationScope scope;
    for (const auto& features : frames)
      tracked = map.process(features).status == LiveStatus::kTracking || tracked;
    allocations = scope.count();
  }
  CHECK(tracked);  // the plane path ran to a map
  CHECK(allocations == 0);
}
