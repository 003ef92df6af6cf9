#pragma once

// A reader of COLMAP's text model (cameras.txt, images.txt, points3D.txt), used by the tests to
// check what colmap_export writes, and a consistency check of the cross references.

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace epitrack::io {

struct ColmapCamera {
  int64_t id = 0;
  std::string model;
  int width = 0;
  int height = 0;
  std::vector<double> params;
};

struct ColmapPoint2D {
  double x = 0.0;  ///< COLMAP pixel convention (origin at the corner of the top-left pixel)
  double y = 0.0;
  int64_t point3d_id = -1;  ///< -1: not triangulated
};

struct ColmapImage {
  int64_t id = 0;
  Eigen::Quaterniond q_cw = Eigen::Quaterniond::Identity();  ///< world-to-camera rotation
  Eigen::Vector3d t_cw = Eigen::Vector3d::Zero();            ///< x_c = R_cw X + t_cw
  int64_t camera_id = 0;
  std::string name;
  std::vector<ColmapPoint2D> points;
};

struct ColmapPoint3D {
  int64_t id = 0;
  Eigen::Vector3d X = Eigen::Vector3d::Zero();
  int r = 0, g = 0, b = 0;
  double error = 0.0;
  std::vector<std::pair<int64_t, int>> track;  ///< (IMAGE_ID, POINT2D_IDX)
};

struct ColmapModel {
  std::vector<ColmapCamera> cameras;
  std::vector<ColmapImage> images;
  std::vector<ColmapPoint3D> points;
};

bool parseColmapCameras(const std::string& text, std::vector<ColmapCamera>& cameras,
                        std::string& error);
bool parseColmapImages(const std::string& text, std::vector<ColmapImage>& images,
                       std::string& error);
bool parseColmapPoints3D(const std::string& text, std::vector<ColmapPoint3D>& points,
                         std::string& error);
/// Reads DIR/cameras.txt, DIR/images.txt and DIR/points3D.txt.
bool readColmapModel(const std::string& dir, ColmapModel& model, std::string& error);

/// Checks the cross references: unique ids; every image names an existing camera; every
/// POINT3D_ID of an image exists and its track holds (image, index); every track entry names an
/// existing image whose 2D point at that index refers back to the point; the number of parameters
/// fits the camera model. Returns false with the first problem found.
bool checkColmapConsistency(const ColmapModel& model, std::string& error);

}  // namespace epitrack::io
