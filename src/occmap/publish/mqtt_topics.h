// MqttTopics: the topics a run publishes under its prefix (conventions of
// shared/guide/integrations.md), and MqttMessage, one message to publish.
//
//   <prefix>/available              online / offline (retained; offline is also the last will)
//   <prefix>/tracks                 a tracks.jsonl line per frame set
//   <prefix>/events                 an events.jsonl line per event (zones and line crossings)
//   <prefix>/stats                  run statistics, every stats_every_s
//   <prefix>/zones/<zone>/count     tracks in the zone (retained, on change)
//   <prefix>/zones/<zone>/occupied  ON / OFF (retained, on change)
//   <prefix>/lines/<line>/in        crossings in, cumulative (retained, on change); .../out
// <zone> and <line> are TopicSlug(name); names whose slugs collide get _2, _3, ... in order.
//
//   MqttTopics topics = MqttTopics::For("occmap/lab", {"door"}, {"gate"});
//   publish(topics.zone_count[0], "2");
#pragma once

#include <string>
#include <vector>

namespace occmap {

struct MqttMessage {
  std::string topic;
  std::string payload;
  bool retain = false;
  int qos = 0;
  friend bool operator==(const MqttMessage&, const MqttMessage&) = default;
};

struct MqttTopics {
  std::string available, tracks, events, stats;
  std::vector<std::string> zone_slugs, line_slugs;      // the topic level of each zone, line
  std::vector<std::string> zone_count, zone_occupied;   // per zone, in the site's order
  std::vector<std::string> line_in, line_out;           // per line

  static MqttTopics For(const std::string& prefix, const std::vector<std::string>& zones,
                        const std::vector<std::string>& lines);
};

// Slugs of the names, unique: a repeated slug gets _2, _3, ... (in order).
std::vector<std::string> UniqueSlugs(const std::vector<std::string>& names);

}  // namespace occmap
