#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace epitrack::synth {

/// A rectangle in space carrying a procedural texture: a grid of square cells of random gray
/// levels. Every interior grid vertex where two edge directions meet is a corner in the image,
/// and these are the ground-truth landmarks.
struct TexturedQuad {
  Eigen::Vector3d origin;  ///< a corner of the rectangle (world)
  Eigen::Vector3d axis_u;  ///< unit vector along the first side
  Eigen::Vector3d axis_v;  ///< unit vector along the second side (orthogonal to axis_u)
  Eigen::Vector3d normal;  ///< axis_u x axis_v
  double cell = 0.25;      ///< cell side (metres)
  int cells_u = 0;         ///< the sides are cells_u * cell and cells_v * cell long
  int cells_v = 0;
  double brightness = 1.0;  ///< constant shading factor of this face
  /// Cell intensities, then coarser levels (each 2x2 averaged), for box-filtered lookups.
  std::vector<std::vector<float>> levels;
  std::vector<int> level_cols;
  std::vector<int> level_rows;

  [[nodiscard]] double sizeU() const { return cells_u * cell; }
  [[nodiscard]] double sizeV() const { return cells_v * cell; }
  [[nodiscard]] float cellValue(int i, int j) const {
    return levels[0][static_cast<std::size_t>(j) * static_cast<std::size_t>(cells_u) +
                     static_cast<std::size_t>(i)];
  }
  /// Mean texture intensity over the box [u-wu/2, u+wu/2] x [v-wv/2, v+wv/2] (metres), the
  /// exact area integral of the cell function on a pyramid level with at most 3x3 cells per box.
  [[nodiscard]] float boxLookup(double u, double v, double wu, double wv) const;
  /// Mean texture intensity over the parallelogram {(u, v) + s a + t b : |s|, |t| <= 1/2}
  /// (metres): the exact area integral (polygon clipping against each covered cell) when it
  /// covers at most 36 cells, otherwise box-filtered pieces along its long side.
  [[nodiscard]] float parallelogramLookup(double u, double v, const Eigen::Vector2d& a,
                                          const Eigen::Vector2d& b) const;
};

/// A 3-D landmark: a texture corner, its id and the quad it lies on.
struct Landmark3d {
  int id = 0;
  int quad = 0;
  Eigen::Vector3d position;
};

struct Scene {
  std::vector<TexturedQuad> quads;
  std::vector<Landmark3d> landmarks;
  float background = 110.0F;  ///< gray level where no surface is hit
};

/// Adds a quad with a seeded random cell texture and a shading factor from its orientation.
void addTexturedQuad(Scene& scene, const Eigen::Vector3d& origin, const Eigen::Vector3d& axis_u,
                     const Eigen::Vector3d& axis_v, double cell, int cells_u, int cells_v,
                     uint64_t seed);

/// An open room (z up, ground z = 0): a 24 x 24 m textured floor, four 8 m textured walls and
/// a seeded arrangement of textured boxes within 3.5 m of the origin.
Scene makeRoomScene(uint64_t seed);

/// The room's floor and walls with 14 seeded textured pillars (0.3-0.75 m wide, 1.2-2.4 m high)
/// at 0.3-4.6 m from the origin, so that a camera orbiting at 6.5 m sees them cross each other.
Scene makeOcclusionScene(uint64_t seed);

/// A single textured wall (the plane y = 4, facing -y), 16 x 10 m.
Scene makePlanarScene(uint64_t seed);

/// Collects the landmarks of every quad: interior grid vertices whose surrounding cells change in
/// both directions by at least `min_contrast` gray levels (after shading).
void collectLandmarks(Scene& scene, double min_contrast = 24.0);

}  // namespace epitrack::synth
