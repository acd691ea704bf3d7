// Internals shared by the reference split (split.cc) and the fast one (split_fast.cc); not part
// of the module's interface.
#pragma once

#include <Eigen/Core>
#include <cstdint>

#include "occmap/lut/floor_grid.h"

namespace occmap::split_internal {

// A bounding box grown by one cell on each side, as a small local grid: local cell (a, b)
// is map cell (i0 + a, j0 + b).
struct LocalBox {
  int i0 = 0, j0 = 0;  // map cell of local (0, 0)
  int width = 0, height = 0;
  int Index(int a, int b) const { return b * width + a; }
};

// The centre of a cluster of cells from the exact sums of their indices: x = origin_x + (sum of
// i / n + 0.5) * cell size (the same in any order of the cells, so the fast k-means updates the
// sums by the cells that changed cluster).
inline Eigen::Vector2d MeanCellCentre(const FloorGrid& grid, int64_t sum_i, int64_t sum_j, int64_t n) {
  return {grid.origin_x_m + (static_cast<double>(sum_i) / static_cast<double>(n) + 0.5) * grid.cell_size_m,
          grid.origin_y_m + (static_cast<double>(sum_j) / static_cast<double>(n) + 0.5) * grid.cell_size_m};
}

}  // namespace occmap::split_internal
