#include "occmap/lut/floor_grid.h"

#include <gtest/gtest.h>

namespace occmap {
namespace {

TEST(FloorGrid, CellAtUsesHalfOpenSquaresWithXFastest) {
  const FloorGrid g{.origin_x_m = -3, .origin_y_m = -9, .cells_x = 480, .cells_y = 1440, .cell_size_m = 0.025};
  EXPECT_EQ(g.CellAt(-3.0, -9.0), 0);
  EXPECT_EQ(g.CellAt(-2.9751, -9.0), 0);
  EXPECT_EQ(g.CellAt(-2.9749, -9.0), 1);
  EXPECT_EQ(g.CellAt(-3.0, -8.9749), 480);
  EXPECT_EQ(g.CellAt(8.99, 26.99), 480 * 1440 - 1);
  EXPECT_EQ(g.CellAt(9.0, 0.0), -1);
  EXPECT_EQ(g.CellAt(-3.0001, 0.0), -1);
  EXPECT_EQ(g.CellAt(0.0, 27.0), -1);
  EXPECT_EQ(g.CellAt(std::nan(""), 0.0), -1);
  const Eigen::Vector2d c = g.CellCenter(481);
  EXPECT_NEAR(c.x(), -3 + 1.5 * 0.025, 1e-12);
  EXPECT_NEAR(c.y(), -9 + 1.5 * 0.025, 1e-12);
  EXPECT_EQ(g.CellAt(c.x(), c.y()), 481);
}

TEST(FloorGrid, ValidateNamesTheProblem) {
  FloorGrid g{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 10, .cells_y = 10, .cell_size_m = 0.0};
  EXPECT_EQ(g.Validate().message(), "cell_size_m: expected a positive number, found 0");
  g.cell_size_m = 0.1;
  g.cells_x = 0;
  EXPECT_EQ(g.Validate().message(), "grid: expected at least 1 x 1 cells, found 0 x 10");
  g.cells_x = 100000;
  g.cells_y = 100000;
  const Status s = g.Validate();
  EXPECT_EQ(s.code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(s.message(),
            "grid: 100000 x 100000 = 10000000000 cells is too large (at most 268435456 cells); use larger cells "
            "or a smaller area");
}

}  // namespace
}  // namespace occmap
