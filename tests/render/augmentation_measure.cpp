// augmentation_measure: the figures of issue 23 for any solve's output directory, including one
// written by an older epitrack-solve that did not report them: how upright the scene's +z stands
// in the images and how much of each image the virtual object covers.
//   augmentation_measure DIR [OBJECT X,Y,Z SCALE]
// reads DIR/cameras.tum and DIR/intrinsics.txt (scene frame), renders OBJECT (towers, cube,
// axes; default towers at 0,0,0, scale 1: the placement before issue 23) alone in every camera
// and prints one JSON line: solved frames, frames with >= 0.5 % coverage, median coverage and the
// median upright cosine. A test helper, not an installed command.
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "hal/io/text_formats.hpp"
#include "tools/render/object_placement.hpp"

int main(int argc, char** argv) {
  using namespace epitrack;
  if (argc != 2 && argc != 5) {
    std::fprintf(stderr, "usage: augmentation_measure DIR [OBJECT X,Y,Z SCALE]\n");
    return 2;
  }
  const std::string dir = argv[1];
  const std::string object = argc == 5 ? argv[2] : "towers";
  io::AugmentedObject placed;
  placed.placement = "given";
  if (argc == 5) {
    double x = 0, y = 0, z = 0;
    char tail = 0;
    if (std::sscanf(argv[3], "%lf,%lf,%lf%c", &x, &y, &z, &tail) != 3 ||
        std::sscanf(argv[4], "%lf%c", &placed.scale, &tail) != 1 || !(placed.scale > 0.0)) {
      std::fprintf(stderr, "augmentation_measure: expected X,Y,Z and a positive SCALE\n");
      return 2;
    }
    placed.at = Eigen::Vector3d(x, y, z);
  }
  placed.height = render::objectUnitHeight(object) * placed.scale;
  if (!(placed.height > 0.0)) {
    std::fprintf(stderr, "augmentation_measure: OBJECT must be towers, cube or axes\n");
    return 2;
  }
  io::Reconstruction rec;
  std::vector<hal::TrajectoryEntry> poses;
  std::string error;
  if (!hal::readIntrinsicsFile(dir + "/intrinsics.txt", rec.intrinsics, error) ||
      !hal::readTrajectoryFile(dir + "/cameras.tum", poses, error)) {
    std::fprintf(stderr, "augmentation_measure: %s\n", error.c_str());
    return 1;
  }
  for (const hal::TrajectoryEntry& e : poses) {
    io::SolvedCamera c;
    c.solved = true;
    c.R_wc = e.rotation.toRotationMatrix();
    c.p_wc = e.position;
    rec.cameras.push_back(c);
  }
  std::vector<double> per_frame;
  render::measureObjectView(rec, render::makeObjectMesh(object, placed.at, placed.scale), placed,
                            0.005, &per_frame);
  if (std::getenv("AUGMENTATION_MEASURE_FRAMES") != nullptr) {
    for (std::size_t i = 0; i < per_frame.size(); ++i)
      std::fprintf(stderr, "frame %zu coverage %.3f %%\n", i, 100.0 * per_frame[i]);
  }
  std::printf(
      "{\"solved_frames\": %d, \"visible_frames\": %d, \"visible_percent\": %.1f, "
      "\"median_coverage_percent\": %.3f, \"upright_cosine_median\": %.3f}\n",
      placed.solved_frames, placed.visible_frames,
      placed.solved_frames > 0 ? 100.0 * placed.visible_frames / placed.solved_frames : 0.0,
      100.0 * placed.median_coverage, placed.upright_cosine_median);
  return 0;
}
