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
//   <prefix>/people                 people on the whole floor (retained, on change)
//   <prefix>/run                    the run's state: running, ended, failed (retained)
//   <prefix>/run/attributes         {"reason": why it ended or failed} (retained)
//   <prefix>/map                    the floor map as a PNG (retained, every stats_every_s)
//   <prefix>/cameras/<camera>/state streaming, reconnecting, ended (retained, on change)
//   <prefix>/cameras/<camera>/fps   frames used per second (retained, every stats_every_s)
// <zone>, <line> and <camera> are TopicSlug(name); names whose slugs collide get _2, _3, ...
// in order.
//
//   MqttTopics topics = MqttTopics::For("occmap/lab", {"door"}, {"gate"}, {"c1"});
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
  std::string people, run, run_attributes, map;
  std::vector<std::string> zone_slugs, line_slugs, camera_slugs;  // the topic level of each
  std::vector<std::string> zone_count, zone_occupied;   // per zone, in the site's order
  std::vector<std::string> line_in, line_out;           // per line
  std::vector<std::string> camera_state, camera_fps;    // per camera

  static MqttTopics For(const std::string& prefix, const std::vector<std::string>& zones,
                        const std::vector<std::string>& lines, const std::vector<std::string>& cameras = {});
  // Every retained topic above (availability, run, people, map, zones, lines, cameras).
  std::vector<std::string> Retained() const;
};

// Slugs of the names, unique: a repeated slug gets _2, _3, ... (in order).
std::vector<std::string> UniqueSlugs(const std::vector<std::string>& names);

}  // namespace occmap
