// ROS map_server maps: the occupancy map as a PGM image and its YAML, for robots (nav2's and
// ROS 1's map_server, and their map_saver's conventions).
//
// The YAML (next to the image, which it names relative to itself):
//   image: static.pgm
//   mode: trinary
//   resolution: 0.05             # metres per pixel = the floor grid's cell size
//   origin: [-3.0, -9.0, 0.0]    # x, y (m) and yaw of the lower-left pixel's corner = cell (0, 0)
//   negate: 0
//   occupied_thresh: 0.65
//   free_thresh: 0.196
// The PGM (binary P5, 8 bits): one pixel per floor cell, +x to the right and +y up, so its
// first row is the grid's last (j = cells_y - 1, the largest y), as map_server expects.
// Values as map_saver writes them: occupied 0, free 254, unknown 205. map_server reads a
// pixel's occupancy as p = (255 - v) / 255 (negate 0): occupied when p > occupied_thresh,
// free when p < free_thresh, else unknown (205 gives p = 0.19608, just above 0.196).
//
// Two maps: a frame's (RosMapFromOccupancy: unseen cells unknown) and a long run's static map
// (StaticMapAccumulator: cells occupied in more than a fraction of the frames that saw them).
//
//   StaticMapAccumulator acc(grid);  for (each frame) acc.Add(map);
//   OCCMAP_RETURN_IF_ERROR(WriteRosMap(dir / "static.yaml", acc.StaticMap(0.5)));
//   OCCMAP_ASSIGN_OR_RETURN(RosMap back, ReadRosMap(dir / "static.yaml"));
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "occmap/fusion/occupancy_map.h"
#include "occmap/lut/floor_grid.h"
#include "occmap/util/status.h"

namespace occmap {

enum class RosCell : uint8_t { kFree = 0, kOccupied = 1, kUnknown = 2 };

struct RosMap {
  FloorGrid grid;               // origin, cell size (the resolution), cells
  std::vector<RosCell> cells;   // grid order: index j * cells_x + i, j = 0 the smallest y
  double yaw_rad = 0;           // of the origin (occmap writes 0)
  RosCell at(int i, int j) const { return cells[static_cast<size_t>(j) * grid.cells_x + i]; }
  friend bool operator==(const RosMap&, const RosMap&) = default;
};

// The values written (map_saver's).
inline constexpr uint8_t kRosOccupiedValue = 0, kRosFreeValue = 254, kRosUnknownValue = 205;

RosMap RosMapFromOccupancy(const OccupancyMap& map);

// Writes `yaml_path` and the PGM beside it (same stem, .pgm), each atomically.
Status WriteRosMap(const std::filesystem::path& yaml_path, const RosMap& map);

// Reads a map_server map as map_server does (mode trinary only; the image a binary 8-bit PGM):
// the YAML's image (relative to the YAML's folder), resolution, origin, negate and thresholds.
// Errors name the file and field: map.yaml:3: resolution: expected a number > 0, found 0.
Result<RosMap> ReadRosMap(const std::filesystem::path& yaml_path);

// Per cell, the frames that saw it (free or occupied) and those in which it was occupied, for
// a static map over a long run (32-bit counts: 6 years at 20 frames a second).
class StaticMapAccumulator {
 public:
  explicit StaticMapAccumulator(const FloorGrid& grid)
      : grid_(grid), seen_(static_cast<size_t>(grid.num_cells()), 0), occupied_(static_cast<size_t>(grid.num_cells()), 0) {}
  void Add(const OccupancyMap& map);  // same grid; CHECKed
  // Occupied: occupied in more than `occupied_fraction` of the frames that saw the cell;
  // free: seen, and occupied in at most that fraction; unknown: never seen.
  RosMap StaticMap(double occupied_fraction) const;
  int64_t frames() const { return frames_; }

 private:
  FloorGrid grid_;
  std::vector<uint32_t> seen_, occupied_;
  int64_t frames_ = 0;
};

}  // namespace occmap
