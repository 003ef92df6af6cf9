#pragma once

#include "algo/geometry/pose.hpp"
#include "algo/sfm/bundle_adjustment.hpp"

namespace epitrack {

/// A frame's pose as a camera of the bundle adjustment and back (the solver's and the live
/// map's frames; both are world-to-camera).
inline BaCamera toBa(const PoseCw& p) { return BaCamera{p.R_cw, p.t_cw}; }
inline PoseCw fromBa(const BaCamera& c) {
  PoseCw p;
  p.R_cw = c.R_cw;
  p.t_cw = c.t_cw;
  return p;
}

}  // namespace epitrack
