#pragma once

// Where the virtual object of `epitrack-solve --render` stands and how big it is (issue 23 item
// 2), and how well it shows in the clip (the figures summary.json reports).
//
// Unless --object-at / --object-scale are given, the object is put on the ground (scene z = 0)
// where it is in view in the most frames: candidate points are the ground hits of rays through
// the middle and lower part of the image of frames spread over the clip (the middle frames
// first), never behind a camera nor deeper than the reconstructed points that camera sees, plus
// the scene origin; each candidate is sized so that it spans a quarter of the image height at the
// 75th percentile of its distances from the cameras, and the one whose bounding box is well
// inside the image and large enough in the most frames wins.
//
// Typical use, after io::applySceneFrame:
//   rec.object = placeObject(rec, "towers", given_at, given_scale, ObjectPlacementOptions{});
//   const Mesh mesh = makeObjectMesh("towers", rec.object.at, rec.object.scale);
//   measureObjectView(rec, mesh, rec.object);   // visible frames, coverage, upright cosine

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "tools/export/reconstruction.hpp"
#include "tools/render/overlay_renderer.hpp"

namespace epitrack::render {

/// The object of a --render value at `anchor` with size factor `scale` ("towers", "cube",
/// "axes"); an empty mesh for anything else.
Mesh makeObjectMesh(const std::string& object, const Eigen::Vector3d& anchor, double scale);

/// Height (base to top) of the object at scale 1, scene units; 0 for an unknown name.
double objectUnitHeight(const std::string& object);

struct ObjectPlacementOptions {
  /// The object spans this fraction of the image height at this quantile of its distances from
  /// the cameras (the median would leave it small in the frames farther than the median: on a
  /// forward drive it shrinks with the square of the distance in the early frames).
  double image_height_fraction = 0.25;
  double size_depth_quantile = 0.75;
  /// A ground point is "beyond the scene" for a camera when deeper than this quantile of the
  /// depths of the points in front of it.
  double max_depth_quantile = 0.9;
  /// At most this many frames give candidate points (evenly spread over the solved frames).
  int candidate_frames = 48;
  /// A frame has the object in view when its projected bounding box lies in front of the camera,
  /// at least this fraction of the box inside the image ...
  double min_inside_fraction = 0.7;
  /// ... and the part inside covers at least this fraction of the image.
  double min_box_coverage = 0.01;
};

/// The object's placement: the given anchor and scale when both are given; otherwise the
/// automatic choice (see the file comment) for what is not given. Without a ground (rec.ground
/// "none") or a solved camera the given values or (0,0,0) and 1 are kept, placement "default".
/// Fills placement, at, scale and height; the visibility figures are measureObjectView's.
io::AugmentedObject placeObject(const io::Reconstruction& rec, const std::string& object,
                                const std::optional<Eigen::Vector3d>& given_at,
                                const std::optional<double>& given_scale,
                                const ObjectPlacementOptions& options);

/// Cosine between the scene's +z drawn at `anchor` (the image of the segment from anchor to
/// anchor + height * z) and the image's up direction (-y) for a camera T_wc = (R_wc, p_wc):
/// 1 upright, -1 upside down. When the segment is not in front of the camera, the cosine of the
/// camera-frame +z projected onto the image plane. NaN when +z is along the optical axis.
double uprightCosine(const CameraIntrinsics& intrinsics, const Eigen::Matrix3d& R_wc,
                     const Eigen::Vector3d& p_wc, const Eigen::Vector3d& anchor, double height);

/// Renders `mesh` alone in every solved camera of `rec` and fills object.solved_frames,
/// visible_frames (coverage >= min_coverage of the image), median_coverage and
/// upright_cosine_median (at object.at, with object.height); `per_frame`, when given, receives
/// each solved frame's coverage. Allocates a renderer (called once).
void measureObjectView(const io::Reconstruction& rec, const Mesh& mesh, io::AugmentedObject& object,
                       double min_coverage = 0.005, std::vector<double>* per_frame = nullptr);

}  // namespace epitrack::render
