#include "occmap/publish/home_assistant.h"

#include <algorithm>
#include <nlohmann/json.hpp>

#include "occmap/publish/mqtt_options.h"

namespace occmap {

using nlohmann::json;

std::string HomeAssistantNodeId(const std::string& topic_prefix) {
  std::string id = TopicSlug(topic_prefix);
  for (char& ch : id) {
    if (ch == '-') ch = '_';
  }
  return id;
}

std::string DiscoveryConfigFilter(const DiscoveryInput& in) {
  return in.discovery_prefix + "/+/" + HomeAssistantNodeId(in.topic_prefix) + "/+/config";
}

std::vector<MqttMessage> HomeAssistantDiscovery(const DiscoveryInput& in) {
  const std::string node = HomeAssistantNodeId(in.topic_prefix);
  const json device = {{"identifiers", json::array({node})},
                       {"name", "occmap " + in.site_name},
                       {"model", "occmap"},
                       {"manufacturer", "occmap"},
                       {"sw_version", in.sw_version}};
  const json origin = {{"name", "occmap"}, {"sw_version", in.sw_version}};
  std::vector<MqttMessage> out;
  auto add = [&](const std::string& component, const std::string& object_id, json config, bool available = true) {
    config["unique_id"] = node + "_" + object_id;
    // Entity ids hold [a-z0-9_] alone.
    std::string entity = node + "_" + object_id;
    std::replace(entity.begin(), entity.end(), '-', '_');
    config["default_entity_id"] = component + "." + entity;
    if (available) {
      config["availability_topic"] = in.topics.available;
      config["payload_available"] = "online";
      config["payload_not_available"] = "offline";
    }
    config["device"] = device;
    config["origin"] = origin;
    out.push_back({in.discovery_prefix + "/" + component + "/" + node + "/" + object_id + "/config", config.dump(), true, 0});
  };
  add("sensor", "people",
      {{"name", "People"},
       {"state_topic", in.topics.people},
       {"state_class", "measurement"},
       {"unit_of_measurement", "people"},
       {"icon", "mdi:account-group"}});
  add("sensor", "run_state",
      {{"name", "Run"},
       {"state_topic", in.topics.run},
       {"json_attributes_topic", in.topics.run_attributes},
       {"device_class", "enum"},
       {"options", {"running", "ended", "failed"}},
       {"entity_category", "diagnostic"},
       {"icon", "mdi:play-circle-outline"}},
      /*available=*/false);
  add("image", "map",
      {{"name", "Map"}, {"image_topic", in.topics.map}, {"content_type", "image/png"}, {"icon", "mdi:floor-plan"}});
  for (size_t c = 0; c < in.cameras.size() && c < in.topics.camera_slugs.size(); ++c) {
    const std::string& slug = in.topics.camera_slugs[c];
    add("sensor", "camera_" + slug + "_state",
        {{"name", in.cameras[c] + " state"},
         {"state_topic", in.topics.camera_state[c]},
         {"device_class", "enum"},
         {"options", {"streaming", "reconnecting", "ended"}},
         {"entity_category", "diagnostic"},
         {"icon", "mdi:cctv"}});
    add("sensor", "camera_" + slug + "_fps",
        {{"name", in.cameras[c] + " frame rate"},
         {"state_topic", in.topics.camera_fps[c]},
         {"state_class", "measurement"},
         {"unit_of_measurement", "fps"},
         {"suggested_display_precision", 1},
         {"entity_category", "diagnostic"},
         {"icon", "mdi:camera-timer"}});
  }
  for (size_t z = 0; z < in.zones.size(); ++z) {
    const std::string& slug = in.topics.zone_slugs[z];
    add("binary_sensor", "zone_" + slug + "_occupied",
        {{"name", in.zones[z] + " occupied"},
         {"state_topic", in.topics.zone_occupied[z]},
         {"device_class", "occupancy"},
         {"payload_on", "ON"},
         {"payload_off", "OFF"}});
    add("sensor", "zone_" + slug + "_count",
        {{"name", in.zones[z] + " count"},
         {"state_topic", in.topics.zone_count[z]},
         {"state_class", "measurement"},
         {"unit_of_measurement", "objects"},
         {"icon", "mdi:account-multiple"}});
  }
  for (size_t l = 0; l < in.lines.size(); ++l) {
    const std::string& slug = in.topics.line_slugs[l];
    add("sensor", "line_" + slug + "_in",
        {{"name", in.lines[l] + " in"},
         {"state_topic", in.topics.line_in[l]},
         {"state_class", "total_increasing"},
         {"unit_of_measurement", "crossings"},
         {"icon", "mdi:login"}});
    add("sensor", "line_" + slug + "_out",
        {{"name", in.lines[l] + " out"},
         {"state_topic", in.topics.line_out[l]},
         {"state_class", "total_increasing"},
         {"unit_of_measurement", "crossings"},
         {"icon", "mdi:logout"}});
  }
  return out;
}

std::vector<MqttMessage> RemoveDiscovery(const DiscoveryInput& in) {
  std::vector<MqttMessage> out = HomeAssistantDiscovery(in);
  for (MqttMessage& m : out) m.payload.clear();
  return out;
}

}  // namespace occmap
