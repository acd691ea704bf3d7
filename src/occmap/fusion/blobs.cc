#include "occmap/fusion/blobs.h"

#include <algorithm>

namespace occmap {

std::vector<Blob> FindBlobs(const OccupancyMap& map, const BlobOptions& options, std::vector<int32_t>* labels) {
  const FloorGrid& grid = map.grid();
  const std::vector<CellState>& states = map.states();
  const int cells_x = grid.cells_x, cells_y = grid.cells_y;
  const int64_t num_cells = static_cast<int64_t>(states.size());
  OCCMAP_CHECK(num_cells == grid.num_cells(), "blobs: map size differs from its grid");
  const double cell_area_m2 = grid.cell_size_m * grid.cell_size_m;

  std::vector<Blob> blobs;
  std::vector<uint8_t> visited(static_cast<size_t>(num_cells), 0);
  std::vector<int64_t> stack;  // explicit flood-fill stack: no recursion, any blob size
  std::vector<int64_t> members;  // the current blob's cells, for the labels
  if (labels != nullptr) labels->assign(static_cast<size_t>(num_cells), -1);
  for (int64_t seed = 0; seed < num_cells; ++seed) {
    if (visited[seed] || states[seed] != CellState::kOccupied) continue;
    Blob blob;
    blob.min_i = blob.max_i = static_cast<int>(seed % cells_x);
    blob.min_j = blob.max_j = static_cast<int>(seed / cells_x);
    int64_t sum_i = 0, sum_j = 0;  // exact sums of cell indices
    visited[seed] = 1;
    stack.push_back(seed);
    while (!stack.empty()) {
      const int64_t cell = stack.back();
      stack.pop_back();
      const int i = static_cast<int>(cell % cells_x), j = static_cast<int>(cell / cells_x);
      if (labels != nullptr) members.push_back(cell);
      ++blob.cells;
      sum_i += i;
      sum_j += j;
      blob.min_i = std::min(blob.min_i, i);
      blob.max_i = std::max(blob.max_i, i);
      blob.min_j = std::min(blob.min_j, j);
      blob.max_j = std::max(blob.max_j, j);
      for (int dj = -1; dj <= 1; ++dj) {
        const int nj = j + dj;
        if (nj < 0 || nj >= cells_y) continue;
        for (int di = -1; di <= 1; ++di) {
          const int ni = i + di;
          if (ni < 0 || ni >= cells_x) continue;
          const int64_t neighbour = int64_t{nj} * cells_x + ni;
          if (visited[neighbour] || states[neighbour] != CellState::kOccupied) continue;
          visited[neighbour] = 1;
          stack.push_back(neighbour);
        }
      }
    }
    blob.area_m2 = static_cast<double>(blob.cells) * cell_area_m2;
    if (blob.area_m2 < options.min_area_m2) {
      members.clear();
      continue;
    }
    if (labels != nullptr) {
      for (int64_t cell : members) (*labels)[cell] = static_cast<int32_t>(blobs.size());
      members.clear();
    }
    // The mean of the cells' CellCenter, from exact index sums.
    const double n = static_cast<double>(blob.cells);
    blob.x_m = grid.origin_x_m + (static_cast<double>(sum_i) / n + 0.5) * grid.cell_size_m;
    blob.y_m = grid.origin_y_m + (static_cast<double>(sum_j) / n + 0.5) * grid.cell_size_m;
    blobs.push_back(blob);
  }
  return blobs;
}

}  // namespace occmap
