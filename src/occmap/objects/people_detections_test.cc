#include "occmap/objects/people_detections.h"

#include <gtest/gtest.h>

namespace occmap {
namespace {

const FloorGrid kCandidates{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 40, .cells_y = 30, .cell_size_m = 0.1};

TEST(PeopleDetections, OneUngroupedPersonDetectionPerExplainedPerson) {
  ObjectFrame frame;
  frame.groups.resize(2);  // a previous frame's
  std::vector<ExplainedPerson> people(2);
  people[0].x_m = 1.05;
  people[0].y_m = 2.25;
  people[1].x_m = 3.15;
  people[1].y_m = 0.45;
  PeopleDetections(people, kCandidates, 0.25, frame);
  EXPECT_EQ(frame.grid, kCandidates);
  EXPECT_TRUE(frame.groups.empty());
  ASSERT_EQ(frame.detections.size(), 2u);
  const Detection& d = frame.detections[1];
  EXPECT_DOUBLE_EQ(d.x_m, 3.15);
  EXPECT_DOUBLE_EQ(d.y_m, 0.45);
  EXPECT_EQ(d.group, -1);
  EXPECT_EQ(d.class_hint, "person");
  EXPECT_NEAR(d.area_m2, 0.19635, 1e-5);
  EXPECT_NEAR(d.spread_m2(0, 0), 0.25 * 0.25 / 4 + 0.01, 1e-12);
  EXPECT_DOUBLE_EQ(d.spread_m2(0, 1), 0.0);
}

TEST(PeopleDetections, ColumnMapBlobsBecomeDetections) {
  OccupancyMap map(kCandidates);
  for (auto& s : map.states()) s = CellState::kFree;
  for (int j = 10; j < 12; ++j)
    for (int i = 5; i < 7; ++i) map.states()[j * 40 + i] = CellState::kOccupied;
  map.states()[25 * 40 + 30] = CellState::kOccupied;
  ObjectFrame frame;
  ColumnMapDetections(map, frame);
  EXPECT_EQ(frame.grid, kCandidates);
  ASSERT_EQ(frame.detections.size(), 2u);
  EXPECT_NEAR(frame.detections[0].x_m, 0.6, 1e-9);
  EXPECT_NEAR(frame.detections[0].y_m, 1.1, 1e-9);
  EXPECT_EQ(frame.detections[0].cells, 4);
}

}  // namespace
}  // namespace occmap
