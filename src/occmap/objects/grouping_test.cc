#include "occmap/objects/grouping.h"

#include <gtest/gtest.h>

#include <random>

namespace occmap {
namespace {

OccupancyMap Empty(int nx, int ny, double cell_m = 0.05) {
  OccupancyMap m(FloorGrid{.origin_x_m = 0, .origin_y_m = 0, .cells_x = nx, .cells_y = ny, .cell_size_m = cell_m});
  for (auto& s : m.states()) s = CellState::kFree;
  return m;
}

void Disc(OccupancyMap& m, double x, double y, double r) {
  for (int64_t c = 0; c < m.grid().num_cells(); ++c) {
    const auto p = m.grid().CellCenter(c);
    if (std::hypot(p.x() - x, p.y() - y) <= r) m.states()[c] = CellState::kOccupied;
  }
}

std::vector<Blob> Groups(const OccupancyMap& m, double r) {
  OccupancyMap grown;
  GrowOccupied(m, r, grown);
  std::vector<int32_t> labels;
  const std::vector<Blob> groups = FindBlobs(grown, {}, &labels);
  return FootprintBlobs(m, labels, groups);
}

TEST(GrowOccupied, JoinsTwoFeetIntoOneDetectionAtTheirFootprintCentroid) {
  OccupancyMap m = Empty(60, 60);
  Disc(m, 1.3, 1.5, 0.06);  // two feet, their centres 0.3 m apart
  Disc(m, 1.6, 1.52, 0.06);
  ASSERT_EQ(FindBlobs(m).size(), 2u);
  const auto joined = Groups(m, 0.15);
  ASSERT_EQ(joined.size(), 1u);
  EXPECT_NEAR(joined[0].x_m, 1.45, 0.01);
  EXPECT_NEAR(joined[0].y_m, 1.51, 0.02);
  const auto single = FindBlobs(m);
  EXPECT_EQ(joined[0].cells, single[0].cells + single[1].cells);  // the footprint, not the growth
  EXPECT_EQ(Groups(m, 0.05).size(), 2u);  // a gap of 0.18 m needs r >= 0.09
}

TEST(GrowOccupied, NeverGrowsIntoUnseenCells) {
  OccupancyMap m = Empty(20, 20);
  m.states()[10 * 20 + 10] = CellState::kOccupied;
  for (int i = 0; i < 20; ++i) m.states()[11 * 20 + i] = CellState::kUnseen;
  OccupancyMap grown;
  GrowOccupied(m, 0.15, grown);
  for (int i = 0; i < 20; ++i) EXPECT_EQ(grown.states()[11 * 20 + i], CellState::kUnseen);
  EXPECT_EQ(grown.states()[9 * 20 + 10], CellState::kOccupied);
}

TEST(GrowOccupied, MatchesTheBruteForceReferenceOnRandomMaps) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 40; ++trial) {
    const int nx = 20 + static_cast<int>(rng() % 40), ny = 20 + static_cast<int>(rng() % 40);
    OccupancyMap m = Empty(nx, ny);
    const unsigned occupied_percent = trial % 2 == 0 ? 3 : 40;  // sparse cells, and long runs
    for (auto& s : m.states()) {
      const auto u = rng() % 100;
      s = u < occupied_percent ? CellState::kOccupied : u < occupied_percent + 7 ? CellState::kUnseen : CellState::kFree;
    }
    const double r = 0.05 * (static_cast<double>(rng() % 60) / 10.0);
    OccupancyMap fast, reference;
    GrowOccupied(m, r, fast);
    GrowOccupiedReference(m, r, reference);
    ASSERT_EQ(fast, reference) << "trial " << trial << " r " << r;
  }
}

TEST(FindBlobs, LabelsEachCellWithItsBlob) {
  OccupancyMap m = Empty(10, 10);
  m.states()[0] = m.states()[1] = CellState::kOccupied;
  m.states()[55] = CellState::kOccupied;
  std::vector<int32_t> labels;
  const auto blobs = FindBlobs(m, {.min_area_m2 = 0.004}, &labels);  // drops the single cell
  ASSERT_EQ(blobs.size(), 1u);
  EXPECT_EQ(labels[0], 0);
  EXPECT_EQ(labels[1], 0);
  EXPECT_EQ(labels[55], -1);
  EXPECT_EQ(labels[2], -1);
}


TEST(FootprintBlobs, FromTheFindersCellsEqualsTheScanOfAllLabels) {
  std::mt19937 rng(23);
  BlobFinder finder;
  std::vector<Blob> fast;
  for (int trial = 0; trial < 30; ++trial) {
    OccupancyMap m = Empty(40 + static_cast<int>(rng() % 40), 30 + static_cast<int>(rng() % 30));
    const unsigned occupied_percent = trial % 2 == 0 ? 2 : 10;
    for (auto& s : m.states()) {
      const auto u = rng() % 100;
      s = u < occupied_percent ? CellState::kOccupied : u < occupied_percent + 8 ? CellState::kUnseen : CellState::kFree;
    }
    OccupancyMap grown;
    GrowOccupied(m, 0.05 * static_cast<double>(rng() % 4), grown);
    std::vector<int32_t> labels;
    const std::vector<Blob> groups = FindBlobs(grown, {}, &labels);
    const std::vector<Blob> reference = FootprintBlobs(m, labels, groups);
    finder.Find(grown);
    FootprintBlobs(m, finder, fast);
    ASSERT_EQ(fast.size(), reference.size());
    for (size_t k = 0; k < fast.size(); ++k) {
      EXPECT_EQ(fast[k].x_m, reference[k].x_m);
      EXPECT_EQ(fast[k].y_m, reference[k].y_m);
      EXPECT_EQ(fast[k].area_m2, reference[k].area_m2);
      EXPECT_EQ(fast[k].cells, reference[k].cells);
      EXPECT_EQ(fast[k].min_i, reference[k].min_i);
      EXPECT_EQ(fast[k].max_j, reference[k].max_j);
    }
  }
}

}  // namespace
}  // namespace occmap
