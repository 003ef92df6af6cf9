#pragma once

namespace epitrack {

/// SolverOptions::detect_distortion's trial (Solver::adjustDetectingDistortion): the final
/// adjustments run as a pinhole and, from the same start, with k1 and k2 free (in the key-frame
/// mode also the registration's global adjustments, until a lens is found).
struct DistortionTrial {
  bool tried = false;                ///< the trial ran
  bool detected = false;             ///< its k1, k2 were kept
  int views = 0;                     ///< frames or views registered when it ran (the last trial)
  double k1 = 0.0, k2 = 0.0;         ///< the lens it found, kept or not
  double max_displacement_px = 0.0;  ///< the largest pixel displacement of that k1, k2
  double median_before_px = 0.0;     ///< adjusted cameras' median reprojection error, pinhole
  double median_after_px = 0.0;      ///< and with the trial's k1, k2
  /// Key frames (SolverOptions::keyframe_lens_reregistration): the views registered again from
  /// the initial pair with the lens the first registration ended with, and which was kept, by
  /// the median reprojection error of every observation (px) after each.
  bool reregistered = false;
  bool reregistration_kept = false;
  double first_registration_median_px = 0.0;
  double reregistration_median_px = 0.0;
};

}  // namespace epitrack
