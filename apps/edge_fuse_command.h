// `occmap edge` and `occmap fuse` (pipeline/edge_fuse.h): cameras on many hosts joined by an
// MQTT broker. The commands parse and wire; the library does the work.
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

#include "live_outputs.h"
#include "occmap/pipeline/edge_fuse.h"
#include "occmap/util/status.h"

namespace occmap {

struct EdgeFuseCommon {
  std::string site_path;
  std::string broker = "mqtt://127.0.0.1:1883";
  std::string topic_prefix;
  std::string cache_dir;
  bool no_cache = false;
};

struct EdgeCommand {
  EdgeFuseCommon common;
  std::string cameras;  // comma-separated ids
  EdgeOptions options;
};

struct FuseCommand {
  EdgeFuseCommon common;
  FuseOptions options;
  LiveOutputsCommand live;  // --mqtt, --ros-map: the run's outputs for other software
  // --listen (empty: no web view), --token, --token-file, --allow-host: `occmap serve`'s live
  // view of the fuse.
  std::string listen, token, token_file;
  std::vector<std::string> allow_hosts;
  bool no_video = false;
  bool no_wall_clock = false;
  bool atomic_outputs = false;
  std::string sync;  // "index", "timestamp", empty: by the sources
};

// `occmap edge-sim`: simulated edges for the bench (bench/edge_sim.h): --record DIR or --replay DIR.
struct EdgeSimCommand {
  EdgeFuseCommon common;
  std::string record_dir, replay_dir;
  double idle_timeout_s = 60;
  int first_camera = 0, cameras = 0;
  double rate_hz = 10, start_unix = 0, seconds = 30;
};

CLI::App* AddEdgeCommand(CLI::App& app, EdgeCommand& cmd);
CLI::App* AddEdgeSimCommand(CLI::App& app, EdgeSimCommand& cmd);
Status RunEdgeSimCommand(const EdgeSimCommand& cmd, const std::string& data_root);
CLI::App* AddFuseCommand(CLI::App& app, FuseCommand& cmd);
Status RunEdgeCommand(EdgeCommand cmd, int threads, const std::string& data_root);
Status RunFuseCommand(FuseCommand cmd, int threads, const std::string& data_root);

}  // namespace occmap
