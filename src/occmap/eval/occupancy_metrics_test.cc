#include "occmap/eval/occupancy_metrics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "occmap/util/image_io.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {

// A raster from rows of text, top row first (+y up, as pictures): '#' occupied, '.' free,
// '?' unseen.
CellRaster RasterFromText(const std::vector<std::string>& rows) {
  CellRaster r;
  r.cells_x = static_cast<int>(rows[0].size());
  r.cells_y = static_cast<int>(rows.size());
  r.states.resize(static_cast<size_t>(r.cells_x * r.cells_y));
  for (int j = 0; j < r.cells_y; ++j) {
    const std::string& row = rows[static_cast<size_t>(r.cells_y - 1 - j)];
    for (int i = 0; i < r.cells_x; ++i) {
      const char c = row[static_cast<size_t>(i)];
      r.states[static_cast<size_t>(j * r.cells_x + i)] =
          c == '#' ? CellState::kOccupied : c == '?' ? CellState::kUnseen : CellState::kFree;
    }
  }
  return r;
}

TEST(OccupancyEvaluator, IouPrecisionRecallOnATinyRasterWorkedByHand) {
  // Computed and reference, 4 x 2 cells:
  //   computed  "##.?"     reference  "#.#."
  //             "#..#"                "##?."
  // Column by column (top, then bottom):
  //   col 0: # vs # TP;        # vs # TP
  //   col 1: # vs . FP;        . vs # FN
  //   col 2: . vs # FN;        . vs ? left out (reference unseen)
  //   col 3: ? left out (computed unseen);  # vs . FP
  // TP 2, FP 2, FN 2, TN 0; 1 cell unseen by the computed map, 1 unseen in the reference.
  // IoU = 2 / (2 + 2 + 2) = 1/3, precision = 2 / 4, recall = 2 / 4.
  OccupancyEvaluator evaluator;
  evaluator.AddFrame(0, RasterFromText({"##.?", "#..#"}), RasterFromText({"#.#.", "##?."}));
  const OccupancyMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.tp, 2);
  EXPECT_EQ(m.fp, 2);
  EXPECT_EQ(m.fn, 2);
  EXPECT_EQ(m.tn, 0);
  EXPECT_EQ(m.cells_evaluated, 6);
  EXPECT_EQ(m.computed_unseen, 1);
  EXPECT_EQ(m.reference_unseen, 1);
  EXPECT_DOUBLE_EQ(m.iou, 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(m.precision, 0.5);
  EXPECT_DOUBLE_EQ(m.recall, 0.5);
}

TEST(OccupancyEvaluator, AccumulatesCellsOverFramesRatherThanAveragingFrames) {
  // Frame 0: 1 TP, 1 FP (IoU 1/2). Frame 1: 3 TP (IoU 1). Summed: IoU = 4 / 5, not the mean
  // of per-frame values (0.75).
  OccupancyEvaluator evaluator;
  evaluator.AddFrame(0, RasterFromText({"##.."}), RasterFromText({"#..."}));
  evaluator.AddFrame(1, RasterFromText({"###."}), RasterFromText({"###."}));
  const OccupancyMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.frames, 2);
  EXPECT_EQ(m.tp, 4);
  EXPECT_EQ(m.fp, 1);
  EXPECT_EQ(m.tn, 3);
  EXPECT_DOUBLE_EQ(m.iou, 0.8);
  ASSERT_EQ(evaluator.frames().size(), 2u);
  EXPECT_EQ(evaluator.frames()[0].fp, 1);
}

TEST(OccupancyEvaluator, NothingOccupiedAnywhereLeavesIouUndefined) {
  OccupancyEvaluator evaluator;
  evaluator.AddFrame(0, RasterFromText({"..?"}), RasterFromText({"..."}));
  const OccupancyMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.tn, 2);
  EXPECT_TRUE(std::isnan(m.iou));
  EXPECT_TRUE(std::isnan(m.precision));
  EXPECT_TRUE(std::isnan(m.recall));
}

TEST(OccupancyEvaluator, TakesAnOccupancyMapDirectly) {
  const FloorGrid grid{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 2, .cells_y = 1, .cell_size_m = 0.1};
  OccupancyMap map(grid);
  map.states() = {CellState::kOccupied, CellState::kFree};
  OccupancyEvaluator evaluator;
  evaluator.AddFrame(0, map, RasterFromText({"##"}));
  const OccupancyMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.tp, 1);
  EXPECT_EQ(m.fn, 1);
  EXPECT_DOUBLE_EQ(m.recall, 0.5);
}

TEST(CellRasterFromGray, ImageRowZeroIsTheTopCellRowAsInToGrayImage) {
  // A 3 x 2 map: bottom row (j = 0) occupied, free, unseen; top row (j = 1) free, occupied,
  // free. Its picture read back gives the same states in the same cells.
  const FloorGrid grid{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 3, .cells_y = 2, .cell_size_m = 0.1};
  OccupancyMap map(grid);
  map.states() = {CellState::kOccupied, CellState::kFree, CellState::kUnseen,
                  CellState::kFree, CellState::kOccupied, CellState::kFree};
  const Image<uint8_t> picture = map.ToGrayImage();
  ASSERT_EQ(picture(0, 1), OccupancyMap::kOccupiedGray);  // cell (0, 0) is on the bottom image row
  const Result<CellRaster> raster = CellRasterFromGray(picture.view(), {}, "map");
  ASSERT_TRUE(raster.ok()) << raster.status().message();
  EXPECT_EQ(*raster, CellRaster::FromMap(map));
}

TEST(CellRasterFromGray, UnknownGreyLevelIsAnErrorNamingThePixel) {
  Image<uint8_t> picture(3, 2, 255);
  picture(2, 1) = 17;
  const Result<CellRaster> raster = CellRasterFromGray(picture.view(), {}, "gt/footprint/000004.png");
  ASSERT_FALSE(raster.ok());
  EXPECT_EQ(raster.status().code(), StatusCode::kInvalidInput);
  EXPECT_EQ(raster.status().message(),
            "gt/footprint/000004.png: pixel (2, 1): expected 255 (free), 0 (occupied) or 128 (unseen), found 17");
}

TEST(CellRasterFromGray, HonoursOtherGreyCodes) {
  // A mask-like raster: 255 occupied, 0 free, 128 unseen.
  Image<uint8_t> picture(2, 1, 0);
  picture(1, 0) = 255;
  const OccupancyGrayCodes codes{.free = 0, .occupied = 255, .unseen = 128};
  const Result<CellRaster> raster = CellRasterFromGray(picture.view(), codes, "x");
  ASSERT_TRUE(raster.ok());
  EXPECT_EQ(raster->states, (std::vector<CellState>{CellState::kFree, CellState::kOccupied}));
}

TEST(ReadCellRaster, ReadsBackAPngOfAMap) {
  testing::TempDir dir;
  const FloorGrid grid{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 4, .cells_y = 3, .cell_size_m = 0.1};
  OccupancyMap map(grid);
  for (size_t k = 0; k < map.states().size(); ++k) map.states()[k] = static_cast<CellState>(k % 3);
  ASSERT_TRUE(WritePng(dir / "000001.png", map.ToGrayImage().view()).ok());
  const Result<CellRaster> raster = ReadCellRaster(dir / "000001.png");
  ASSERT_TRUE(raster.ok()) << raster.status().message();
  EXPECT_EQ(*raster, CellRaster::FromMap(map));
}

TEST(ReadCellRaster, MissingFileIsNotFound) {
  EXPECT_EQ(ReadCellRaster("/nonexistent/000001.png").status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace occmap
