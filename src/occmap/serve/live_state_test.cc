#include "occmap/serve/live_state.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "occmap/geometry/pinhole_camera.h"
#include "occmap/geometry/rotation.h"

namespace occmap {
namespace {

Site TwoCameraSite() {
  Site site;
  site.name = "t";
  site.tracking.zones.push_back(ZoneOptions{"door", {{0, 0}, {1, 0}, {1, 1}}, std::nullopt});
  site.tracking.lines.push_back(LineOptions{"gate", {0, 0}, {0, 1}, 0.2, true});
  return site;
}

FrameRecord Record(int64_t frame, bool with_c2) {
  FrameRecord r;
  r.frame = frame;
  r.time_s = static_cast<double>(frame) / 10;
  FloorGrid g;
  g.cells_x = 4;
  g.cells_y = 3;
  g.cell_size_m = 0.5;
  r.map = OccupancyMap(g);
  r.map.states()[1] = CellState::kOccupied;
  r.detections.resize(2);
  r.tracks.resize(1);
  r.tracks[0].id = 9;
  r.zones.counts = {1};
  r.lines.counts = {LineCounts{2, 3}};
  r.frames_gray.resize(2);
  r.frames_rgb.resize(2);
  r.change_masks.resize(2);
  r.frames_gray[0] = Image<uint8_t>(8, 6, static_cast<uint8_t>(frame));
  r.change_masks[0] = Image<uint8_t>(8, 6, 1);
  if (with_c2) r.frames_gray[1] = Image<uint8_t>(4, 2, static_cast<uint8_t>(100 + frame));
  return r;
}

TEST(LiveState, SinkPublishesCopiesAndKeepsAMissingCamerasLastFrame) {
  auto state = std::make_shared<LiveState>();
  LiveStateSink sink(state);
  const Site site = TwoCameraSite();
  SinkStart start;
  start.site = &site;
  start.fps = 12.5;
  start.camera_ids = {"c1", "c2"};
  ASSERT_TRUE(sink.Open(start).ok());
  EXPECT_TRUE(state->running());
  EXPECT_EQ(state->fps(), 12.5);
  EXPECT_EQ(state->Latest()->frame, -1);

  RunStats stats;
  stats.frames = 1;
  {
    FrameRecord r = Record(5, true);
    ASSERT_TRUE(sink.Consume(r, stats).ok());
    r.frames_gray[0].row(0)[0] = 77;  // the run reuses its buffers: the snapshot must not see it
  }
  auto s1 = state->Latest();
  EXPECT_EQ(s1->frame, 5);
  EXPECT_EQ(s1->frames_gray[0].row(0)[0], 5);
  EXPECT_EQ(s1->frames_gray[1].row(0)[0], 105);
  EXPECT_EQ(s1->detections.size(), 2u);
  EXPECT_EQ(s1->tracks[0].id, 9);
  EXPECT_EQ(s1->zone_names, std::vector<std::string>{"door"});
  EXPECT_EQ(s1->zone_counts, std::vector<int>{1});
  EXPECT_EQ(s1->line_counts[0], (LineCounts{2, 3}));
  EXPECT_EQ(s1->map.state(1), CellState::kOccupied);

  ASSERT_TRUE(sink.Consume(Record(6, false), stats).ok());
  auto s2 = state->Latest();
  EXPECT_GT(s2->version, s1->version);
  EXPECT_EQ(s2->frames_gray[0].row(0)[0], 6);
  EXPECT_EQ(s2->frames_gray[1].row(0)[0], 105);  // c2 missed frame 6: its last frame stays
  EXPECT_EQ(s1->frame, 5);                         // a reader's snapshot never changes

  stats.stop_reason = "end of streams";
  ASSERT_TRUE(sink.Close(stats).ok());
  EXPECT_FALSE(state->running());
  EXPECT_EQ(state->ended(), "end of streams");
  EXPECT_EQ(state->Latest()->frame, 6);  // the last state stays served
}

// A person 2 m in front of a camera 1 m up looking along +y: its box spans the column's
// projection (1.7 m high, 0.5 m wide); a track behind the camera has none.
TEST(LiveState, TrackBoxesAreTheColumnsProjection) {
  PinholeParameters p;
  p.image_size = {640, 480};
  p.fx_px = p.fy_px = 400;
  p.cx_px = 319.5;
  p.cy_px = 239.5;
  const Eigen::Vector3d position(0, 0, 1.0);
  p.cam_from_world_rotation = LookAtRotation(position, {0, 10, 1.0});
  p.cam_from_world_translation_m = -p.cam_from_world_rotation * position;
  const PinholeCamera camera = PinholeCamera::Create(p).value();
  std::vector<Track> tracks(2);
  tracks[0].id = 4;
  tracks[0].object_class = "person";
  tracks[0].y_m = 2.0;
  tracks[1].id = 5;
  tracks[1].object_class = "person";
  tracks[1].y_m = -2.0;
  const std::vector<TrackBox> boxes = TrackBoxesInCamera(camera, tracks);
  ASSERT_EQ(boxes.size(), 1u);
  EXPECT_EQ(boxes[0].id, 4);
  EXPECT_EQ(boxes[0].object_class, "person");
  // Nearest face at y = 1.75 m: x +-0.25 m -> +-57 px; the floor 1 m down -> +229 px, the head
  // 0.7 m up -> -160 px.
  EXPECT_NEAR(boxes[0].x0, 319.5 - 400 * 0.25 / 1.75, 1);
  EXPECT_NEAR(boxes[0].x1, 319.5 + 400 * 0.25 / 1.75, 1);
  EXPECT_NEAR(boxes[0].y0, 239.5 - 400 * 0.7 / 1.75, 1);
  EXPECT_NEAR(boxes[0].y1, 239.5 + 400 * 1.0 / 1.75, 1);
}

// The sink keeps the latest events for the page and counts them all.
TEST(LiveState, SinkKeepsTheRecentEventsAndCountsThemAll) {
  auto state = std::make_shared<LiveState>();
  LiveStateSink sink(state);
  const Site site = TwoCameraSite();
  SinkStart start;
  start.site = &site;
  start.camera_ids = {"c1", "c2"};
  ASSERT_TRUE(sink.Open(start).ok());
  RunStats stats;
  for (int64_t f = 0; f < 60; ++f) {
    FrameRecord r = Record(f, true);
    r.event_lines = {fmt::format(R"({{"frame":{},"event":"enter"}})", f), fmt::format(R"({{"frame":{},"event":"exit"}})", f)};
    ASSERT_TRUE(sink.Consume(r, stats).ok());
  }
  const auto s = state->Latest();
  EXPECT_EQ(s->events_total, 120);
  ASSERT_EQ(s->recent_events.size(), kRecentEvents);
  EXPECT_EQ(s->recent_events.back(), R"({"frame":59,"event":"exit"})");
  EXPECT_EQ(s->recent_events.front(), R"({"frame":10,"event":"enter"})");
}

TEST(LiveState, SinkKeepsTheChangesOfACameraWithoutFrames) {
  // occmap fuse: its cameras come as the changes their edges sent, without frames.
  auto state = std::make_shared<LiveState>();
  LiveStateSink sink(state);
  SinkStart start;
  start.camera_ids = {"c1", "c2"};
  ASSERT_TRUE(sink.Open(start).ok());
  FrameRecord r;
  r.frame = 3;
  FloorGrid g;
  g.cells_x = 2;
  g.cells_y = 2;
  g.cell_size_m = 0.5;
  r.map = OccupancyMap(g);
  r.frames_gray.assign(2, Image<uint8_t>());
  r.change_masks.assign(2, Image<uint8_t>());
  r.change_masks[0] = Image<uint8_t>(8, 6, 1);
  ASSERT_TRUE(sink.Consume(r, RunStats()).ok());
  auto s = state->Latest();
  ASSERT_EQ(s->change_masks[0].width(), 8);
  EXPECT_EQ(s->change_masks[0].row(0)[0], 1);
  EXPECT_TRUE(s->frames_gray[0].empty());
  EXPECT_TRUE(s->change_masks[1].empty());  // c2 sent nothing yet
}

TEST(LiveState, StartingUntilTheRunOpens) {
  LiveState state;
  EXPECT_FALSE(state.starting());
  state.SetStarting();
  EXPECT_TRUE(state.starting());
  EXPECT_FALSE(state.running());
  state.SetRunning(true);
  EXPECT_FALSE(state.starting());
  EXPECT_TRUE(state.running());
}

TEST(LiveState, WaitNewerWakesOnPublishAndOnWake) {
  auto state = std::make_shared<LiveState>();
  const int64_t v0 = state->Latest()->version;
  std::thread publisher([&] {
    auto s = std::make_shared<LiveSnapshot>();
    s->version = state->next_version();
    s->frame = 1;
    state->Publish(s);
  });
  auto got = state->WaitNewer(v0, std::chrono::seconds(30));
  publisher.join();
  got = state->WaitNewer(v0, std::chrono::seconds(30));
  EXPECT_GT(got->version, v0);
  std::atomic<bool> done{false};
  std::thread waker([&] {
    while (!done) {
      state->Wake();
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  });
  const auto t0 = std::chrono::steady_clock::now();
  state->WaitNewer(got->version, std::chrono::seconds(60));
  done = true;
  waker.join();
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(59));
}

}  // namespace
}  // namespace occmap
