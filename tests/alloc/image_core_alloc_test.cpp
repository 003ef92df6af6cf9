#include <catch2/catch.hpp>

#include "algo/image/image.hpp"
#include "algo/image/pyramid.hpp"
#include "algo/image/scharr.hpp"
#include "hal/frame_source.hpp"
#include "hal/io/file_util.hpp"
#include "hal/io/image_codec.hpp"
#include "tests/alloc/counting_allocator.hpp"
#include "tests/support/test_support.hpp"

using epitrack::Image;
using epitrack::Pyramid;
using epitrack::test::AllocationScope;

TEST_CASE("The counting allocator sees operator new and malloc", "[alloc]") {
  AllocationScope scope;
  auto* p = new int(3);
  asm volatile("" : : "r"(p) : "memory");  // keep the compiler from eliding the pair
  delete p;
  REQUIRE(scope.count() >= 1);
  if (epitrack::test::mallocIsCounted()) {
    AllocationScope s2;
    void* m = std::malloc(10);
    asm volatile("" : : "r"(m) : "memory");
    std::free(m);
    REQUIRE(s2.count() == 1);
  }
}

TEST_CASE("Rebuilding a pyramid and gradients for same-size frames allocates nothing",
          "[alloc][pyramid]") {
  Image<uint8_t> a(704, 576);
  Image<uint8_t> b(704, 576);
  epitrack::test::fillRandom(a.view(), 1);
  epitrack::test::fillRandom(b.view(), 2);
  Pyramid pyr(704, 576, 4);
  Image<int16_t> dx(704, 576);
  Image<int16_t> dy(704, 576);
  AllocationScope scope;
  for (int i = 0; i < 20; ++i) {
    REQUIRE(pyr.build((i % 2 == 0 ? a : b).constView()) == Pyramid::Status::kOk);
    epitrack::scharrGradients(pyr.level(1), dx.view().subView(0, 0, 352, 288),
                              dy.view().subView(0, 0, 352, 288));
  }
  REQUIRE(scope.count() == 0);
}

TEST_CASE("Replaying a PGM frame directory allocates nothing per frame", "[alloc][replay]") {
  epitrack::test::TempDir dir("alloc-replay");
  Image<uint8_t> img(160, 120);
  std::string err;
  for (int i = 0; i < 12; ++i) {
    epitrack::test::fillRandom(img.view(), static_cast<uint32_t>(i));
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.pgm", i);
    REQUIRE(epitrack::hal::writePgm(dir.file(name), img.constView(), err));
  }
  auto src = epitrack::hal::openFrameSource(dir.path(), {}, err);
  REQUIRE(src);
  epitrack::hal::Frame f;
  REQUIRE(src->next(f) == epitrack::hal::FrameStatus::kOk);  // warm-up
  REQUIRE(src->next(f) == epitrack::hal::FrameStatus::kOk);
  AllocationScope scope;
  int frames = 0;
  while (src->next(f) == epitrack::hal::FrameStatus::kOk) ++frames;
  REQUIRE(frames == 10);
  REQUIRE(scope.count() == 0);
}
