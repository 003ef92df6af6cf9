#include <catch2/catch.hpp>

#include <cstdint>
#include <vector>

#include "algo/geometry/essential_five_point.hpp"
#include "algo/image/image.hpp"
#include "algo/matching/descriptor_matcher.hpp"
#include "algo/matching/feature_extractor.hpp"
#include "tests/alloc/counting_allocator.hpp"
#include "tests/geometry/two_view_scene.hpp"
#include "tools/synth/synthetic_sequence.hpp"

// The per-frame parts of the descriptor matcher: extraction (pyramid, detection, description),
// matching and the five-point RANSAC allocate nothing once constructed. (DescriptorTracker's
// clip-level store of every frame's keypoints grows with the clip, as the TrackTable it feeds.)

using namespace epitrack;
using epitrack::test::AllocationScope;

TEST_CASE("Feature extraction, matching and E-RANSAC allocate nothing once constructed",
          "[alloc][matching]") {
  synth::SynthOptions so;
  so.kind = synth::SceneKind::kOrbit;
  so.frames = 40;
  so.width = 320;
  so.height = 240;
  so.focal = 300.0;
  const synth::SyntheticSequence seq(so);
  synth::FrameRenderer renderer(seq);
  Image<uint8_t> a, b;
  renderer.render(0, a);
  renderer.render(24, b);
  FeatureExtractorOptions fo;
  fo.max_features = 500;
  FeatureExtractor fx(fo, so.width, so.height);
  std::vector<Keypoint> ka(500), kb(500);
  std::vector<BinaryDescriptor> ua(500), oa(500), ub(500), ob(500);
  DescriptorMatcher matcher(500);
  std::vector<DescriptorMatch> matches(500);
  int na = 0, nb = 0, n = 0;
  fx.extract(a.constView(), {}, ka, ua, oa, na);  // warm-up (first call)
  std::size_t extract_allocs = 0, match_allocs = 0;
  {
    AllocationScope scope;
    fx.extract(a.constView(), {}, ka, ua, oa, na);
    fx.extract(b.constView(), {}, kb, ub, ob, nb);
    extract_allocs = scope.count();
  }
  {
    AllocationScope scope;
    matcher.match({ka.data(), static_cast<std::size_t>(na)},
                  {oa.data(), static_cast<std::size_t>(na)},
                  {kb.data(), static_cast<std::size_t>(nb)},
                  {ob.data(), static_cast<std::size_t>(nb)}, {}, matches, n);
    match_allocs = scope.count();
  }
  CHECK(na > 200);
  CHECK(n > 50);
  CHECK(extract_allocs == 0);
  CHECK(match_allocs == 0);

  EssentialRansac er(400);
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    const auto s = test::makeTwoViewScene(seed, 300, 0.5, 0.4);
    std::vector<Eigen::Vector2d> n1, n2;
    for (std::size_t i = 0; i < s.x1.size(); ++i) {
      n1.push_back(s.normalize(s.x1[i]));
      n2.push_back(s.normalize(s.x2[i]));
    }
    EssentialRansacOptions eo;
    eo.focal_px = s.f;
    EssentialRansacResult r;
    std::size_t allocs = 0;
    EssentialRansac::Status st;
    {
      AllocationScope scope;
      st = er.estimate(n1, n2, eo, r);
      allocs = scope.count();
    }
    INFO("seed " << seed);
    CHECK(st == EssentialRansac::Status::kOk);
    CHECK(allocs == 0);
  }
}
