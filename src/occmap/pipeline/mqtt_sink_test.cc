#include "occmap/pipeline/mqtt_sink.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "occmap/pipeline/output_files.h"
#include "occmap/publish/test_broker.h"

namespace occmap {
namespace {

using namespace std::chrono_literals;
using occmap::testing::TestBroker;
using occmap::testing::TestSubscriber;

TEST(MqttSink, PublishesTheRecordsTracksEventsAndCountsAndStatsAtTheEnd) {
  TestBroker broker;
  ASSERT_TRUE(broker.Start()) << broker.error();
  TestSubscriber sub(broker.port(), "occmap/#");
  ASSERT_TRUE(sub.WaitSubscribed());

  Site site;
  site.name = "Lab";
  site.tracking.zones = {ZoneOptions{"door", {{0, 0}, {1, 0}, {1, 1}}, std::nullopt}};
  site.tracking.lines = {LineOptions{"gate", {0, 0}, {0, 2}, 0.2, true}};
  MqttOptions options;
  options.broker = {"127.0.0.1", broker.port()};
  options.stats_every_s = 3600;  // only the one at the end
  MqttSink sink(options);
  SinkStart start;
  start.site = &site;
  start.camera_ids = {"c1", "c2"};
  ASSERT_TRUE(sink.Open(start).ok());
  ASSERT_TRUE(sub.WaitFor("occmap/lab/lines/gate/out", "0")) << "the state on connecting";

  FrameRecord r;
  r.frame = 7;
  r.time_s = 0.7;
  r.t_unix = 1.5e9;  // stamped first, as on the files' lines
  Track t;
  t.id = 3;
  t.x_m = 0.5;
  t.y_m = 0.25;
  t.object_class = "person";
  r.tracks = {t};
  r.zones.events = {ZoneEvent{7, 0.7, "door", 3, ZoneEventKind::kEnter, 1}};
  r.zones.counts = {1};
  r.lines.events = {LineEvent{7, 0.7, "gate", 3, LineDirection::kOut, {0, 1}}};
  r.lines.counts = {{0, 1}};
  MakeJsonLines(r, /*wall_clock_times=*/true);
  RunStats stats;
  stats.frames = 8;
  // c2 a live camera whose cached background is refreshed, its last write failed.
  const BackgroundCacheFigures cache{.entry = "/cache/backgrounds/lab-c2-0123-y.png",
                                     .refreshes = 3,
                                     .failures = 2,
                                     .last_refresh_frame = 6,
                                     .last_error = "camera c2: refreshing its cached background: disk full"};
  stats.cameras = {CameraStats{.id = "c1", .frames = 8, .dropped = 2},
                   CameraStats{.id = "c2", .frames = 8, .background_cache = cache}};
  ASSERT_TRUE(sink.Consume(r, stats).ok());
  ASSERT_TRUE(sink.Close(stats).ok());

  ASSERT_TRUE(sub.WaitFor("occmap/lab/available", "offline"));
  ASSERT_TRUE(sub.WaitFor("occmap/lab/stats")) << [&] {  // what came instead
    std::string topics;
    for (const auto& m : sub.Messages()) topics += m.topic + " " + m.payload.substr(0, 40) + "\n";
    return topics;
  }();
  EXPECT_EQ(sub.On("occmap/lab/tracks").back().payload,
            R"({"t_unix":1500000000.000000,"frame":7,"time_s":0.7,"tracks":[{"id":3,"x_m":0.5,"y_m":0.25,"vx_mps":0,"vy_mps":0,"class":"person"}]})");
  const auto events = sub.On("occmap/lab/events");
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].payload, R"({"t_unix":1500000000.000000,"frame":7,"time_s":0.7,"zone":"door","track_id":3,"event":"enter","count":1})");
  EXPECT_EQ(events[1].payload,
            R"({"t_unix":1500000000.000000,"frame":7,"time_s":0.7,"line":"gate","track_id":3,"event":"cross","direction":"out","in":0,"out":1})");
  EXPECT_EQ(sub.On("occmap/lab/zones/door/count").back().payload, "1");
  EXPECT_EQ(sub.On("occmap/lab/zones/door/occupied").back().payload, "ON");
  EXPECT_EQ(sub.On("occmap/lab/lines/gate/out").back().payload, "1");
  const nlohmann::json s = nlohmann::json::parse(sub.On("occmap/lab/stats").back().payload);
  EXPECT_EQ(s["frames"], 8);
  EXPECT_EQ(s["line_crossings"], 1);
  EXPECT_EQ(s["cameras"][0]["id"], "c1");
  EXPECT_EQ(s["cameras"][0]["dropped"], 2);
  // The cache's figures as summary.json gives them, only for a camera that has them.
  EXPECT_FALSE(s["cameras"][0].contains("background_cache"));
  EXPECT_EQ(s["cameras"][1]["background_cache"],
            nlohmann::json::parse(R"({"entry": "/cache/backgrounds/lab-c2-0123-y.png", "refreshes": 3, "failures": 2,
                                      "last_refresh_frame": 6,
                                      "last_error": "camera c2: refreshing its cached background: disk full"})"));
  EXPECT_EQ(s["mqtt"]["dropped"], 0);
  EXPECT_GT(s["t_unix"].get<double>(), 1.7e9);
}

