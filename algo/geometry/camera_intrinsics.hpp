#pragma once

namespace epitrack {

/// Pinhole intrinsics (ARCHITECTURE.md "Conventions of geometry"): no skew, pixel origin at the
/// centre of the top-left pixel; optional radial distortion mapping normalized undistorted
/// (x, y) to (x, y) * (1 + k1 r^2 + k2 r^4).
struct CameraIntrinsics {
  double fx = 0.0;
  double fy = 0.0;
  double cx = 0.0;
  double cy = 0.0;
  int width = 0;
  int height = 0;
  double k1 = 0.0;
  double k2 = 0.0;

  /// Square pixels with the principal point at the image centre ((w-1)/2, (h-1)/2), the model
  /// focal self-calibration assumes.
  static CameraIntrinsics centered(int width, int height, double focal) {
    CameraIntrinsics k;
    k.fx = k.fy = focal;
    k.cx = (width - 1) * 0.5;
    k.cy = (height - 1) * 0.5;
    k.width = width;
    k.height = height;
    return k;
  }
  [[nodiscard]] bool hasDistortion() const { return k1 != 0.0 || k2 != 0.0; }
};

}  // namespace epitrack
