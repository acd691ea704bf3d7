// Home Assistant MQTT discovery: the retained config messages that make a run's zones and
// lines appear in Home Assistant with no YAML on its side (integrations.md).
//
// One device per run (identifiers [<node_id>], name "occmap <site>"), node_id the topic
// prefix as a slug ("occmap/lab" -> "occmap_lab"). Per zone a binary_sensor (device_class
// occupancy, ON / OFF from .../occupied) and a sensor (the count, state_class measurement);
// per line two sensors (in, out; state_class total_increasing). No entity reads <prefix>/tracks
// (a message per frame set would flood Home Assistant's recorder). Every entity has the
// availability topic. Topics:
//   <discovery_prefix>/<component>/<node_id>/<object_id>/config
// object_id: zone_<slug>_occupied, zone_<slug>_count, line_<slug>_in, line_<slug>_out.
// unique_id: <node_id>_<object_id>. An empty retained payload on the same topic removes an
// entity (RemoveDiscovery).
//
//   for (const MqttMessage& m : HomeAssistantDiscovery(in)) client.Publish(m);
#pragma once

#include <string>
#include <vector>

#include "occmap/publish/mqtt_topics.h"

namespace occmap {

struct DiscoveryInput {
  std::string discovery_prefix = "homeassistant";
  std::string topic_prefix;  // the run's
  std::string site_name;
  std::string sw_version;
  std::vector<std::string> zones, lines;  // names, in the site's order
  MqttTopics topics;                      // MqttTopics::For(topic_prefix, zones, lines)
};

std::vector<MqttMessage> HomeAssistantDiscovery(const DiscoveryInput& in);
// The same topics with empty retained payloads: Home Assistant deletes the entities.
std::vector<MqttMessage> RemoveDiscovery(const DiscoveryInput& in);

}  // namespace occmap
