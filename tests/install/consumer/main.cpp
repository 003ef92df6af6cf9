// A project outside the tree using the installed package.
#include <cstdio>
#include <string>

#include <epitrack/algo/image/image.hpp>
#include <epitrack/algo/image/pyramid.hpp>
#include <epitrack/hal/io/image_codec.hpp>

int main() {
  epitrack::Image<uint8_t> img(352, 288);
  img.fill(90);
  epitrack::Pyramid pyr(352, 288, 3);
  if (pyr.build(img.constView()) != epitrack::Pyramid::Status::kOk) return 1;
  std::vector<uint8_t> pgm;
  epitrack::hal::encodePgm(img.constView(), pgm);
  epitrack::hal::GrayImageDecoder dec;
  epitrack::Image<uint8_t> back;
  std::string err;
  if (!dec.decode(pgm.data(), pgm.size(), back, err)) return 2;
  std::printf("levels %d %dx%d\n", pyr.levelCount(), pyr.level(2).width, pyr.level(2).height);
  return 0;
}
