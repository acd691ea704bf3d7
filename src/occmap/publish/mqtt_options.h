// MqttOptions: where and how a run publishes on MQTT (the site file's `outputs: mqtt:` block,
// or `occmap run --mqtt URL`), and the checked parsing of both.
//
//   outputs:
//     mqtt:
//       url: mqtt://192.168.1.10:1883     # mqtt://HOST[:PORT], PORT 1883 by default; no TLS
//       topic_prefix: occmap/lab          # default occmap/<site name as a slug>
//       client_id: occmap-lab             # default occmap-<site name as a slug>
//       username: occmap                  # optional
//       password_file: mqtt-password.txt  # optional, its first line; relative to the site file
//       keepalive_s: 30
//       stats_every_s: 5                  # <prefix>/stats every this many seconds (wall clock)
//       discovery: true                   # Home Assistant MQTT discovery configs
//       discovery_prefix: homeassistant
//
// Errors name the file, line and field: site.yaml:40: outputs.mqtt.url: expected
// mqtt://HOST[:PORT], found 'http://x'. A URL given on the command line is named "--mqtt".
//
//   OCCMAP_ASSIGN_OR_RETURN(MqttBroker broker, ParseMqttUrl("mqtt://127.0.0.1:1883"));
//   MqttOptions options;  options.broker = broker;  ResolveMqttDefaults("lab", options);
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include "occmap/util/status.h"
#include "occmap/util/yaml_util.h"

namespace occmap {

struct MqttBroker {
  std::string host;  // a name, an IPv4 address or an IPv6 address (given in brackets in a URL)
  int port = 1883;
  friend bool operator==(const MqttBroker&, const MqttBroker&) = default;
};

struct MqttOptions {
  MqttBroker broker;
  // Every topic starts with this (no wildcards, no empty level, no leading '/' or '$');
  // empty: occmap/<site slug> (ResolveMqttDefaults).
  std::string topic_prefix;
  std::string client_id;  // empty: occmap-<site slug>
  std::string username;   // empty: no login
  std::filesystem::path password_file;  // empty: no password; needs a username
  int keepalive_s = 30;
  double stats_every_s = 5;
  bool discovery = true;  // Home Assistant discovery configs (home_assistant.h)
  std::string discovery_prefix = "homeassistant";

  Status Validate() const;
};

// mqtt://HOST[:PORT][/]; errors say what was expected and what was found, prefixed by `where`
// (a field's location or "--mqtt").
Result<MqttBroker> ParseMqttUrl(std::string_view url, std::string_view where);

// A topic level made of [a-z0-9_-] (others become '_'): "Door West" -> "door_west".
std::string TopicSlug(std::string_view name);

// Fills an empty topic prefix and client id from the site's name.
void ResolveMqttDefaults(std::string_view site_name, MqttOptions& options);

// Reads an `outputs.mqtt` block (url required); relative paths resolve against site_dir, and
// a password file must exist.
Result<MqttOptions> ParseMqttOptions(const YamlField& field, const std::filesystem::path& site_dir);

// The password: the file's first line without its line end; an error names the file.
Result<std::string> ReadMqttPassword(const std::filesystem::path& password_file);

}  // namespace occmap
