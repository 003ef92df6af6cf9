#pragma once

namespace epitrack {

/// Huber's M-estimator for a residual of norm e with threshold h (h <= 0: plain least squares).
/// The weight of iteratively reweighted least squares: 1 inside the threshold, h / e beyond it.
inline double huberWeight(double e, double h) { return (h <= 0.0 || e <= h) ? 1.0 : h / e; }

/// The cost whose gradient that weight gives: e^2 / 2 inside, h (e - h / 2) beyond (continuous
/// with its first derivative at e = h).
inline double huberCost(double e, double h) {
  return (h <= 0.0 || e <= h) ? 0.5 * e * e : h * (e - 0.5 * h);
}

}  // namespace epitrack
