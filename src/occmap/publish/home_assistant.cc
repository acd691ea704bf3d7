#include "occmap/publish/home_assistant.h"

#include <nlohmann/json.hpp>

#include "occmap/publish/mqtt_options.h"

namespace occmap {
namespace {

using nlohmann::json;

std::string NodeId(const std::string& topic_prefix) {
  std::string id = TopicSlug(topic_prefix);
  for (char& ch : id) {
    if (ch == '-') ch = '_';
  }
  return id;
}

}  // namespace

std::vector<MqttMessage> HomeAssistantDiscovery(const DiscoveryInput& in) {
  const std::string node = NodeId(in.topic_prefix);
  const json device = {{"identifiers", json::array({node})},
                       {"name", "occmap " + in.site_name},
                       {"model", "occmap"},
                       {"manufacturer", "occmap"},
                       {"sw_version", in.sw_version}};
  std::vector<MqttMessage> out;
  auto add = [&](const std::string& component, const std::string& object_id, json config) {
    config["unique_id"] = node + "_" + object_id;
    config["object_id"] = node + "_" + object_id;
    config["availability_topic"] = in.topics.available;
    config["payload_available"] = "online";
    config["payload_not_available"] = "offline";
    config["device"] = device;
    out.push_back({in.discovery_prefix + "/" + component + "/" + node + "/" + object_id + "/config", config.dump(), true, 0});
  };
  for (size_t z = 0; z < in.zones.size(); ++z) {
    const std::string& slug = in.topics.zone_slugs[z];
    add("binary_sensor", "zone_" + slug + "_occupied",
        {{"name", in.zones[z] + " occupied"},
         {"state_topic", in.topics.zone_occupied[z]},
         {"device_class", "occupancy"},
         {"payload_on", "ON"},
         {"payload_off", "OFF"}});
    add("sensor", "zone_" + slug + "_count",
        {{"name", in.zones[z] + " count"}, {"state_topic", in.topics.zone_count[z]}, {"state_class", "measurement"}});
  }
  for (size_t l = 0; l < in.lines.size(); ++l) {
    const std::string& slug = in.topics.line_slugs[l];
    add("sensor", "line_" + slug + "_in",
        {{"name", in.lines[l] + " in"}, {"state_topic", in.topics.line_in[l]}, {"state_class", "total_increasing"}});
    add("sensor", "line_" + slug + "_out",
        {{"name", in.lines[l] + " out"}, {"state_topic", in.topics.line_out[l]}, {"state_class", "total_increasing"}});
  }
  return out;
}

std::vector<MqttMessage> RemoveDiscovery(const DiscoveryInput& in) {
  std::vector<MqttMessage> out = HomeAssistantDiscovery(in);
  for (MqttMessage& m : out) m.payload.clear();
  return out;
}

}  // namespace occmap
