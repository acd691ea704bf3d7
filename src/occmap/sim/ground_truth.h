// Ground truth of a scene, one frame per line in ground_truth.jsonl (docs/formats.md):
//   {"frame": 12, "time_s": 1.2, "objects": [{"id": 3, "class": "person", "x_m": 1.5, "y_m": 2.0,
//     "footprint_m": [[x, y], ...]}]}
// written by the simulator and read by `occmap eval`. (x_m, y_m) is the object's reference
// point on the floor (a person's centre between the feet, a chair's centre); footprint_m the
// polygon (or polygons' outline) where it touches the floor, counter-clockwise.
//
//   OCCMAP_ASSIGN_OR_RETURN(std::vector<GroundTruthFrame> gt, ReadGroundTruth("gt/ground_truth.jsonl"));
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "occmap/util/status.h"

namespace occmap {

struct GroundTruthObject {
  int64_t id = 0;
  std::string object_class;  // "person", "chair", "robot", "box"
  double x_m = 0, y_m = 0;
  std::vector<Eigen::Vector2d> footprint_m;
};

struct GroundTruthFrame {
  int64_t frame = 0;
  double time_s = 0;
  std::vector<GroundTruthObject> objects;
};

std::string GroundTruthLine(const GroundTruthFrame& frame);  // one JSON line, no newline
Result<std::vector<GroundTruthFrame>> ReadGroundTruth(const std::filesystem::path& path);
Status WriteGroundTruth(const std::filesystem::path& path, const std::vector<GroundTruthFrame>& frames);

}  // namespace occmap
