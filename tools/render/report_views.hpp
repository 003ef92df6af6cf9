#pragma once

// The geometric views of report.html: the top view of the camera path over the point cloud, and
// the scene-frame section (issue 23: the ground, the up direction and the object, seen from the
// side, with one augmented frame showing them and a warning when the choice is weak).

#include <string>

#include "tools/export/reconstruction.hpp"
#include "tools/render/report_writer.hpp"

namespace epitrack::render {

std::string topViewSection(const io::Reconstruction& rec, const ReportOptions& options);
std::string sceneFrameSection(const io::Reconstruction& rec, const ReportOptions& options);

}  // namespace epitrack::render
