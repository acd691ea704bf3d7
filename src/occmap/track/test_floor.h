// Synthetic floors for the track tests: people as discs of occupied cells on a grid of 5 cm
// cells, so the trackers see what the pipeline gives them (FindBlobs of an OccupancyMap).
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
#include "occmap/track/track.h"

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
    const Eigen::Vector2d moved = c + noise.position_sigma_m * Eigen::Vector2d(jitter(rng), jitter(rng));
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

namespace occmap::testing {

// Runs a tracker (MultiTargetTracker or WindowTracker) over `frames` frames of `dt_s`: the
// people of frame f are people(f), drawn as discs of radius_m with `noise`. Returns the tracks
// of every frame; blob_counts (if given) gets the blobs of each frame at least 0.03 m^2.
template <typename Tracker, typename PeopleFn>
std::vector<std::vector<Track>> RunTracker(Tracker& tracker, int frames, double dt_s, PeopleFn&& people,
                                           const FloorNoise& noise = kClean, unsigned seed = 1,
                                           double radius_m = 0.25, std::vector<int>* blob_counts = nullptr) {
  std::mt19937 rng(seed);
  std::vector<std::vector<Track>> out;
  for (int f = 0; f < frames; ++f) {
    const OccupancyMap map = FloorWithDiscs(TestGrid(), people(f), radius_m, noise, rng);
    const std::vector<Blob> blobs = FindBlobs(map);
    if (blob_counts) {
      blob_counts->push_back(static_cast<int>(
          std::count_if(blobs.begin(), blobs.end(), [](const Blob& b) { return b.area_m2 >= 0.03; })));
    }
    auto tracks = tracker.Update(blobs, map, dt_s * f);
    EXPECT_TRUE(tracks.ok()) << tracks.status().ToString();
    out.push_back(tracks.ok() ? *tracks : std::vector<Track>{});
  }
  return out;
}

inline const Track* FindTrack(const std::vector<Track>& tracks, int64_t id) {
  for (const Track& t : tracks) {
    if (t.id == id) return &t;
  }
  return nullptr;
}

inline const Track* NearestTrack(const std::vector<Track>& tracks, const Eigen::Vector2d& p) {
  const Track* best = nullptr;
  for (const Track& t : tracks) {
    if (!best || (Eigen::Vector2d(t.x_m, t.y_m) - p).norm() < (Eigen::Vector2d(best->x_m, best->y_m) - p).norm()) best = &t;
  }
  return best;
}

}  // namespace occmap::testing
