#include "occmap/lut/column_lut.h"

#include <gtest/gtest.h>

#include "occmap/lut/test_scene.h"

namespace occmap {
namespace {

std::vector<LutCameraInput> Inputs(const std::vector<PinholeCamera>& cameras) {
  std::vector<LutCameraInput> in;
  for (const auto& c : cameras) in.push_back({&c, {}});
  return in;
}

TEST(OccluderTest, BoxAndCylinderBlockWhatPassesThroughThem) {
  Occluder box;
  box.centre_m = {2, 0};
  box.size_m = {1, 1};
  box.height_m = 2;
  EXPECT_TRUE(box.Blocks({0, 0, 1}, {4, 0, 1}));
  EXPECT_FALSE(box.Blocks({0, 0, 3}, {4, 0, 3}));   // above it
  EXPECT_FALSE(box.Blocks({0, 2, 1}, {4, 2, 1}));   // beside it
  EXPECT_FALSE(box.Blocks({0, 0, 1}, {1.4, 0, 1}));  // stops before it
  box.yaw_deg = 45;                                 // the corner now reaches y = 0.707
  EXPECT_TRUE(box.Blocks({0, 0.65, 1}, {4, 0.65, 1}));
  Occluder pillar;
  pillar.shape = Occluder::Shape::kCylinder;
  pillar.centre_m = {2, 0};
  pillar.size_m = {0.5, 0.5};
  pillar.height_m = 4;
  EXPECT_TRUE(pillar.Blocks({0, 0.2, 1}, {4, 0.2, 1}));
  EXPECT_FALSE(pillar.Blocks({0, 0.3, 1}, {4, 0.3, 1}));
  EXPECT_TRUE(pillar.Blocks({2, -3, 1}, {2, 3, 1}));
}

TEST(OccluderTest, ParsesTheStaticsListAndNamesBadFields) {
  auto ok = ParseYaml(
      "- {shape: box, centre_m: [1, 2], size_m: [0.5, 0.4], height_m: 1, yaw_deg: 10}\n"
      "- {shape: cylinder, centre_m: [3, 4], diameter_m: 0.6, height_m: 4, name: pillar}\n",
      "site.yaml");
  ASSERT_TRUE(ok.ok());
  auto list = ParseOccluders(*ok);
  ASSERT_TRUE(list.ok()) << list.status().message();
  ASSERT_EQ(list->size(), 2u);
  EXPECT_EQ((*list)[1].shape, Occluder::Shape::kCylinder);
  EXPECT_DOUBLE_EQ((*list)[1].size_m.x(), 0.6);
  for (const char* bad : {"- {shape: cone, centre_m: [1, 2], height_m: 1}",
                          "- {shape: box, centre_m: [1, 2], size_m: [0, 1], height_m: 1}",
                          "- {shape: cylinder, centre_m: [1, 2], size_m: [1, 1], height_m: 1}",
                          "- {shape: box, centre_m: [1], size_m: [1, 1], height_m: 1}",
                          "{shape: box}"}) {
    auto yaml = ParseYaml(bad, "site.yaml");
    ASSERT_TRUE(yaml.ok());
    auto r = ParseOccluders(*yaml);
    EXPECT_FALSE(r.ok()) << bad;
    if (!r.ok()) {
      EXPECT_NE(r.status().message().find("site.yaml"), std::string::npos) << r.status().message();
    }
  }
}

TEST(ColumnLutTest, ColumnsStandUpInEveryViewAndOccludersHideThem) {
  testing::SmallRoom room(320, 240);
  Context ctx(1);
  ColumnLutOptions options;
  auto lut = BuildColumnLut(Inputs(room.cameras), room.grid, 0.0, options, {}, ctx);
  ASSERT_TRUE(lut.ok()) << lut.status().message();
  EXPECT_EQ(lut->cells_per_step(), 2);
  EXPECT_EQ(lut->candidates().cells_x, 40);
  const int64_t centre = lut->candidates().CellAt(2.0, 1.5);
  for (int c = 0; c < 4; ++c) {
    const ColumnView& v = lut->view(c, centre);
    EXPECT_TRUE(v.seen && v.projected && !v.blocked);
    EXPECT_LT(v.top_row, v.bottom_row);  // the head above the foot
    const auto foot = room.cameras[c].Project({2.05, 1.55, 0.0});
    ASSERT_TRUE(foot.has_value());
    EXPECT_NEAR(v.bottom_row, foot->y(), 1e-3);
    EXPECT_NEAR(v.axis_x_bottom, foot->x(), 1e-3);
    EXPECT_GT(v.half_width_bottom, 0);
  }
  EXPECT_EQ(lut->view_count()[centre], 4);
  // A pillar between the first camera (at (-0.3, -0.3)) and the centre hides it from that camera only.
  Occluder pillar;
  pillar.shape = Occluder::Shape::kCylinder;
  pillar.centre_m = {1.0, 0.7};
  pillar.size_m = {0.4, 0.4};
  pillar.height_m = 3;
  // And a pole right under the third camera hides nothing from it.
  Occluder pole = pillar;
  pole.centre_m = {4.3, 3.3};
  pole.size_m = {0.1, 0.1};
  const std::vector<Occluder> occluders = {pillar, pole};
  auto hidden = BuildColumnLut(Inputs(room.cameras), room.grid, 0.0, options, occluders, ctx);
  ASSERT_TRUE(hidden.ok());
  EXPECT_TRUE(hidden->view(0, centre).blocked);
  for (int c = 1; c < 4; ++c) EXPECT_FALSE(hidden->view(c, centre).blocked) << c;
  // Built with two threads: the same tables.
  Context two(2);
  auto again = BuildColumnLut(Inputs(room.cameras), room.grid, 0.0, options, occluders, two);
  ASSERT_TRUE(again.ok());
  for (int c = 0; c < 4; ++c) {
    for (int64_t k = 0; k < again->candidates().num_cells(); ++k) {
      EXPECT_EQ(again->view(c, k).blocked, hidden->view(c, k).blocked);
      EXPECT_EQ(again->view(c, k).bottom_row, hidden->view(c, k).bottom_row);
    }
  }
}

TEST(ColumnLutTest, RejectsBadOptions) {
  testing::SmallRoom room;
  Context ctx(1);
  ColumnLutOptions options;
  options.step_m = 0.01;  // finer than the floor grid
  EXPECT_FALSE(BuildColumnLut(Inputs(room.cameras), room.grid, 0.0, options, {}, ctx).ok());
  options = {};
  options.height_m = -1;
  EXPECT_FALSE(BuildColumnLut(Inputs(room.cameras), room.grid, 0.0, options, {}, ctx).ok());
  EXPECT_FALSE(BuildColumnLut({}, room.grid, 0.0, ColumnLutOptions{}, {}, ctx).ok());
}

}  // namespace
}  // namespace occmap
