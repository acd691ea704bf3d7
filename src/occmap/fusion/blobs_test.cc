#include "occmap/fusion/blobs.h"

#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

namespace occmap {
namespace {

// A map from rows of text, top row first (+y up, as pictures): '#' occupied, '.' free,
// '?' unseen. Cells of 0.1 m, grid corner at (1, 2) m.
OccupancyMap MapFromText(const std::vector<std::string>& rows) {
  const FloorGrid grid{.origin_x_m = 1.0,
                       .origin_y_m = 2.0,
                       .cells_x = static_cast<int>(rows[0].size()),
                       .cells_y = static_cast<int>(rows.size()),
                       .cell_size_m = 0.1};
  OccupancyMap map(grid);
  for (int j = 0; j < grid.cells_y; ++j) {
    const std::string& row = rows[static_cast<size_t>(grid.cells_y - 1 - j)];
    for (int i = 0; i < grid.cells_x; ++i) {
      const char c = row[static_cast<size_t>(i)];
      map.states()[static_cast<size_t>(j * grid.cells_x + i)] =
          c == '#' ? CellState::kOccupied : c == '?' ? CellState::kUnseen : CellState::kFree;
    }
  }
  return map;
}

TEST(FindBlobs, TwoSeparateSquaresAreTwoBlobsWithCentroidsAndAreasInMetres) {
  const OccupancyMap map = MapFromText({
      "..........",
      ".......###",
      ".##....###",
      ".##....###",
      "..........",
  });
  const std::vector<Blob> blobs = FindBlobs(map);
  ASSERT_EQ(blobs.size(), 2u);
  // Ordered by first cell in row-major order from cell 0 (the bottom row, j = 0): the 2x2
  // square (rows j = 1, 2) comes before the 3x3 one (rows j = 1..3), which starts at i = 7.
  const Blob& small = blobs[0];
  EXPECT_EQ(small.cells, 4);
  EXPECT_NEAR(small.area_m2, 0.04, 1e-12);
  EXPECT_NEAR(small.x_m, 1.0 + 0.2, 1e-12);  // cells i = 1, 2: centres 0.15 and 0.25 m
  EXPECT_NEAR(small.y_m, 2.0 + 0.2, 1e-12);  // rows j = 1, 2
  EXPECT_EQ(small.min_i, 1);
  EXPECT_EQ(small.max_i, 2);
  EXPECT_EQ(small.min_j, 1);
  EXPECT_EQ(small.max_j, 2);
  const Blob& large = blobs[1];
  EXPECT_EQ(large.cells, 9);
  EXPECT_NEAR(large.area_m2, 0.09, 1e-12);
  EXPECT_NEAR(large.x_m, 1.0 + 0.85, 1e-12);  // i = 7..9, centre column 8
  EXPECT_NEAR(large.y_m, 2.0 + 0.25, 1e-12);  // j = 1..3, centre row 2
  EXPECT_EQ(large.min_i, 7);
  EXPECT_EQ(large.max_i, 9);
  EXPECT_EQ(large.min_j, 1);
  EXPECT_EQ(large.max_j, 3);
}

TEST(FindBlobs, CellsTouchingOnlyAtACornerAreOneBlob) {
  const OccupancyMap map = MapFromText({
      "#...",
      ".#..",
      "..#.",
      "...#",
  });
  const std::vector<Blob> blobs = FindBlobs(map);
  ASSERT_EQ(blobs.size(), 1u);
  EXPECT_EQ(blobs[0].cells, 4);
  EXPECT_NEAR(blobs[0].x_m, 1.2, 1e-12);
  EXPECT_NEAR(blobs[0].y_m, 2.2, 1e-12);
  EXPECT_EQ(blobs[0].min_i, 0);
  EXPECT_EQ(blobs[0].max_i, 3);
}

TEST(FindBlobs, AUShapeIsOneBlobWhoseCentroidLiesInItsOpening) {
  const OccupancyMap map = MapFromText({
      "#...#",
      "#...#",
      "#####",
  });
  const std::vector<Blob> blobs = FindBlobs(map);
  ASSERT_EQ(blobs.size(), 1u);
  EXPECT_EQ(blobs[0].cells, 9);
  EXPECT_NEAR(blobs[0].x_m, 1.25, 1e-12);  // symmetric about column 2
  // Rows j = 0 (5 cells), 1 and 2 (2 cells each): mean j = (0 * 5 + 1 * 2 + 2 * 2) / 9.
  EXPECT_NEAR(blobs[0].y_m, 2.0 + (6.0 / 9 + 0.5) * 0.1, 1e-12);
  EXPECT_EQ(map.state(static_cast<int64_t>(1 * 5 + 2)), CellState::kFree);  // the centroid's cell is free
}

TEST(FindBlobs, UnseenAndFreeCellsBothSeparateBlobs) {
  const OccupancyMap map = MapFromText({
      "##?##.##",
      "##?##.##",
  });
  const std::vector<Blob> blobs = FindBlobs(map);
  ASSERT_EQ(blobs.size(), 3u);
  for (const Blob& b : blobs) EXPECT_EQ(b.cells, 4);
  EXPECT_EQ(blobs[0].min_i, 0);
  EXPECT_EQ(blobs[1].min_i, 3);
  EXPECT_EQ(blobs[2].min_i, 6);
  EXPECT_TRUE(FindBlobs(MapFromText({"??..", "?.?."})).empty());
}

TEST(FindBlobs, BlobsSmallerThanTheMinimumAreaAreDropped) {
  const OccupancyMap map = MapFromText({
      "#....###",
      ".....###",
      "##...###",
  });
  // Areas: 0.01 m2 (1 cell), 0.02 (2 cells), 0.09 (9 cells), in order of first cell: the
  // two-cell bar (j = 0) and the 3x3 square (j = 0, i = 5) come before the single cell.
  std::vector<Blob> all = FindBlobs(map);
  ASSERT_EQ(all.size(), 3u);
  EXPECT_EQ(all[0].cells, 2);
  EXPECT_EQ(all[1].cells, 9);
  EXPECT_EQ(all[2].cells, 1);
  std::vector<Blob> kept = FindBlobs(map, {.min_area_m2 = 0.015});
  ASSERT_EQ(kept.size(), 2u);
  EXPECT_EQ(kept[0].cells, 2);
  EXPECT_EQ(kept[1].cells, 9);
  kept = FindBlobs(map, {.min_area_m2 = 0.05});
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_EQ(kept[0].cells, 9);
  EXPECT_TRUE(FindBlobs(map, {.min_area_m2 = 1.0}).empty());
}

TEST(FindBlobs, AMillionCellBlobNeedsNoRecursion) {
  const FloorGrid grid{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 1000, .cells_y = 1000, .cell_size_m = 0.025};
  OccupancyMap map(grid);
  std::fill(map.states().begin(), map.states().end(), CellState::kOccupied);
  std::vector<Blob> blobs = FindBlobs(map);
  ASSERT_EQ(blobs.size(), 1u);
  EXPECT_EQ(blobs[0].cells, 1000000);
  EXPECT_NEAR(blobs[0].area_m2, 625.0, 1e-9);
  EXPECT_NEAR(blobs[0].x_m, 12.5, 1e-9);
  EXPECT_NEAR(blobs[0].y_m, 12.5, 1e-9);
  EXPECT_EQ(blobs[0].max_i, 999);
  EXPECT_EQ(blobs[0].max_j, 999);
  // A one-cell-wide serpentine: the longest possible path through the map.
  for (int j = 0; j < 1000; ++j) {
    for (int i = 0; i < 1000; ++i) {
      const bool wall = j % 2 == 1 && (j % 4 == 1 ? i != 999 : i != 0);
      map.states()[static_cast<size_t>(j * 1000 + i)] = wall ? CellState::kFree : CellState::kOccupied;
    }
  }
  blobs = FindBlobs(map);
  ASSERT_EQ(blobs.size(), 1u);
  EXPECT_EQ(blobs[0].cells, 500 * 1000 + 500);
}


void ExpectSameBlob(const Blob& a, const Blob& b) {
  EXPECT_EQ(a.x_m, b.x_m);
  EXPECT_EQ(a.y_m, b.y_m);
  EXPECT_EQ(a.area_m2, b.area_m2);
  EXPECT_EQ(a.cells, b.cells);
  EXPECT_EQ(a.min_i, b.min_i);
  EXPECT_EQ(a.min_j, b.min_j);
  EXPECT_EQ(a.max_i, b.max_i);
  EXPECT_EQ(a.max_j, b.max_j);
}

TEST(NextOccupied, FindsTheFirstOccupiedCellAfterLongFreeAndUnseenSpans) {
  std::vector<CellState> s(200, CellState::kFree);
  for (size_t k = 0; k < s.size(); k += 3) s[k] = CellState::kUnseen;
  EXPECT_EQ(NextOccupied(s.data(), 0, 200), 200);
  for (int64_t at : {0, 7, 8, 31, 32, 33, 150, 199}) {
    std::vector<CellState> t = s;
    t[static_cast<size_t>(at)] = CellState::kOccupied;
    for (int64_t from : {int64_t{0}, at / 2, at}) EXPECT_EQ(NextOccupied(t.data(), from, 200), at) << at << " " << from;
    EXPECT_EQ(NextOccupied(t.data(), 0, at), at);  // `to` bounds the search
  }
}

TEST(BlobFinder, EqualsFindBlobsOnRandomMapsCallAfterCall) {
  std::mt19937 rng(5);
  BlobFinder finder;  // one finder for all maps: its reused labels must not leak between calls
  for (int trial = 0; trial < 60; ++trial) {
    const int nx = trial < 50 ? 30 + static_cast<int>(rng() % 50) : 64;
    const int ny = trial < 50 ? 20 + static_cast<int>(rng() % 30) : 48;
    OccupancyMap map(FloorGrid{.origin_x_m = -1, .origin_y_m = 0.5, .cells_x = nx, .cells_y = ny, .cell_size_m = 0.05});
    const unsigned occupied_percent = trial % 3 == 0 ? 2 : trial % 3 == 1 ? 15 : 55;
    for (auto& c : map.states()) {
      const auto u = rng() % 100;
      c = u < occupied_percent ? CellState::kOccupied : u < occupied_percent + 10 ? CellState::kUnseen : CellState::kFree;
    }
    const BlobOptions options{.min_area_m2 = trial % 2 == 0 ? 0.0 : 0.0075};  // odd trials drop 1-2 cell blobs
    std::vector<int32_t> labels;
    const std::vector<Blob> reference = FindBlobs(map, options, &labels);
    const std::vector<Blob>& fast = finder.Find(map, options);
    ASSERT_EQ(fast.size(), reference.size()) << "trial " << trial;
    for (size_t k = 0; k < fast.size(); ++k) ExpectSameBlob(fast[k], reference[k]);
    ASSERT_EQ(finder.labels(), labels) << "trial " << trial;
    for (size_t k = 0; k < fast.size(); ++k) {
      EXPECT_EQ(static_cast<int64_t>(finder.cells(k).size()), fast[k].cells);
      for (int64_t c : finder.cells(k)) EXPECT_EQ(labels[static_cast<size_t>(c)], static_cast<int32_t>(k));
    }
  }
}

}  // namespace
}  // namespace occmap
