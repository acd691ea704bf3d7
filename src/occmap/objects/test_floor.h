// Synthetic floors for the objects and track tests: people as discs of occupied cells on a grid
// of 5 cm cells, so the splitter and the trackers see what the pipeline gives them.
//
//   std::mt19937 rng(7);
//   OccupancyMap map = testing::FloorWithDiscs(testing::TestGrid(), {{2.0, 3.0}}, 0.25, testing::kNoisy, rng);
//   std::vector<Blob> blobs = FindBlobs(map);
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "occmap/fusion/blobs.h"
#include "occmap/fusion/occupancy_map.h"

namespace occmap::testing {

// 8 x 6 m of 5 cm cells, corner at the world origin.
inline FloorGrid TestGrid() {
  return FloorGrid{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 160, .cells_y = 120, .cell_size_m = 0.05};
}

// Marks occupied every cell whose centre is within radius_m of centre_m.
inline void MarkDisc(OccupancyMap& map, const Eigen::Vector2d& centre_m, double radius_m) {
  const FloorGrid& grid = map.grid();
  for (int64_t cell = 0; cell < grid.num_cells(); ++cell) {
    if ((grid.CellCenter(cell) - centre_m).norm() <= radius_m) map.states()[static_cast<size_t>(cell)] = CellState::kOccupied;
  }
}

// Marks occupied the cells whose centres lie in [x0, x1] x [y0, y1].
inline void MarkRectangle(OccupancyMap& map, double x0, double y0, double x1, double y1) {
  const FloorGrid& grid = map.grid();
  for (int64_t cell = 0; cell < grid.num_cells(); ++cell) {
    const Eigen::Vector2d c = grid.CellCenter(cell);
    if (c.x() >= x0 && c.x() <= x1 && c.y() >= y0 && c.y() <= y1) map.states()[static_cast<size_t>(cell)] = CellState::kOccupied;
  }
}

inline OccupancyMap FreeFloor(const FloorGrid& grid) {
  OccupancyMap map(grid);
  std::fill(map.states().begin(), map.states().end(), CellState::kFree);
  return map;
}

struct FloorNoise {
  double position_sigma_m = 0;  // each disc's centre is moved by this (Gaussian, per axis)
  double radius_jitter_m = 0;   // each disc's radius varies uniformly by +- this
  int speckles = 0;             // single occupied cells at random places (false changes)
};
inline constexpr FloorNoise kClean{};
inline constexpr FloorNoise kNoisy{0.02, 0.02, 6};

inline OccupancyMap FloorWithDiscs(const FloorGrid& grid, const std::vector<Eigen::Vector2d>& centres_m,
                                   double radius_m, const FloorNoise& noise, std::mt19937& rng) {
  OccupancyMap map = FreeFloor(grid);
  std::normal_distribution<double> jitter(0.0, 1.0);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (const Eigen::Vector2d& c : centres_m) {
    // One draw a statement: a call's arguments have no set order (GCC takes them right to left
    // on x86-64, left to right on aarch64), and the tests' expectations hold for this sequence.
    const double dy = jitter(rng);
    const double dx = jitter(rng);
    const Eigen::Vector2d moved = c + noise.position_sigma_m * Eigen::Vector2d(dx, dy);
    MarkDisc(map, moved, radius_m + noise.radius_jitter_m * unit(rng));
  }
  std::uniform_int_distribution<int64_t> any_cell(0, grid.num_cells() - 1);
  for (int k = 0; k < noise.speckles; ++k) map.states()[static_cast<size_t>(any_cell(rng))] = CellState::kOccupied;
  return map;
}

inline OccupancyMap FloorWithDiscs(const FloorGrid& grid, const std::vector<Eigen::Vector2d>& centres_m,
                                   double radius_m = 0.25) {
  std::mt19937 rng(1);
  return FloorWithDiscs(grid, centres_m, radius_m, kClean, rng);
}

// A straight walk at constant velocity: the position at `time_s`.
struct Walk {
  Eigen::Vector2d start_m;
  Eigen::Vector2d velocity_mps;
  Eigen::Vector2d At(double time_s) const { return start_m + time_s * velocity_mps; }
};

}  // namespace occmap::testing
