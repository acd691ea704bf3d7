#include "occmap/bench/edge_sim.h"

#include <gtest/gtest.h>

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <map>
#include <thread>

#include "occmap/pipeline/edge_fuse.h"
#include "occmap/pipeline/edge_message.h"
#include "occmap/pipeline/mqtt_link.h"
#include "occmap/publish/test_broker.h"
#include "occmap/site/demo_scene.h"

namespace occmap::bench {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

EdgeMessage Changes(const Site& site, uint32_t camera, int64_t frame) {
  EdgeMessage m;
  m.table_key = EdgeTableKey(site);
  m.settings_key = EdgeSettingsKey(site);
  m.camera = camera;
  const ImageSize size = site.cameras[camera].camera->image_size();
  m.width = static_cast<uint32_t>(size.width);
  m.height = static_cast<uint32_t>(size.height);
  m.frame = frame;
  m.t_unix = 1.7e9;
  m.fps = 10;
  m.changes.assign(static_cast<size_t>(size.width) * size.height, 0);
  // A box per camera and frame, so that every message differs.
  for (int y = 10 + static_cast<int>(frame); y < 40 + static_cast<int>(frame); ++y) {
    for (int x = 20 * static_cast<int>(camera + 1); x < 20 * static_cast<int>(camera + 1) + 15; ++x) {
      m.changes[static_cast<size_t>(y) * size.width + x] = 1;
    }
  }
  return m;
}

TEST(EdgeSim, RecordedMessagesAreSentAgainAsOtherCamerasInStep) {
  occmap::testing::TestBroker broker;
  if (!broker.Start()) GTEST_SKIP() << broker.error();
  const Site site = MakeDemoLabSite();
  ASSERT_GE(site.cameras.size(), 3u);
  const fs::path dir = fs::temp_directory_path() / ("occmap-edge-sim-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const MqttBroker address{"127.0.0.1", broker.port()};
  const std::string prefix = "occmap-test/edge-sim";

  // 1. Recorded: 3 messages per camera, then each camera's end.
  EdgeRecordOptions record;
  record.broker = address;
  record.topic_prefix = prefix;
  record.dir = dir;
  record.idle_timeout_s = 20;
  std::atomic<bool> subscribed{false};
  record.on_subscribed = [&] { subscribed = true; };
  Result<EdgeRecording> recording = InvalidInput("not run");
  std::thread recorder([&] { recording = RecordEdgeMessages(site, record); });
  for (int k = 0; k < 500 && !subscribed; ++k) std::this_thread::sleep_for(10ms);
  ASSERT_TRUE(subscribed.load());
  {
    auto link = MqttLink::Start(address, "occmap-test-edge-sim-pub", {});
    ASSERT_TRUE(link.ok());
    ASSERT_TRUE((*link)->WaitConnected(5s));
    for (uint32_t n = 0; n < site.cameras.size(); ++n) {
      const std::string topic = EdgeTopic(prefix, site.cameras[n].id);
      for (int64_t f = 0; f < 3; ++f) ASSERT_TRUE((*link)->Publish(topic, EncodeEdgeMessage(Changes(site, n, f))).ok());
      EdgeMessage end = Changes(site, n, 3);
      end.kind = EdgeMessageKind::kEnd;
      ASSERT_TRUE((*link)->Publish(topic, EncodeEdgeMessage(end)).ok());
    }
    ASSERT_TRUE((*link)->WaitPublished(5s));
  }
  recorder.join();
  ASSERT_TRUE(recording.ok()) << recording.status().message();
  for (const EdgeRecording::Camera& c : recording->cameras) EXPECT_EQ(c.messages, 3) << c.id;

  // 2. Sent again as cameras 1 and 2, at 50 frame sets/s for 0.1 s: camera n gets recorded
  // camera n's messages (n mod R), restamped with each tick and the site's keys.
  auto sub = MqttLink::Start(address, "occmap-test-edge-sim-sub", {prefix + "/edge/+"});
  ASSERT_TRUE(sub.ok());
  for (int k = 0; k < 500 && !(*sub)->subscribed(); ++k) std::this_thread::sleep_for(10ms);
  EdgeReplayOptions replay;
  replay.broker = address;
  replay.topic_prefix = prefix;
  replay.dir = dir;
  replay.first_camera = 1;
  replay.cameras = 2;
  replay.rate_hz = 50;
  replay.seconds = 0.1;
  Result<EdgeReplaySummary> sent = ReplayEdgeMessages(site, replay);
  ASSERT_TRUE(sent.ok()) << sent.status().message();
  EXPECT_GE(sent->ticks, 4);
  EXPECT_EQ(sent->messages, sent->ticks * 2);
  EdgeExpectation expect{EdgeTableKey(site), EdgeSettingsKey(site), {}};
  for (const SiteCamera& c : site.cameras) expect.camera_sizes.push_back(c.camera->image_size());
  std::map<uint32_t, int> changes, ends;
  std::map<int64_t, double> tick_time;
  while (auto r = (*sub)->Pop(2s)) {
    auto m = DecodeEdgeMessage(r->payload, expect, r->topic);
    ASSERT_TRUE(m.ok()) << m.status().message();
    ASSERT_EQ(r->topic, EdgeTopic(prefix, site.cameras[m->camera].id));
    if (m->kind == EdgeMessageKind::kEnd) {
      ++ends[m->camera];
      if (ends.size() == 2) break;
      continue;
    }
    ++changes[m->camera];
    EXPECT_EQ(m->timestamp_s, m->t_unix);
    EXPECT_DOUBLE_EQ(m->t_unix, static_cast<double>(m->frame) / 50);
    // Cameras in step: one time per tick, whichever camera.
    auto [it, inserted] = tick_time.emplace(m->frame, m->t_unix);
    EXPECT_EQ(it->second, m->t_unix);
    EXPECT_EQ(m->changes, Changes(site, m->camera, m->frame % 3).changes) << m->camera << " " << m->frame;
  }
  EXPECT_EQ(changes[1], sent->ticks);
  EXPECT_EQ(changes[2], sent->ticks);
  EXPECT_EQ(changes.count(0), 0u);
  EXPECT_EQ(ends[1], 1);
  EXPECT_EQ(ends[2], 1);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace occmap::bench
