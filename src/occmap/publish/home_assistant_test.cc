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
  in.cameras = {"c1"};
  in.topics = MqttTopics::For(in.topic_prefix, in.zones, in.lines, in.cameras);
  return in;
}

std::vector<std::string> Topics(const std::vector<MqttMessage>& messages) {
  std::vector<std::string> topics;
  for (const MqttMessage& m : messages) topics.push_back(m.topic);
  return topics;
}

TEST(HomeAssistantDiscovery, EachZoneIsAnOccupancySensorAndACountEachLineTwoTotals) {
  const std::vector<MqttMessage> messages = HomeAssistantDiscovery(Input());
  std::vector<std::string> topics;
  for (const MqttMessage& m : messages) {
    topics.push_back(m.topic);
    EXPECT_TRUE(m.retain) << m.topic;
  }
  EXPECT_EQ(topics, (std::vector<std::string>{
                        "homeassistant/sensor/occmap_lab/people/config",
                        "homeassistant/sensor/occmap_lab/run_state/config",
                        "homeassistant/image/occmap_lab/map/config",
                        "homeassistant/sensor/occmap_lab/camera_c1_state/config",
                        "homeassistant/sensor/occmap_lab/camera_c1_fps/config",
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
  const json origin = {{"name", "occmap"}, {"sw_version", "0.1.0"}};
  EXPECT_EQ(json::parse(messages[5].payload), (json{{"name", "Door West occupied"},
                                                   {"unique_id", "occmap_lab_zone_door_west_occupied"},
                                                   {"default_entity_id", "binary_sensor.occmap_lab_zone_door_west_occupied"},
                                                   {"state_topic", "occmap/lab/zones/door_west/occupied"},
                                                   {"device_class", "occupancy"},
                                                   {"payload_on", "ON"},
                                                   {"payload_off", "OFF"},
                                                   {"availability_topic", "occmap/lab/available"},
                                                   {"payload_available", "online"},
                                                   {"payload_not_available", "offline"},
                                                   {"device", device},
                                                   {"origin", origin}}));
  EXPECT_EQ(json::parse(messages[6].payload), (json{{"name", "Door West count"},
                                                   {"unique_id", "occmap_lab_zone_door_west_count"},
                                                   {"default_entity_id", "sensor.occmap_lab_zone_door_west_count"},
                                                   {"state_topic", "occmap/lab/zones/door_west/count"},
                                                   {"state_class", "measurement"},
                                                   {"unit_of_measurement", "objects"},
                                                   {"icon", "mdi:account-multiple"},
                                                   {"availability_topic", "occmap/lab/available"},
                                                   {"payload_available", "online"},
                                                   {"payload_not_available", "offline"},
                                                   {"device", device},
                                                   {"origin", origin}}));
  const json in = json::parse(messages[9].payload);
  EXPECT_EQ(in["state_topic"], "occmap/lab/lines/gate/in");
  EXPECT_EQ(in["state_class"], "total_increasing");
  EXPECT_EQ(in["unit_of_measurement"], "crossings");
  for (const MqttMessage& m : messages) {
    EXPECT_FALSE(json::parse(m.payload).contains("object_id")) << m.topic << ": deprecated by Home Assistant 2025.10";
  }
}

TEST(HomeAssistantDiscovery, ASiteWithoutZonesHasTheFloorTheRunTheMapAndEachCamera) {
  DiscoveryInput in;
  in.topic_prefix = "occmap/hall";
  in.site_name = "hall";
  in.cameras = {"Cam 1", "cam-2"};
  in.topics = MqttTopics::For(in.topic_prefix, {}, {}, in.cameras);
  const std::vector<MqttMessage> messages = HomeAssistantDiscovery(in);
  EXPECT_EQ(Topics(messages), (std::vector<std::string>{
                                  "homeassistant/sensor/occmap_hall/people/config",
                                  "homeassistant/sensor/occmap_hall/run_state/config",
                                  "homeassistant/image/occmap_hall/map/config",
                                  "homeassistant/sensor/occmap_hall/camera_cam_1_state/config",
                                  "homeassistant/sensor/occmap_hall/camera_cam_1_fps/config",
                                  "homeassistant/sensor/occmap_hall/camera_cam-2_state/config",
                                  "homeassistant/sensor/occmap_hall/camera_cam-2_fps/config",
                              }));
  const json people = json::parse(messages[0].payload);
  EXPECT_EQ(people["state_topic"], "occmap/hall/people");
  EXPECT_EQ(people["unit_of_measurement"], "people");
  EXPECT_EQ(people["state_class"], "measurement");
  EXPECT_EQ(people["default_entity_id"], "sensor.occmap_hall_people");
  EXPECT_EQ(people["availability_topic"], "occmap/hall/available");
  const json run = json::parse(messages[1].payload);
  EXPECT_EQ(run["state_topic"], "occmap/hall/run");
  EXPECT_EQ(run["device_class"], "enum");
  EXPECT_EQ(run["options"], (json{"running", "ended", "failed"}));
  EXPECT_EQ(run["json_attributes_topic"], "occmap/hall/run/attributes");
  EXPECT_FALSE(run.contains("availability_topic")) << "a run that failed must still read failed";
  const json map = json::parse(messages[2].payload);
  EXPECT_EQ(map["image_topic"], "occmap/hall/map");
  EXPECT_EQ(map["content_type"], "image/png");
  const json state = json::parse(messages[5].payload);
  EXPECT_EQ(state["name"], "cam-2 state");
  EXPECT_EQ(state["state_topic"], "occmap/hall/cameras/cam-2/state");
  EXPECT_EQ(state["options"], (json{"streaming", "reconnecting", "ended"}));
  EXPECT_EQ(state["entity_category"], "diagnostic");
  const json fps = json::parse(messages[6].payload);
  EXPECT_EQ(fps["state_topic"], "occmap/hall/cameras/cam-2/fps");
  EXPECT_EQ(fps["unit_of_measurement"], "fps");
  EXPECT_EQ(fps["unique_id"], "occmap_hall_camera_cam-2_fps");
  EXPECT_EQ(fps["default_entity_id"], "sensor.occmap_hall_camera_cam_2_fps") << "entity ids hold [a-z0-9_] alone";
  EXPECT_EQ(DiscoveryConfigFilter(in), "homeassistant/+/occmap_hall/+/config");
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
  EXPECT_TRUE(t.camera_state.empty());
  const MqttTopics c = MqttTopics::For("occmap/lab", {}, {}, {"c1"});
  EXPECT_EQ(c.people, "occmap/lab/people");
  EXPECT_EQ(c.run, "occmap/lab/run");
  EXPECT_EQ(c.map, "occmap/lab/map");
  EXPECT_EQ(c.camera_state, (std::vector<std::string>{"occmap/lab/cameras/c1/state"}));
  EXPECT_EQ(c.camera_fps, (std::vector<std::string>{"occmap/lab/cameras/c1/fps"}));
}

}  // namespace
}  // namespace occmap
