#include "occmap/publish/mqtt_publisher.h"

#include <fmt/core.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <mutex>

#include <nlohmann/json.hpp>
#include <thread>

#include "occmap/publish/test_broker.h"

namespace occmap {
namespace {

using occmap::testing::ReceivedMessage;
using occmap::testing::TestBroker;
using occmap::testing::TestSubscriber;
using namespace std::chrono_literals;

MqttOptions OptionsFor(int port) {
  MqttOptions o;
  o.broker = {"127.0.0.1", port};
  o.topic_prefix = "occmap/test";
  o.client_id = "occmap-test-" + std::to_string(port);
  return o;
}

MqttPublisherInfo Lab() { return {"lab", {"Door West", "desk"}, {"gate"}, {}, {}}; }

// What on_status said, from the network thread.
struct StatusLines {
  std::mutex mutex;
  std::vector<std::string> lines;
  std::function<void(const std::string&)> Callback() {
    return [this](const std::string& line) {
      std::lock_guard<std::mutex> lock(mutex);
      lines.push_back(line);
    };
  }
  std::vector<std::string> Get() {
    std::lock_guard<std::mutex> lock(mutex);
    return lines;
  }
};

template <typename Predicate>
bool WaitUntil(Predicate done, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(10ms);
  }
  return true;
}

std::string Last(TestSubscriber& sub, const std::string& topic) {
  const std::vector<ReceivedMessage> m = sub.On(topic);
  return m.empty() ? "<none>" : m.back().payload;
}

TEST(MqttPublisher, PublishesTracksEventsAndRetainedZoneAndLineStates) {
  TestBroker broker;
  ASSERT_TRUE(broker.Start()) << broker.error();
  Result<std::unique_ptr<MqttPublisher>> started = MqttPublisher::Start(OptionsFor(broker.port()), Lab());
  ASSERT_TRUE(started.ok()) << started.status().ToString();
  MqttPublisher& mqtt = **started;
  ASSERT_TRUE(mqtt.WaitConnected(5s));
  TestSubscriber live(broker.port(), "occmap/test/#");
  ASSERT_TRUE(live.WaitSubscribed());
  // The state sent on connecting ends with the last line's "out" count.
  ASSERT_TRUE(live.WaitFor("occmap/test/lines/gate/out", "0"));
  const size_t start = live.Messages().size();
  auto after_start = [&](const std::string& topic) {
    std::vector<std::string> payloads;
    const std::vector<ReceivedMessage> all = live.Messages();
    for (size_t k = start; k < all.size(); ++k) {
      if (all[k].topic == topic) payloads.push_back(all[k].payload);
    }
    return payloads;
  };

  mqtt.PublishFrame({R"({"frame":0,"time_s":0,"tracks":[]})", {}, {0, 0}, {{0, 0}}});
  mqtt.PublishFrame({R"({"frame":1,"time_s":0.1,"tracks":[{"id":1}]})",
                     {R"({"frame":1,"zone":"Door West","event":"enter"})"},
                     {1, 0},
                     {{0, 0}}});
  mqtt.PublishFrame({R"({"frame":2,"time_s":0.2,"tracks":[{"id":1}]})",
                     {R"({"frame":2,"line":"gate","event":"cross","direction":"in"})"},
                     {2, 0},
                     {{1, 0}}});
  mqtt.PublishStats(R"({"frames":3})");
  ASSERT_TRUE(live.WaitFor("occmap/test/stats", R"({"frames":3})"));
  EXPECT_EQ(live.On("occmap/test/tracks").size(), 3u);
  ASSERT_EQ(live.On("occmap/test/events").size(), 2u);
  EXPECT_EQ(live.On("occmap/test/events")[1].payload, R"({"frame":2,"line":"gate","event":"cross","direction":"in"})");
  // Zone states on change only: the count 1 then 2, occupied once.
  EXPECT_EQ(after_start("occmap/test/zones/door_west/count"), (std::vector<std::string>{"1", "2"}));
  EXPECT_EQ(after_start("occmap/test/zones/door_west/occupied"), (std::vector<std::string>{"ON"}));
  EXPECT_TRUE(after_start("occmap/test/zones/desk/count").empty()) << "unchanged: nothing sent";
  EXPECT_EQ(Last(live, "occmap/test/lines/gate/in"), "1");

  // A subscriber arriving now gets the retained state, not the per-frame messages.
  TestSubscriber late(broker.port(), "#");
  ASSERT_TRUE(late.WaitSubscribed());
  ASSERT_TRUE(late.WaitForAll({"occmap/test/available", "occmap/test/lines/gate/in", "occmap/test/lines/gate/out",
                               "occmap/test/zones/door_west/count", "occmap/test/zones/door_west/occupied",
                               "occmap/test/zones/desk/count", "occmap/test/zones/desk/occupied",
                               "homeassistant/binary_sensor/occmap_test/zone_door_west_occupied/config",
                               "homeassistant/sensor/occmap_test/zone_door_west_count/config"}));
  EXPECT_EQ(Last(late, "occmap/test/available"), "online");
  EXPECT_EQ(Last(late, "occmap/test/zones/door_west/count"), "2");
  EXPECT_EQ(Last(late, "occmap/test/zones/door_west/occupied"), "ON");
  EXPECT_EQ(Last(late, "occmap/test/zones/desk/count"), "0");
  EXPECT_EQ(Last(late, "occmap/test/zones/desk/occupied"), "OFF");
  EXPECT_EQ(Last(late, "occmap/test/lines/gate/in"), "1");
  for (const ReceivedMessage& m : late.Messages()) {
    EXPECT_TRUE(m.retain) << m.topic;
    EXPECT_NE(m.topic, "occmap/test/tracks");
  }
  const nlohmann::json config =
      nlohmann::json::parse(Last(late, "homeassistant/sensor/occmap_test/zone_door_west_count/config"));
  EXPECT_EQ(config["state_topic"], "occmap/test/zones/door_west/count");
  EXPECT_EQ(config["availability_topic"], "occmap/test/available");

  const MqttCounters c = mqtt.counters();
  EXPECT_TRUE(c.connected);
  EXPECT_EQ(c.connects, 1);
  EXPECT_EQ(c.dropped, 0);

  // A clean stop says "offline" itself (the will is only for a connection that dies).
  mqtt.Stop();
  EXPECT_TRUE(late.WaitFor("occmap/test/available", "offline"));
}

TEST(MqttPublisher, ABrokerDownAtTheStartIsReachedLaterAndGetsTheState) {
  const int port = occmap::testing::FreeLoopbackPort();
  Result<std::unique_ptr<MqttPublisher>> started = MqttPublisher::Start(OptionsFor(port), Lab());
  ASSERT_TRUE(started.ok()) << started.status().ToString();
  MqttPublisher& mqtt = **started;
  // No broker: frames are dropped and counted, the state is kept.
  mqtt.PublishFrame({R"({"frame":0,"tracks":[]})", {R"({"event":"enter"})"}, {3, 0}, {{2, 1}}});
  EXPECT_FALSE(mqtt.counters().connected);
  EXPECT_EQ(mqtt.counters().dropped, 2);

  TestBroker broker(port);
  ASSERT_TRUE(broker.Start()) << broker.error();
  ASSERT_TRUE(mqtt.WaitConnected(40s)) << "the client retries with backoff (1 s doubling to 30 s)";
  TestSubscriber sub(port, "occmap/test/#");
  ASSERT_TRUE(sub.WaitSubscribed());
  ASSERT_TRUE(sub.WaitFor("occmap/test/lines/gate/out", "1"));
  EXPECT_EQ(Last(sub, "occmap/test/zones/door_west/count"), "3");
  EXPECT_EQ(Last(sub, "occmap/test/lines/gate/in"), "2");
  EXPECT_EQ(Last(sub, "occmap/test/available"), "online");
}

TEST(MqttPublisher, ABrokerThatGoesAwayIsReconnectedAndTheLostFramesCounted) {
  TestBroker broker;
  ASSERT_TRUE(broker.Start()) << broker.error();
  const int port = broker.port();
  Result<std::unique_ptr<MqttPublisher>> started = MqttPublisher::Start(OptionsFor(port), Lab());
  ASSERT_TRUE(started.ok());
  MqttPublisher& mqtt = **started;
  ASSERT_TRUE(mqtt.WaitConnected(5s));
  mqtt.PublishFrame({"{}", {}, {1, 0}, {}});

  broker.Stop();  // the broker dies (no persistence: its retained messages are gone with it)
  for (int k = 0; k < 500 && mqtt.counters().connected; ++k) std::this_thread::sleep_for(10ms);
  ASSERT_FALSE(mqtt.counters().connected);
  for (int k = 0; k < 10; ++k) mqtt.PublishFrame({"{}", {}, {k == 9 ? 4 : 2, 0}, {}});
  EXPECT_EQ(mqtt.counters().dropped, 10);
  EXPECT_EQ(mqtt.counters().disconnects, 1);

  TestBroker again(port);
  ASSERT_TRUE(again.Start()) << again.error();
  ASSERT_TRUE(mqtt.WaitConnected(40s));
  TestSubscriber sub(port, "occmap/test/#");
  ASSERT_TRUE(sub.WaitSubscribed());
  ASSERT_TRUE(sub.WaitFor("occmap/test/lines/gate/out")) << "the state, sent again on reconnection";
  EXPECT_EQ(Last(sub, "occmap/test/zones/door_west/count"), "4") << "the latest, not a resent older one";
  EXPECT_EQ(mqtt.counters().connects, 2);
  mqtt.PublishFrame({R"({"frame":12})", {}, {}, {}});
  EXPECT_TRUE(sub.WaitFor("occmap/test/tracks", R"({"frame":12})"));
}

TEST(MqttPublisher, ClearsWhatAnEarlierRunLeftRetainedAndItNoLongerHas) {
  TestBroker broker;
  ASSERT_TRUE(broker.Start()) << broker.error();
  TestSubscriber sub(broker.port(), "#");
  ASSERT_TRUE(sub.WaitSubscribed());
  {
    MqttPublisherInfo before = Lab();
    before.cameras = {"c1", "c2"};
    Result<std::unique_ptr<MqttPublisher>> first = MqttPublisher::Start(OptionsFor(broker.port()), before);
    ASSERT_TRUE(first.ok());
    ASSERT_TRUE((*first)->WaitConnected(5s));
    (*first)->PublishCameras({"streaming", "streaming"}, {10, 9.5});
    (*first)->PublishFrame({"{}", {}, {1, 0}, {{2, 1}}, 1});
    ASSERT_TRUE(sub.WaitFor("occmap/test/cameras/c2/fps", "9.50"));
    ASSERT_TRUE(sub.WaitFor("occmap/test/zones/door_west/count", "1"));
    (*first)->Stop();
  }
  // The site lost the zone "Door West", the line and camera c2.
  Result<std::unique_ptr<MqttPublisher>> second =
      MqttPublisher::Start(OptionsFor(broker.port()), {"lab", {"desk"}, {}, {"c1"}, {}});
  ASSERT_TRUE(second.ok());
  const std::vector<std::string> removed = {
      "homeassistant/binary_sensor/occmap_test/zone_door_west_occupied/config",
      "homeassistant/sensor/occmap_test/zone_door_west_count/config",
      "homeassistant/sensor/occmap_test/line_gate_in/config",
      "homeassistant/sensor/occmap_test/line_gate_out/config",
      "homeassistant/sensor/occmap_test/camera_c2_state/config",
      "homeassistant/sensor/occmap_test/camera_c2_fps/config",
      "occmap/test/zones/door_west/count",
      "occmap/test/zones/door_west/occupied",
      "occmap/test/lines/gate/in",
      "occmap/test/lines/gate/out",
      "occmap/test/cameras/c2/state",
      "occmap/test/cameras/c2/fps",
  };
  for (const std::string& topic : removed) EXPECT_TRUE(sub.WaitForCleared(topic)) << topic;
  EXPECT_EQ((*second)->counters().cleared, static_cast<int64_t>(removed.size()));

  // A newcomer gets this run's entities and nothing of the removed ones.
  TestSubscriber late(broker.port(), "#");
  ASSERT_TRUE(late.WaitSubscribed());
  ASSERT_TRUE(late.WaitForAll({"homeassistant/sensor/occmap_test/zone_desk_count/config",
                               "homeassistant/sensor/occmap_test/camera_c1_state/config",
                               "homeassistant/sensor/occmap_test/people/config", "occmap/test/zones/desk/count"}));
  // Retained messages come on subscribing, before anything published after it.
  ASSERT_TRUE(late.Publish("sync/late", "x"));
  ASSERT_TRUE(late.WaitFor("sync/late", "x"));
  for (const ReceivedMessage& m : late.Messages()) {
    EXPECT_EQ(std::find(removed.begin(), removed.end(), m.topic), removed.end()) << m.topic << " is still retained";
  }
  // Topics both runs have carry this run's values (the earlier run left 1).
  EXPECT_EQ(Last(late, "occmap/test/people"), "0");
}

TEST(MqttPublisher, SendsDiscoveryAgainWhenHomeAssistantComesBack) {
  TestBroker broker;
  ASSERT_TRUE(broker.Start()) << broker.error();
  TestSubscriber ha(broker.port(), "#");
  ASSERT_TRUE(ha.WaitSubscribed());
  Result<std::unique_ptr<MqttPublisher>> started = MqttPublisher::Start(OptionsFor(broker.port()), Lab());
  ASSERT_TRUE(started.ok());
  ASSERT_TRUE((*started)->WaitConnected(5s));
  const std::string people = "homeassistant/sensor/occmap_test/people/config";
  // The state sent on connecting ends with the last line's "out" count.
  ASSERT_TRUE(ha.WaitFor("occmap/test/lines/gate/out"));
  const size_t configs = ha.On(people).size(), counts = ha.On("occmap/test/zones/desk/count").size();
  ASSERT_EQ(configs, 1u);
  // Home Assistant's birth message after its restart (it lost the entities it had not stored).
  ASSERT_TRUE(ha.Publish("homeassistant/status", "online"));
  ASSERT_TRUE(WaitUntil([&] { return ha.On(people).size() == configs + 1; }, 10s));
  EXPECT_TRUE(WaitUntil([&] { return ha.On("occmap/test/zones/desk/count").size() == counts + 1; }, 10s));
  // "offline" (Home Assistant stopping) sends nothing.
  const size_t before = ha.On(people).size();
  ASSERT_TRUE(ha.Publish("homeassistant/status", "offline"));
  ASSERT_TRUE(ha.Publish("sync/ha", "x"));
  ASSERT_TRUE(ha.WaitFor("sync/ha"));
  (*started)->PublishStats("{}");
  ASSERT_TRUE(ha.WaitFor("occmap/test/stats"));
  EXPECT_EQ(ha.On(people).size(), before);
}

TEST(MqttPublisher, SaysOnceWhyItCannotConnectAndWhenItIsBack) {
  const int port = occmap::testing::FreeLoopbackPort();
  StatusLines said;
  MqttPublisherInfo info = Lab();
  info.on_status = said.Callback();
  Result<std::unique_ptr<MqttPublisher>> started = MqttPublisher::Start(OptionsFor(port), info);
  ASSERT_TRUE(started.ok());
  MqttPublisher& mqtt = **started;
  ASSERT_TRUE(WaitUntil([&] { return mqtt.counters().failures >= 2; }, 20s));
  const std::vector<std::string> down = said.Get();
  ASSERT_EQ(down.size(), 1u) << "said once, not at every retry";
  EXPECT_EQ(down[0], fmt::format("mqtt: cannot publish to mqtt://127.0.0.1:{}: Connection refused; retrying, messages "
                                 "are dropped until it is back",
                                 port));
  EXPECT_EQ(mqtt.counters().error, "Connection refused");
  EXPECT_EQ(mqtt.counters().broker, fmt::format("mqtt://127.0.0.1:{}", port));
  mqtt.PublishFrame({"{}", {}, {}, {}, -1});

  TestBroker broker(port);
  ASSERT_TRUE(broker.Start()) << broker.error();
  ASSERT_TRUE(mqtt.WaitConnected(40s));
  ASSERT_TRUE(WaitUntil([&] { return said.Get().size() == 2; }, 5s));
  EXPECT_THAT(said.Get()[1], ::testing::StartsWith(fmt::format("mqtt: connected to mqtt://127.0.0.1:{} again after ", port)));
  EXPECT_THAT(said.Get()[1], ::testing::EndsWith(" s; 1 messages dropped meanwhile"));
  EXPECT_EQ(mqtt.counters().error, "");

  // The broker going away is said once more.
  broker.Stop();
  ASSERT_TRUE(WaitUntil([&] { return said.Get().size() == 3; }, 10s));
  EXPECT_THAT(said.Get()[2], ::testing::HasSubstr("cannot publish to"));
  EXPECT_NE(mqtt.counters().error, "");
}

TEST(MqttPublisher, ARefusedLoginIsToldWithTheBrokersReason) {
  TestBroker broker(0, "allow_anonymous false");
  ASSERT_TRUE(broker.Start()) << broker.error();
  StatusLines said;
  MqttPublisherInfo info = Lab();
  info.on_status = said.Callback();
  MqttOptions options = OptionsFor(broker.port());
  options.username = "nobody";
  Result<std::unique_ptr<MqttPublisher>> started = MqttPublisher::Start(options, info);
  ASSERT_TRUE(started.ok());
  ASSERT_TRUE(WaitUntil([&] { return (*started)->counters().failures >= 2; }, 20s));
  EXPECT_EQ((*started)->counters().error, "Connection Refused: not authorised.");
  ASSERT_EQ(said.Get().size(), 1u);
  EXPECT_THAT(said.Get()[0], ::testing::HasSubstr(": Connection Refused: not authorised.; retrying"));
}

TEST(MqttPublisher, AnUnknownHostIsToldAsSuch) {
  MqttOptions options = OptionsFor(1883);
  options.broker.host = "occmap-no-such-host.invalid";
  StatusLines said;
  MqttPublisherInfo info = Lab();
  info.on_status = said.Callback();
  Result<std::unique_ptr<MqttPublisher>> started = MqttPublisher::Start(options, info);
  ASSERT_TRUE(started.ok());
  ASSERT_TRUE(WaitUntil([&] { return !said.Get().empty(); }, 30s));
  EXPECT_EQ((*started)->counters().error, "Lookup error.");
  EXPECT_FALSE((*started)->counters().connected);
}

TEST(MqttPublisher, StopsPromptlyWithNoBroker) {
  Result<std::unique_ptr<MqttPublisher>> started =
      MqttPublisher::Start(OptionsFor(occmap::testing::FreeLoopbackPort()), Lab());
  ASSERT_TRUE(started.ok());
  std::this_thread::sleep_for(50ms);
  (*started)->Stop();  // must not hang in the reconnect backoff (ctest's timeout would catch it)
  EXPECT_FALSE((*started)->counters().connected);
}

TEST(MqttPublisher, BadOptionsFailAtTheStart) {
  MqttOptions o = OptionsFor(1883);
  o.topic_prefix = "occmap/+/x";
  EXPECT_EQ(MqttPublisher::Start(o, Lab()).status().message(),
            "mqtt.topic_prefix: expected no MQTT wildcard ('+' or '#'), found 'occmap/+/x'");
  o = OptionsFor(1883);
  o.username = "u";
  o.password_file = "/nonexistent/occmap-password";
  EXPECT_EQ(MqttPublisher::Start(o, Lab()).status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace occmap
