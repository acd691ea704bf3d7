#include "occmap/lut/floor_grid.h"

#include <fmt/core.h>

namespace occmap {

Status FloorGrid::Validate() const {
  if (!std::isfinite(origin_x_m) || !std::isfinite(origin_y_m)) {
    return InvalidInput("origin_m: expected finite numbers");
  }
  if (!(cell_size_m > 0) || !std::isfinite(cell_size_m)) {
    return InvalidInput(fmt::format("cell_size_m: expected a positive number, found {}", cell_size_m));
  }
  if (cells_x <= 0 || cells_y <= 0) {
    return InvalidInput(fmt::format("grid: expected at least 1 x 1 cells, found {} x {}", cells_x, cells_y));
  }
  if (num_cells() > kMaxCells) {
    return ResourceExhausted(fmt::format(
        "grid: {} x {} = {} cells is too large (at most {} cells); use larger cells or a smaller area",
        cells_x, cells_y, num_cells(), kMaxCells));
  }
  return Status::Ok();
}

void FloorGrid::AppendToHash(Hasher& h) const {
  h.Add("grid");
  h.AddPod(origin_x_m);
  h.AddPod(origin_y_m);
  h.AddPod(cells_x);
  h.AddPod(cells_y);
  h.AddPod(cell_size_m);
}

}  // namespace occmap
