#include "occmap/pipeline/ros_map_sink.h"

#include <gtest/gtest.h>

#include "occmap/util/testing.h"

namespace occmap {
namespace {

namespace fs = std::filesystem;

// A 3 x 2 grid; frame f has cell 0 occupied always, cell 1 occupied in the odd frames, cell 5
// never seen and the rest free.
FrameRecord Record(const FloorGrid& grid, int64_t f) {
  FrameRecord r;
  r.frame = f;
  r.time_s = 0.5 * static_cast<double>(f);
  r.map = OccupancyMap(grid);
  r.map.states().assign(6, CellState::kFree);
  r.map.states()[0] = CellState::kOccupied;
  if (f % 2 == 1) r.map.states()[1] = CellState::kOccupied;
  r.map.states()[5] = CellState::kUnseen;
  return r;
}

TEST(RosMapSink, WritesTheChosenFramesAndTheStaticMapPeriodicallyAndAtTheEnd) {
  testing::TempDir dir;
  Site site;
  site.grid = FloorGrid{0, 0, 3, 2, 0.1};
  RosMapSink sink({.dir = dir.path() / "ros", .frames = {3}, .static_fraction = 0.5, .static_every_s = 2});
  SinkStart start;
  start.site = &site;
  ASSERT_TRUE(sink.Open(start).ok());
  for (int64_t f = 0; f < 5; ++f) {
    ASSERT_TRUE(sink.Consume(Record(site.grid, f), RunStats{}).ok());
    // Frames at 0, 0.5, ... s: the static map is first written at 2 s (frame 4).
    EXPECT_EQ(fs::exists(dir.path() / "ros" / "static.yaml"), f >= 4) << f;
  }
  const Result<RosMap> frame = ReadRosMap(dir.path() / "ros" / "frame_000003.yaml");
  ASSERT_TRUE(frame.ok()) << frame.status().ToString();
  EXPECT_EQ(frame->cells, (std::vector<RosCell>{RosCell::kOccupied, RosCell::kOccupied, RosCell::kFree, RosCell::kFree,
                                                RosCell::kFree, RosCell::kUnknown}));
  EXPECT_FALSE(fs::exists(dir.path() / "ros" / "frame_000002.yaml"));

  // One more frame (cell 1 occupied in 3 of 6 frames: not more than half), then the end.
  ASSERT_TRUE(sink.Consume(Record(site.grid, 5), RunStats{}).ok());
  ASSERT_TRUE(sink.Close(RunStats{}).ok());
  const Result<RosMap> still = ReadRosMap(dir.path() / "ros" / "static.yaml");
  ASSERT_TRUE(still.ok()) << still.status().ToString();
  EXPECT_EQ(still->cells, (std::vector<RosCell>{RosCell::kOccupied, RosCell::kFree, RosCell::kFree, RosCell::kFree,
                                                RosCell::kFree, RosCell::kUnknown}));
  EXPECT_EQ(still->grid, site.grid);
  EXPECT_EQ(sink.written().size(), 4u);  // frame_000003 and static, .yaml and .pgm each
}

TEST(RosMapOptions, ValidateNamesTheOption) {
  EXPECT_EQ(RosMapOptions{}.Validate().message(), "--ros-map: expected a folder");
  EXPECT_EQ((RosMapOptions{.dir = "x", .frames = {-1}}).Validate().message(), "--ros-map-frame: expected a frame >= 0, found -1");
  EXPECT_EQ((RosMapOptions{.dir = "x", .frames = {}, .static_fraction = 1}).Validate().message(),
            "--ros-map-static-fraction: expected a number in [0, 1), found 1");
  EXPECT_EQ((RosMapOptions{.dir = "x", .frames = {}, .static_fraction = 0.5, .static_every_s = -1}).Validate().message(),
            "--ros-map-every-s: expected a number >= 0, found -1");
}

}  // namespace
}  // namespace occmap
