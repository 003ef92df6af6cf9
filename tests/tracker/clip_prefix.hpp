#pragma once

// The first frames of the 704x576 orbit of tests/tracker/orbit_clip.hpp (the orbit's motion does
// not depend on the clip length), clean or with seeded noise, rendered once per process: tests
// that need 100-150 frames do not render all 340.

#include <map>
#include <utility>

#include "tests/tracker/orbit_clip.hpp"

namespace epitrack::test {

/// The first `frames` frames of orbitClip() (same scene, size, focal and seed).
inline const RenderedClip& orbitPrefix(int frames) {
  static std::map<int, RenderedClip> cache;
  auto it = cache.find(frames);
  if (it == cache.end()) {
    synth::SynthOptions o;
    o.kind = synth::SceneKind::kOrbit;
    o.frames = frames;
    o.width = 704;
    o.height = 576;
    o.focal = 600.0;
    o.seed = 1;
    it = cache.emplace(frames, renderClip(o)).first;
  }
  return it->second;
}

/// orbitPrefix(frames) with Gaussian noise of `sigma` gray levels (seed 7), made once per
/// (frames, sigma); sigma 0 is orbitPrefix itself.
inline const RenderedClip& noisyOrbitPrefix(int frames, double sigma) {
  if (!(sigma > 0.0)) return orbitPrefix(frames);
  static std::map<std::pair<int, double>, RenderedClip> cache;
  const auto key = std::make_pair(frames, sigma);
  auto it = cache.find(key);
  if (it == cache.end()) it = cache.emplace(key, addNoise(orbitPrefix(frames), sigma, 7)).first;
  return it->second;
}

}  // namespace epitrack::test
