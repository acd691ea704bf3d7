#include "occmap/fusion/blobs.h"

#include <algorithm>
#include <cstring>

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

int64_t NextOccupied(const CellState* states, int64_t from, int64_t to) {
  static_assert(static_cast<uint8_t>(CellState::kOccupied) == 2 && static_cast<uint8_t>(CellState::kFree) == 1 &&
                static_cast<uint8_t>(CellState::kUnseen) == 0);
  constexpr uint64_t kBit1 = 0x0202020202020202ull;
  int64_t c = from;
  // Four words at a time over long free spans, then one word, then single cells.
  while (c + 32 <= to) {
    uint64_t w[4];
    std::memcpy(w, states + c, sizeof(w));
    if (((w[0] | w[1] | w[2] | w[3]) & kBit1) != 0) break;
    c += 32;
  }
  while (c + 8 <= to) {
    uint64_t w;
    std::memcpy(&w, states + c, sizeof(w));
    if ((w & kBit1) != 0) break;
    c += 8;
  }
  for (; c < to; ++c) {
    if (states[c] == CellState::kOccupied) return c;
  }
  return to;
}

const std::vector<Blob>& BlobFinder::Find(const OccupancyMap& map, const BlobOptions& options) {
  const FloorGrid& grid = map.grid();
  const CellState* states = map.states().data();
  const int cells_x = grid.cells_x, cells_y = grid.cells_y;
  const int64_t num_cells = static_cast<int64_t>(map.states().size());
  OCCMAP_CHECK(num_cells == grid.num_cells(), "blobs: map size differs from its grid");
  const double cell_area_m2 = grid.cell_size_m * grid.cell_size_m;
  constexpr int32_t kUnlabelled = -1, kDropped = -2;

  // Labels back to -1: only the cells the last call labelled (all of them for another size).
  if (static_cast<int64_t>(labels_.size()) != num_cells) {
    labels_.assign(static_cast<size_t>(num_cells), kUnlabelled);
  } else {
    for (int64_t cell : members_) labels_[static_cast<size_t>(cell)] = kUnlabelled;
  }
  blobs_.clear();
  members_.clear();
  dropped_.clear();
  offsets_.assign(1, 0);
  for (int64_t seed = NextOccupied(states, 0, num_cells); seed < num_cells;
       seed = NextOccupied(states, seed + 1, num_cells)) {
    if (labels_[static_cast<size_t>(seed)] != kUnlabelled) {
      // Its row's run of occupied cells is in the same blob, labelled too: skipped.
      while ((seed + 1) % cells_x != 0 && states[seed + 1] == CellState::kOccupied) ++seed;
      continue;
    }
    const int32_t label = static_cast<int32_t>(blobs_.size());
    const size_t first = members_.size();
    Blob blob;
    blob.min_i = blob.max_i = static_cast<int>(seed % cells_x);
    blob.min_j = blob.max_j = static_cast<int>(seed / cells_x);
    int64_t sum_i = 0, sum_j = 0;  // exact sums of cell indices
    // A span fill: a popped cell, if still unlabelled, grows to its row's run of unlabelled
    // occupied cells, which is labelled at once; the runs of the rows above and below that
    // touch it (8-connected: one cell beyond each end) are pushed by their first cell. The
    // same components, labels and sums as a cell-by-cell fill (only members_' order
    // differs); lab scene: fewer neighbour tests per cell of the grown map.
    stack_.push_back(seed);
    while (!stack_.empty()) {
      const int64_t cell = stack_.back();
      stack_.pop_back();
      if (labels_[static_cast<size_t>(cell)] != kUnlabelled) continue;
      const int j = static_cast<int>(cell / cells_x);
      const int64_t row = int64_t{j} * cells_x;
      int lo = static_cast<int>(cell - row), hi = lo;
      while (lo > 0 && states[row + lo - 1] == CellState::kOccupied && labels_[static_cast<size_t>(row + lo - 1)] == kUnlabelled) {
        --lo;
      }
      while (hi + 1 < cells_x && states[row + hi + 1] == CellState::kOccupied &&
             labels_[static_cast<size_t>(row + hi + 1)] == kUnlabelled) {
        ++hi;
      }
      for (int i = lo; i <= hi; ++i) {
        labels_[static_cast<size_t>(row + i)] = label;
        members_.push_back(row + i);
      }
      const int64_t n = hi - lo + 1;
      sum_i += (int64_t{lo} + hi) * n / 2;
      sum_j += int64_t{j} * n;
      blob.min_i = std::min(blob.min_i, lo);
      blob.max_i = std::max(blob.max_i, hi);
      blob.min_j = std::min(blob.min_j, j);
      blob.max_j = std::max(blob.max_j, j);
      const int from = std::max(0, lo - 1), to = std::min(cells_x - 1, hi + 1);
      for (int nj = j - 1; nj <= j + 1; nj += 2) {
        if (nj < 0 || nj >= cells_y) continue;
        const int64_t nrow = int64_t{nj} * cells_x;
        bool in_run = false;
        for (int i = from; i <= to; ++i) {
          const bool open = states[nrow + i] == CellState::kOccupied && labels_[static_cast<size_t>(nrow + i)] == kUnlabelled;
          if (open && !in_run) stack_.push_back(nrow + i);
          in_run = open;
        }
      }
    }
    blob.cells = static_cast<int64_t>(members_.size() - first);
    blob.area_m2 = static_cast<double>(blob.cells) * cell_area_m2;
    if (blob.area_m2 < options.min_area_m2) {
      for (size_t k = first; k < members_.size(); ++k) {
        labels_[static_cast<size_t>(members_[k])] = kDropped;
        dropped_.push_back(members_[k]);
      }
      members_.resize(first);
      continue;
    }
    // The mean of the cells' CellCenter, from exact index sums (as FindBlobs).
    const double n = static_cast<double>(blob.cells);
    blob.x_m = grid.origin_x_m + (static_cast<double>(sum_i) / n + 0.5) * grid.cell_size_m;
    blob.y_m = grid.origin_y_m + (static_cast<double>(sum_j) / n + 0.5) * grid.cell_size_m;
    blobs_.push_back(blob);
    offsets_.push_back(static_cast<int64_t>(members_.size()));
  }
  for (int64_t cell : dropped_) labels_[static_cast<size_t>(cell)] = kUnlabelled;
  return blobs_;
}

}  // namespace occmap
