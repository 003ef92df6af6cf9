#pragma once

// Which synthetic corners an accuracy table may use (tests/tools/synth_test.cpp,
// tests/tracker/orbit_clip.cpp).

#include <cmath>
#include <cstddef>

#include <Eigen/Dense>

#include "tools/synth/synthetic_sequence.hpp"

namespace epitrack::test {

/// A corner is well conditioned for sub-pixel localisation when its texture cells are large on
/// screen (> 9 px) and its two edge directions are far from parallel (> 45 degrees). Far,
/// foreshortened corners are not: their error along the edges is large for any detector.
inline bool wellConditioned(const synth::SyntheticSequence& seq, const synth::Landmark3d& l,
                            int frame) {
  const synth::TexturedQuad& q = seq.scene().quads[static_cast<std::size_t>(l.quad)];
  const synth::Pose p = seq.pose(frame);
  Eigen::Vector2d c;
  if (!seq.camera().project(p.R_wc.transpose() * (l.position - p.t_wc), c)) return false;
  Eigen::Vector2d dir[2];
  int k = 0;
  for (const Eigen::Vector3d& d : {q.axis_u, q.axis_v}) {
    for (const double s : {-1.0, 1.0}) {
      Eigen::Vector2d n;
      if (!seq.camera().project(p.R_wc.transpose() * (l.position + s * q.cell * d - p.t_wc), n))
        return false;
      if ((n - c).norm() < 9.0) return false;
      if (s > 0) dir[k] = (n - c).normalized();
    }
    ++k;
  }
  return std::abs(dir[0].x() * dir[1].y() - dir[0].y() * dir[1].x()) > 0.7;
}

}  // namespace epitrack::test
