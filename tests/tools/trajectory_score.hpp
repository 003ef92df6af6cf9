#pragma once

// The tools tests' scoring of a solve: epitrack-eval's metrics of a cameras.tum against a
// ground-truth trajectory file (association by frame index, similarity alignment).

#include <catch2/catch.hpp>

#include <string>
#include <vector>

#include "hal/io/text_formats.hpp"
#include "tools/eval/trajectory_metrics.hpp"

namespace epitrack::test {

inline eval::TrajectoryMetrics scoreTrajectoryFiles(const std::string& groundtruth,
                                                    const std::string& estimate) {
  std::vector<hal::TrajectoryEntry> g, e;
  std::string error;
  INFO(groundtruth << " vs " << estimate);
  REQUIRE(hal::readTrajectoryFile(groundtruth, g, error));
  REQUIRE(hal::readTrajectoryFile(estimate, e, error));
  eval::TrajectoryMetrics m;
  REQUIRE(eval::evaluateTrajectory(g, e, 0.01, m, error));
  return m;
}

}  // namespace epitrack::test
