// OccupancyMap: the paper's O[x, y] as a tri-state map over a FloorGrid.
//
// kUnseen: no active camera sees the cell (never reported as occupied); kFree: enough
// cameras see through to the floor; kOccupied: the fusion rule says something stands there.
// Cells are indexed like FloorGrid (j * cells_x + i).
//
//   OccupancyMap map(lut.grid());
//   if (map.state(cell) == CellState::kOccupied) ...
#pragma once

#include <cstdint>
#include <vector>

#include "occmap/lut/floor_grid.h"
#include "occmap/util/image.h"

namespace occmap {

enum class CellState : uint8_t { kUnseen = 0, kFree = 1, kOccupied = 2 };

class OccupancyMap {
 public:
  OccupancyMap() = default;
  explicit OccupancyMap(const FloorGrid& grid) : grid_(grid), state_(static_cast<size_t>(grid.num_cells()), CellState::kUnseen) {}

  const FloorGrid& grid() const { return grid_; }
  CellState state(int64_t cell) const { return state_[cell]; }
  std::vector<CellState>& states() { return state_; }
  const std::vector<CellState>& states() const { return state_; }
  int64_t Count(CellState s) const;  // cells in state s

  // A plan-view picture, one pixel per cell (+x right, +y up: image row 0 holds cell row
  // cells_y - 1, column i holds cell column i): white free, black occupied, grey unseen.
  static constexpr uint8_t kFreeGray = 255, kOccupiedGray = 0, kUnseenGray = 128;
  Image<uint8_t> ToGrayImage() const;

  friend bool operator==(const OccupancyMap&, const OccupancyMap&) = default;

 private:
  FloorGrid grid_;
  std::vector<CellState> state_;
};

}  // namespace occmap
