// `occmap serve`: the site's pipeline with a web server (src/occmap/serve/): live view, setup
// in the browser, JSON API, metrics. The command parses and wires; the library does the work.
#pragma once

#include <CLI/CLI.hpp>

#include <optional>
#include <string>
#include <vector>

#include "live_outputs.h"
#include "occmap/serve/web_server.h"
#include "occmap/util/status.h"

namespace occmap {

struct ServeCommand {
  std::string site_path;
  std::string listen = "127.0.0.1:8080";
  std::string token;
  std::string token_file;
  std::vector<std::string> allow_hosts;
  std::string out_dir = "occmap-out";
  // The run's input and output options (as `occmap run`'s).
  int64_t max_frames = -1;
  int64_t start_frame = 0;
  bool loop = false;
  std::string cache_dir;
  bool no_cache = false;
  std::string sync = "index";
  bool continue_without_camera = false;
  bool occupancy_pngs = false;
  bool no_video = false;
  bool no_wall_clock = false;
  double summary_every_s = 5;
  int background_frames = 25;
  std::optional<double> min_blob_area_m2;
  bool no_pace = false;
  LiveOutputsCommand live;  // --mqtt, --ros-map, ... as `occmap run`'s
};

CLI::App* AddServeCommand(CLI::App& app, ServeCommand& cmd);

// --allow-host NAME...: the one definition for every command with a web server (serve, fuse).
void AddAllowHostOption(CLI::App& c, std::vector<std::string>& allow_hosts);

// --listen, --token, --token-file: the address (port 0: any free port) and the token, checked:
// a token of printable ASCII, and one whenever the address is not loopback. `who` names the
// command in the messages ("occmap serve", "occmap fuse").
// Beyond loopback the token is the one gate: at least kMinTokenChars characters. `allowed_hosts`:
// --allow-host names (web_server.h).
inline constexpr size_t kMinTokenChars = 16;
Result<WebServerOptions> WebServerOptionsFrom(const std::string& listen, const std::string& token,
                                              const std::string& token_file,
                                              const std::vector<std::string>& allowed_hosts = {});
// "<who>: listening on http://HOST:PORT/" on stdout, the line scripts and tests wait for.
void SayListening(const std::string& who, const ListenAddress& listen, int port);

Status RunServe(const ServeCommand& cmd, int threads, const std::string& data_root);

}  // namespace occmap