TEST(MqttSink, ASiteWithoutZonesStillGivesTheFloorTheCamerasTheRunAndTheMap) {
  TestBroker broker;
  ASSERT_TRUE(broker.Start()) << broker.error();
  TestSubscriber sub(broker.port(), "#");
  ASSERT_TRUE(sub.WaitSubscribed());

  Site site;
  site.name = "hall";  // no zones, no lines
  MqttOptions options;
  options.broker = {"127.0.0.1", broker.port()};
  options.stats_every_s = 3600;
  std::vector<std::string> said;
  MqttSink sink(options, [&](const std::string& line) { said.push_back(line); });
  SinkStart start;
  start.site = &site;
  start.camera_ids = {"c1", "c2"};
  ASSERT_TRUE(sink.Open(start).ok());
  for (const char* entity : {"sensor/occmap_hall/people", "sensor/occmap_hall/run_state", "image/occmap_hall/map",
                             "sensor/occmap_hall/camera_c1_state", "sensor/occmap_hall/camera_c1_fps",
                             "sensor/occmap_hall/camera_c2_state", "sensor/occmap_hall/camera_c2_fps"}) {
    EXPECT_TRUE(sub.WaitFor(std::string("homeassistant/") + entity + "/config")) << entity;
  }
  ASSERT_TRUE(sub.WaitFor("occmap/hall/run", "running"));

  FrameRecord r;
  r.frame = 0;
  const FloorGrid grid{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 4, .cells_y = 3, .cell_size_m = 0.5};
  r.map = OccupancyMap(grid);
  std::fill(r.map.states().begin(), r.map.states().end(), CellState::kFree);
  r.map.states()[0] = CellState::kOccupied;  // cell (0, 0): the picture's bottom-left corner
  Track a, b, robot;
  a.id = 1, a.object_class = "person", a.x_m = 1.75, a.y_m = 1.25;
  b.id = 2, b.object_class = "person", b.x_m = 1.0, b.y_m = 0.5;
  robot.id = 3, robot.object_class = "robot", robot.x_m = 0.5, robot.y_m = 1.0;
  r.tracks = {a, b, robot};
  MakeJsonLines(r, /*wall_clock_times=*/true);
  RunStats stats;
  stats.frames = 1;
  stats.cameras = {CameraStats{.id = "c1", .frames = 1}, CameraStats{.id = "c2", .connected = false}};
  ASSERT_TRUE(sink.Consume(r, stats).ok());
  ASSERT_TRUE(sub.WaitFor("occmap/hall/people", "2")) << "people: the tracks of class person";
  ASSERT_TRUE(sub.WaitFor("occmap/hall/cameras/c1/state", "streaming"));
  ASSERT_TRUE(sub.WaitFor("occmap/hall/cameras/c2/state", "reconnecting"));
  ASSERT_TRUE(sub.WaitFor("occmap/hall/map"));
  const std::string png = sub.On("occmap/hall/map").back().payload;
  const cv::Mat picture = cv::imdecode(cv::Mat(1, static_cast<int>(png.size()), CV_8U, const_cast<char*>(png.data())),
                                       cv::IMREAD_COLOR);
  ASSERT_FALSE(picture.empty());
  EXPECT_EQ(picture.cols, 480);  // 120 px per cell
  EXPECT_EQ(picture.rows, 360);
  EXPECT_EQ(picture.at<cv::Vec3b>(359, 0), cv::Vec3b(0, 0, 0)) << "cell (0, 0) occupied, row 0 is the top";
  EXPECT_EQ(picture.at<cv::Vec3b>(0, 0), cv::Vec3b(255, 255, 255));
  EXPECT_EQ(picture.at<cv::Vec3b>(60, 420), cv::Vec3b(40, 40, 220)) << "track 1's dot at (1.75, 1.25) m";

  stats.stop_reason = "camera c2 lost at frame 1";
  stats.cameras[1].active = false;
  ASSERT_TRUE(sink.Close(stats).ok());
  ASSERT_TRUE(sub.WaitFor("occmap/hall/available", "offline"));
  EXPECT_EQ(sub.On("occmap/hall/run").back().payload, "failed");
  EXPECT_EQ(nlohmann::json::parse(sub.On("occmap/hall/run/attributes").back().payload)["reason"],
            "camera c2 lost at frame 1");
  EXPECT_EQ(sub.On("occmap/hall/cameras/c2/state").back().payload, "ended");
  EXPECT_TRUE(said.empty()) << "nothing to say while the broker is there: " << (said.empty() ? "" : said[0]);
  EXPECT_EQ(RunStateAfter("end of streams"), "ended");
  EXPECT_EQ(RunStateAfter("stop requested"), "ended");
  EXPECT_EQ(RunStateAfter("frame limit"), "ended");
}

TEST(MqttSink, ABrokerThatIsNotThereNeverFailsTheRun) {
  Site site;
  site.name = "lab";
  MqttOptions options;
  options.broker = {"127.0.0.1", occmap::testing::FreeLoopbackPort()};
  MqttSink sink(options);
  SinkStart start;
  start.site = &site;
  ASSERT_TRUE(sink.Open(start).ok());
  FrameRecord r;
  for (int k = 0; k < 5; ++k) {
    r.frame = k;
    MakeJsonLines(r, /*wall_clock_times=*/true);
    EXPECT_TRUE(sink.Consume(r, RunStats{}).ok());
  }
  EXPECT_TRUE(sink.Close(RunStats{}).ok());
  EXPECT_EQ(sink.counters().dropped, 6) << "5 tracks messages and the last stats";
}

}  // namespace
}  // namespace occmap
