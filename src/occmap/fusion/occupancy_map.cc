#include "occmap/fusion/occupancy_map.h"

#include <algorithm>

namespace occmap {

int64_t OccupancyMap::Count(CellState s) const { return std::count(state_.begin(), state_.end(), s); }

Image<uint8_t> OccupancyMap::ToGrayImage() const {
  const int cells_x = grid_.cells_x, cells_y = grid_.cells_y;
  Image<uint8_t> image(cells_x, cells_y);
  for (int j = 0; j < cells_y; ++j) {
    uint8_t* row = image.row(cells_y - 1 - j);  // +y up: row 0 holds the last cell row
    const CellState* cells = state_.data() + static_cast<size_t>(j) * static_cast<size_t>(cells_x);
    for (int i = 0; i < cells_x; ++i) {
      switch (cells[i]) {
        case CellState::kFree: row[i] = kFreeGray; break;
        case CellState::kOccupied: row[i] = kOccupiedGray; break;
        case CellState::kUnseen: row[i] = kUnseenGray; break;
      }
    }
  }
  return image;
}

}  // namespace occmap
