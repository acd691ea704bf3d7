// The outputs `occmap run` and `occmap serve` give other software: MQTT (with the site's
// outputs.mqtt block) and ROS map_server maps; their options, and the sinks added to a run.
#pragma once

#include <CLI/CLI.hpp>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "occmap/pipeline/mqtt_sink.h"
#include "occmap/pipeline/ros_map_sink.h"
#include "occmap/pipeline/run.h"
#include "occmap/site/site.h"
#include "occmap/util/status.h"

namespace occmap {

struct LiveOutputsCommand {
  std::string mqtt_url, mqtt_prefix, mqtt_client_id, mqtt_user, mqtt_password_file;
  std::string ros_map_dir;
  std::vector<int64_t> ros_map_frames;
  std::optional<double> ros_map_static_fraction, ros_map_every_s;
};

struct LiveSinks {
  std::shared_ptr<MqttSink> mqtt;
  std::shared_ptr<RosMapSink> ros_map;
};

// --mqtt, --mqtt-prefix, ..., --ros-map, --ros-map-frame, ... on `cmd`.
void AddLiveOutputOptions(CLI::App& cmd, LiveOutputsCommand& live);
// The MQTT options: the site's outputs.mqtt, the command line's over them; none without either.
Result<std::optional<MqttOptions>> MqttOptionsFor(const Site& site, const LiveOutputsCommand& cmd);
// Adds the sinks the command asks for to the run's options; the MQTT link's failures and
// recoveries are said on stderr as "<program>: mqtt: ...".
Result<LiveSinks> AddLiveSinks(const Site& site, const LiveOutputsCommand& cmd, RunOptions& run,
                               const std::string& program);
// What the sinks did: MQTT counters, the ROS maps written.
void PrintLiveSinks(const LiveSinks& sinks);

}  // namespace occmap
