// Home Assistant MQTT discovery: the retained config messages that make a run appear in Home
// Assistant with no YAML on its side (integrations.md).
//
// One device per run (identifiers [<node_id>], name "occmap <site>"), node_id the topic
// prefix as a slug ("occmap/lab" -> "occmap_lab"). Every run, zones or not, has:
//   sensor people          people on the whole floor (unit people, state_class measurement)
//   sensor run_state       running / ended / failed (device_class enum, diagnostic), its
//                          reason as attributes; without availability, so that a run that
//                          ended or failed still reads so
//   image map              the floor map as a PNG (<prefix>/map)
//   per camera: sensor camera_<slug>_state (enum streaming / reconnecting / ended) and
//               sensor camera_<slug>_fps (unit fps), both diagnostic
//   per zone:   binary_sensor zone_<slug>_occupied (device_class occupancy, ON / OFF) and
//               sensor zone_<slug>_count (unit objects, state_class measurement)
//   per line:   sensor line_<slug>_in and line_<slug>_out (unit crossings, total_increasing)
// No entity reads <prefix>/tracks (a message per frame set would flood Home Assistant's
// recorder). Every entity but run_state has the availability topic. Topics:
//   <discovery_prefix>/<component>/<node_id>/<object_id>/config
// unique_id: <node_id>_<object_id>; default_entity_id: <component>.<node_id>_<object_id> (Home
// Assistant 2025.10 deprecated object_id for it); origin names occmap and its version. An empty
// retained payload on the same topic removes an entity (RemoveDiscovery; MqttPublisher clears
// the configs under its node_id that the run no longer has).
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
  std::vector<std::string> zones, lines, cameras;  // names and camera ids, in the site's order
  MqttTopics topics;  // MqttTopics::For(topic_prefix, zones, lines, cameras)
};

// The device's node_id: the topic prefix as a slug with '_' for '-'.
std::string HomeAssistantNodeId(const std::string& topic_prefix);
// The subscription that finds every config published under the run's node_id:
// <discovery_prefix>/+/<node_id>/+/config.
std::string DiscoveryConfigFilter(const DiscoveryInput& in);

std::vector<MqttMessage> HomeAssistantDiscovery(const DiscoveryInput& in);
// The same topics with empty retained payloads: Home Assistant deletes the entities.
std::vector<MqttMessage> RemoveDiscovery(const DiscoveryInput& in);

}  // namespace occmap
