#include "live_outputs.h"

#include <fmt/core.h>

#include <unistd.h>

#include <cstdio>
#include <filesystem>

namespace occmap {
namespace fs = std::filesystem;

void AddLiveOutputOptions(CLI::App& cmd, LiveOutputsCommand& live) {
  cmd.add_option("--mqtt", live.mqtt_url, "publish on MQTT: mqtt://HOST[:PORT] (over the site's outputs.mqtt.url)");
  cmd.add_option("--mqtt-prefix", live.mqtt_prefix, "MQTT topic prefix (default occmap/<site>)");
  cmd.add_option("--mqtt-client-id", live.mqtt_client_id, "MQTT client id (default occmap-<site>)");
  cmd.add_option("--mqtt-user", live.mqtt_user, "MQTT user name");
  cmd.add_option("--mqtt-password-file", live.mqtt_password_file, "file whose first line is the MQTT password");
  cmd.add_option("--ros-map", live.ros_map_dir, "write ROS map_server maps (PGM + YAML) to this folder: static.yaml, and frame_NNNNNN.yaml");
  cmd.add_option("--ros-map-frame", live.ros_map_frames, "also write this frame's map (repeatable)");
  cmd.add_option("--ros-map-static-fraction", live.ros_map_static_fraction,
                 "static map: cells occupied in more than this fraction of the frames that saw them (default 0.5)");
  cmd.add_option("--ros-map-every-s", live.ros_map_every_s,
                 "rewrite static.yaml every this many seconds of stream time, and at the end (default 60; 0: at the end)");
}

Result<std::optional<MqttOptions>> MqttOptionsFor(const Site& site, const LiveOutputsCommand& cmd) {
  std::optional<MqttOptions> options = site.outputs.mqtt;
  if (!cmd.mqtt_url.empty()) {
    OCCMAP_ASSIGN_OR_RETURN(MqttBroker broker, ParseMqttUrl(cmd.mqtt_url, "--mqtt"));
    if (!options) options.emplace();
    options->broker = broker;
  }
  const bool other_flags = !cmd.mqtt_prefix.empty() || !cmd.mqtt_client_id.empty() || !cmd.mqtt_user.empty() ||
                           !cmd.mqtt_password_file.empty();
  if (!options) {
    if (other_flags) return InvalidInput("--mqtt-prefix, --mqtt-client-id, --mqtt-user, --mqtt-password-file: need --mqtt URL or outputs.mqtt in the site file");
    return std::optional<MqttOptions>();
  }
  if (!cmd.mqtt_prefix.empty()) options->topic_prefix = cmd.mqtt_prefix;
  if (!cmd.mqtt_client_id.empty()) options->client_id = cmd.mqtt_client_id;
  if (!cmd.mqtt_user.empty()) options->username = cmd.mqtt_user;
  if (!cmd.mqtt_password_file.empty()) {
    options->password_file = cmd.mqtt_password_file;
    if (std::error_code ec; !fs::is_regular_file(options->password_file, ec)) {
      return NotFound(fmt::format("--mqtt-password-file: file not found: '{}'", cmd.mqtt_password_file));
    }
  }
  ResolveMqttDefaults(site.name, *options);
  OCCMAP_RETURN_IF_ERROR(options->Validate().WithContext(cmd.mqtt_url.empty() ? site.file.string() : "--mqtt"));
  return options;
}

Result<LiveSinks> AddLiveSinks(const Site& site, const LiveOutputsCommand& cmd, RunOptions& run,
                               const std::string& program) {
  LiveSinks sinks;
  OCCMAP_ASSIGN_OR_RETURN(std::optional<MqttOptions> mqtt, MqttOptionsFor(site, cmd));
  if (mqtt) {
    // From the publisher's network thread: one line per failure streak and per recovery.
    const bool terminal = ::isatty(STDERR_FILENO) == 1;
    auto say = [program, terminal](const std::string& line) {
      std::fputs(fmt::format("{}{}: {}\n", terminal ? "\r\033[K" : "", program, line).c_str(), stderr);
    };
    sinks.mqtt = std::make_shared<MqttSink>(*mqtt, say);
    run.sinks.push_back(sinks.mqtt);
  }
  if (cmd.ros_map_dir.empty()) {
    if (!cmd.ros_map_frames.empty() || cmd.ros_map_static_fraction || cmd.ros_map_every_s) {
      return InvalidInput("--ros-map-frame, --ros-map-static-fraction, --ros-map-every-s: need --ros-map DIR");
    }
    return sinks;
  }
  RosMapOptions ros;
  ros.dir = cmd.ros_map_dir;
  ros.frames = cmd.ros_map_frames;
  if (cmd.ros_map_static_fraction) ros.static_fraction = *cmd.ros_map_static_fraction;
  if (cmd.ros_map_every_s) ros.static_every_s = *cmd.ros_map_every_s;
  OCCMAP_RETURN_IF_ERROR(ros.Validate());
  sinks.ros_map = std::make_shared<RosMapSink>(ros);
  run.sinks.push_back(sinks.ros_map);
  return sinks;
}

void PrintLiveSinks(const LiveSinks& sinks) {
  if (sinks.mqtt) {
    const MqttCounters c = sinks.mqtt->counters();
    std::fputs(fmt::format("mqtt: {} messages published, {} dropped (broker away or too slow); connected {} times, "
                           "lost {} times\n",
                           c.published, c.dropped, c.connects, c.disconnects)
                   .c_str(),
               stdout);
  }
  if (sinks.ros_map) {
    for (const fs::path& p : sinks.ros_map->written()) {
      if (p.extension() == ".yaml") std::fputs(fmt::format("wrote {}\n", p.string()).c_str(), stdout);
    }
  }
}

}  // namespace occmap
