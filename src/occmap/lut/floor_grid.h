// FloorGrid: the occupancy map's discretisation of the support plane (the paper's O[x, y]).
//
// Cell (i, j), 0 <= i < cells_x, 0 <= j < cells_y, covers the square
//   [origin_x_m + i * cell_size_m, origin_x_m + (i + 1) * cell_size_m) x (same in y)
// on the plane; its index is j * cells_x + i (x varies fastest). Rounding a floor point to its
// cell is the paper's "rounded to the nearest integers" with cell centres on integers.
// Map images are drawn with +x to the right and +y up: image row 0 holds j = cells_y - 1.
//
//   FloorGrid grid{.origin_x_m = -3, .origin_y_m = -9, .cells_x = 480, .cells_y = 1440,
//                  .cell_size_m = 0.025};
//   int64_t cell = grid.CellAt(1.0, 2.0);   // -1 when off the grid
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>

#include "occmap/util/hash.h"
#include "occmap/util/status.h"
#include "occmap/util/yaml_util.h"

namespace occmap {

struct FloorGrid {
  // The largest grid occmap accepts: 2^28 cells (a 1 GiB map of 32-bit values).
  static constexpr int64_t kMaxCells = int64_t{1} << 28;

  double origin_x_m = 0;  // world x of the corner of cell (0, 0) (its smallest x)
  double origin_y_m = 0;
  int cells_x = 0;
  int cells_y = 0;
  double cell_size_m = 0;

  Status Validate() const;
  int64_t num_cells() const { return int64_t{cells_x} * cells_y; }
  double size_x_m() const { return cells_x * cell_size_m; }
  double size_y_m() const { return cells_y * cell_size_m; }

  // The cell containing the point, or -1 off the grid.
  int64_t CellAt(double x_m, double y_m) const {
    const double fi = std::floor((x_m - origin_x_m) / cell_size_m);
    const double fj = std::floor((y_m - origin_y_m) / cell_size_m);
    if (!(fi >= 0 && fj >= 0 && fi < cells_x && fj < cells_y)) return -1;
    return static_cast<int64_t>(fj) * cells_x + static_cast<int64_t>(fi);
  }
  Eigen::Vector2d CellCenter(int64_t index) const {
    const int64_t i = index % cells_x, j = index / cells_x;
    return {origin_x_m + (static_cast<double>(i) + 0.5) * cell_size_m,
            origin_y_m + (static_cast<double>(j) + 0.5) * cell_size_m};
  }
  void AppendToHash(Hasher& hasher) const;
  friend bool operator==(const FloorGrid&, const FloorGrid&) = default;
};

// Reads origin_m, cell_size_m and exactly one of cells or size_m (a whole number of cells) from
// a `floor:` map of a site or scene file, with located errors; other keys are the caller's.
Result<FloorGrid> ParseFloorGrid(const YamlField& floor);

}  // namespace occmap
