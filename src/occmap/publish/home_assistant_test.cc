#include "occmap/publish/home_assistant.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

namespace occmap {
namespace {

using nlohmann::json;

DiscoveryInput Input() {
  DiscoveryInput in;
  in.topic_prefix = "occmap/lab";
  in.site_name = "lab";
  in.sw_version = "0.1.0";
  in.zones = {"Door West", "desk"};
  in.lines = {"gate"};
  in.topics = MqttTopics::For(in.topic_prefix, in.zones, in.lines);
  return in;
}

TEST(HomeAssistantDiscovery, EachZoneIsAnOccupancySensorAndACountEachLineTwoTotals) {
  const std::vector<MqttMessage> messages = HomeAssistantDiscovery(Input());
  std::vector<std::string> topics;
  for (const MqttMessage& m : messages) {
    topics.push_back(m.topic);
    EXPECT_TRUE(m.retain) << m.topic;
  }
  EXPECT_EQ(topics, (std::vector<std::string>{
                        "homeassistant/binary_sensor/occmap_lab/zone_door_west_occupied/config",
                        "homeassistant/sensor/occmap_lab/zone_door_west_count/config",
                        "homeassistant/binary_sensor/occmap_lab/zone_desk_occupied/config",
                        "homeassistant/sensor/occmap_lab/zone_desk_count/config",
                        "homeassistant/sensor/occmap_lab/line_gate_in/config",
                        "homeassistant/sensor/occmap_lab/line_gate_out/config",
                    }));
  const json device = {{"identifiers", {"occmap_lab"}},
                       {"name", "occmap lab"},
                       {"model", "occmap"},
                       {"manufacturer", "occmap"},
                       {"sw_version", "0.1.0"}};
  EXPECT_EQ(json::parse(messages[0].payload), (json{{"name", "Door West occupied"},
                                                   {"unique_id", "occmap_lab_zone_door_west_occupied"},
                                                   {"object_id", "occmap_lab_zone_door_west_occupied"},
                                                   {"state_topic", "occmap/lab/zones/door_west/occupied"},
                                                   {"device_class", "occupancy"},
                                                   {"payload_on", "ON"},
                                                   {"payload_off", "OFF"},
                                                   {"availability_topic", "occmap/lab/available"},
                                                   {"payload_available", "online"},
                                                   {"payload_not_available", "offline"},
                                                   {"device", device}}));
  EXPECT_EQ(json::parse(messages[1].payload), (json{{"name", "Door West count"},
                                                   {"unique_id", "occmap_lab_zone_door_west_count"},
                                                   {"object_id", "occmap_lab_zone_door_west_count"},
                                                   {"state_topic", "occmap/lab/zones/door_west/count"},
                                                   {"state_class", "measurement"},
                                                   {"availability_topic", "occmap/lab/available"},
                                                   {"payload_available", "online"},
                                                   {"payload_not_available", "offline"},
                                                   {"device", device}}));
  const json in = json::parse(messages[4].payload);
  EXPECT_EQ(in["state_topic"], "occmap/lab/lines/gate/in");
  EXPECT_EQ(in["state_class"], "total_increasing");
}

TEST(HomeAssistantDiscovery, RemovalSendsEmptyRetainedPayloadsOnTheSameTopics) {
  const std::vector<MqttMessage> add = HomeAssistantDiscovery(Input());
  const std::vector<MqttMessage> remove = RemoveDiscovery(Input());
  ASSERT_EQ(add.size(), remove.size());
  for (size_t k = 0; k < add.size(); ++k) {
    EXPECT_EQ(remove[k].topic, add[k].topic);
    EXPECT_TRUE(remove[k].payload.empty());
    EXPECT_TRUE(remove[k].retain);
  }
}

TEST(MqttTopics, ZonesAndLinesUnderThePrefix) {
  const MqttTopics t = MqttTopics::For("occmap/lab", {"Door West", "door west"}, {"gate"});
  EXPECT_EQ(t.available, "occmap/lab/available");
  EXPECT_EQ(t.tracks, "occmap/lab/tracks");
  EXPECT_EQ(t.events, "occmap/lab/events");
  EXPECT_EQ(t.stats, "occmap/lab/stats");
  EXPECT_EQ(t.zone_count, (std::vector<std::string>{"occmap/lab/zones/door_west/count", "occmap/lab/zones/door_west_2/count"}));
  EXPECT_EQ(t.zone_occupied[0], "occmap/lab/zones/door_west/occupied");
  EXPECT_EQ(t.line_in[0], "occmap/lab/lines/gate/in");
  EXPECT_EQ(t.line_out[0], "occmap/lab/lines/gate/out");
}

}  // namespace
}  // namespace occmap
