#include "serve_command.h"

#include <fmt/core.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <thread>

#include "occmap/serve/serve_session.h"
#include "occmap/serve/web_api.h"
#include "occmap/serve/web_assets.h"
#include "occmap/serve/web_server.h"
#include "occmap/util/file_util.h"
#include "occmap/util/text_guard.h"
#include "run_support.h"

namespace occmap {

CLI::App* AddServeCommand(CLI::App& app, ServeCommand& cmd) {
  CLI::App* c = app.add_subcommand(
      "serve", "run the site live with a web view: map, tracks, cameras, setup (calibration, masks, zones) in the browser");
  c->add_option("site", cmd.site_path, "site file (YAML)")->required();
  c->add_option("--listen", cmd.listen, "HOST:PORT to serve on (port 0: any free port, printed)")->capture_default_str();
  c->add_option("--token", cmd.token, "every request needs this token (Authorization: Bearer T or ?token=T)");
  c->add_option("--token-file", cmd.token_file, "file whose first line is the token");
  AddAllowHostOption(*c, cmd.allow_hosts);
  c->add_option("--out", cmd.out_dir, "output folder of the run")->capture_default_str();
  // As `occmap run`'s (-1, "until a source ends", is not a count a user may give).
  c->add_option("--frames", cmd.max_frames, "process at most N frames")
      ->check(CLI::Range(int64_t{1}, int64_t{1'000'000'000'000}));
  c->add_option("--start", cmd.start_frame, "first frame of every source")
      ->capture_default_str()
      ->check(CLI::Range(int64_t{0}, int64_t{1'000'000'000'000}));
  c->add_flag("--loop", cmd.loop, "read video files and image sequences again from their start when they end");
  c->add_option("--cache-dir", cmd.cache_dir, "folder of cached tables and backgrounds (default: ~/.cache/occmap)");
  c->add_flag("--no-cache", cmd.no_cache, "never read or write cached tables or backgrounds");
  c->add_option("--sync", cmd.sync, "synchronise cameras by frame index or timestamp")
      ->check(CLI::IsMember({"index", "timestamp"}))
      ->capture_default_str();
  c->add_flag("--continue-without-camera", cmd.continue_without_camera,
              "when a camera's stream ends or fails, go on without it (its cells become unseen)");
  c->add_flag("--occupancy-pngs", cmd.occupancy_pngs, "also write occupancy/NNNNNN.png per frame");
  c->add_flag("--no-video", cmd.no_video, "do not write occupancy.mp4 and mosaic.mp4");
  c->add_flag("--no-wall-clock", cmd.no_wall_clock, "leave t_unix out of the JSON lines");
  c->add_option("--summary-every-s", cmd.summary_every_s, "rewrite summary.json this often (0 = only at the end)")
      ->capture_default_str();
  c->add_option("--background-frames", cmd.background_frames, "K: frames in the median background of a camera without one")
      ->capture_default_str();
  c->add_option("--min-blob-area-m2", cmd.min_blob_area_m2, "drop detections with a smaller footprint");
  c->add_flag("--no-pace", cmd.no_pace,
              "file inputs as fast as they decode (default: at their frame rate, as a live view)");
  AddLiveOutputOptions(*c, cmd.live);
  return c;
}

void AddAllowHostOption(CLI::App& c, std::vector<std::string>& allow_hosts) {
  c.add_option("--allow-host", allow_hosts,
               "a host name the pages may be reached by besides IP addresses and localhost (repeat for more): "
               "requests naming another host are refused (DNS rebinding)");
}

Result<WebServerOptions> WebServerOptionsFrom(const std::string& listen_text, const std::string& token_text,
                                              const std::string& token_file,
                                              const std::vector<std::string>& allowed_hosts) {
  OCCMAP_ASSIGN_OR_RETURN(ListenAddress listen, ParseListen(listen_text));
  if (!token_text.empty() && !token_file.empty()) return InvalidInput("--token, --token-file: give one of them");
  std::string token = token_text;
  if (!token_file.empty()) {
    auto text = ReadFileToString(token_file);
    if (!text.ok()) return NotFound(fmt::format("--token-file: cannot read '{}'", token_file));
    token = text->substr(0, text->find('\n'));
    while (!token.empty() && (token.back() == '\r' || token.back() == ' ')) token.pop_back();
    if (token.empty()) return InvalidInput(fmt::format("--token-file '{}': the first line is empty", token_file));
  }
  for (char ch : token) {
    // '%': cpp-httplib percent-decodes header values, so "Bearer a%41" would arrive as "aA".
    if (ch < 0x21 || ch > 0x7e || ch == '%') {
      return InvalidInput("--token: expected printable ASCII without spaces or '%'");
    }
  }
  if (!IsLoopbackHost(listen.host) && token.empty()) {
    return InvalidInput(fmt::format("--listen {}: serving beyond this machine needs --token or --token-file",
                                    listen_text));
  }
  if (!IsLoopbackHost(listen.host) && token.size() < kMinTokenChars) {
    return InvalidInput(fmt::format("--token: serving beyond this machine needs a token of at least {} characters, "
                                    "found {} (make one with: openssl rand -hex 16)",
                                    kMinTokenChars, token.size()));
  }
  for (const std::string& h : allowed_hosts) {
    if (h.empty() || h.size() > 253 || h.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789.-") !=
                                           std::string::npos) {
      return InvalidInput(fmt::format("--allow-host: expected a host name (letters, digits, '.', '-'), found '{}'",
                                      Excerpt(h, 80)));
    }
  }
  WebServerOptions wo;
  wo.listen = listen;
  wo.token = token;
  wo.allowed_hosts = allowed_hosts;
  return wo;
}

void SayListening(const std::string& who, const ListenAddress& listen, int port) {
  const std::string host = listen.host.find(':') != std::string::npos ? "[" + listen.host + "]" : listen.host;
  std::fputs(fmt::format("{}: listening on http://{}:{}/\n", who, host, port).c_str(), stdout);
  std::fflush(stdout);
}

Status RunServe(const ServeCommand& cmd, int threads, const std::string& data_root) {
  namespace fs = std::filesystem;
  OCCMAP_ASSIGN_OR_RETURN(const WebServerOptions wo, WebServerOptionsFrom(cmd.listen, cmd.token, cmd.token_file, cmd.allow_hosts));
  if (cmd.min_blob_area_m2 && !(*cmd.min_blob_area_m2 >= 0)) return InvalidInput("--min-blob-area-m2: expected >= 0");

  ServeSessionOptions so;
  so.site_path = cmd.site_path;
  if (!data_root.empty()) so.load.data_root = fs::path(data_root);
  so.threads = threads;
  so.pace = !cmd.no_pace;
  RunOptions& o = so.run;
  o.out_dir = cmd.out_dir;
  o.max_frames = cmd.max_frames;
  o.start_frame = cmd.start_frame;
  o.loop = cmd.loop;
  o.cache_dir = cmd.no_cache ? fs::path() : cmd.cache_dir.empty() ? DefaultCacheDir() : fs::path(cmd.cache_dir);
  o.sync = cmd.sync == "timestamp" ? FrameSync::kTimestamp : FrameSync::kIndex;
  o.on_camera_failure = cmd.continue_without_camera ? OnCameraFailure::kContinue : OnCameraFailure::kStop;
  o.occupancy_pngs = cmd.occupancy_pngs;
  if (cmd.no_video) o.occupancy_video = o.mosaic_video = false;
  o.wall_clock_times = !cmd.no_wall_clock;
  o.summary_every_s = cmd.summary_every_s;
  o.background_frames = cmd.background_frames;
  o.warning = PrintWarnings("occmap serve");
  OCCMAP_RETURN_IF_ERROR(o.Validate());
  // MQTT and ROS maps as `occmap run` gives them, from the site as it is now (a site saved from
  // the page keeps these sinks). A site that does not load is the session's to report, unless
  // the command line asks for these outputs.
  LiveSinks live;
  if (auto site = LoadSite(cmd.site_path, so.load); site.ok()) {
    OCCMAP_ASSIGN_OR_RETURN(live, AddLiveSinks(*site, cmd.live, o, "occmap serve"));
  } else if (!cmd.live.mqtt_url.empty() || !cmd.live.ros_map_dir.empty()) {
    return site.status();
  }
  if (cmd.min_blob_area_m2) {
    const double area = *cmd.min_blob_area_m2;
    so.adjust_site = [area](Site& site) {
      site.objects.min_area_m2 = area;
      return Status::Ok();
    };
  }
  // Before any thread starts, so that every thread inherits the blocked signals.
  StopOnSignals signals(cmd.out_dir);
  OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<ServeSession> session, ServeSession::Create(so));
  if (live.mqtt) session->state().SetMqtt(live.mqtt);  // its link's state in /api/state, /metrics
  WebServer server(wo, *session, EmbeddedWebAssets());
  OCCMAP_ASSIGN_OR_RETURN(int port, server.Bind());
  server.Start();
  SayListening("occmap serve", wo.listen, port);
  session->Start();
  // With file inputs the run ends on its own; the server stays up with the last state until
  // a signal.
  while (!signals.stop()->load()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  server.Stop();
  session->Stop();
  if (auto s = session->last_summary()) {
    std::fputs(fmt::format("{} frames in {:.2f} s: {}\n", s->frames, s->seconds, s->stop_reason).c_str(), stdout);
  }
  PrintLiveSinks(live);
  std::fputs(fmt::format("wrote {}\n", (fs::path(cmd.out_dir) / "summary.json").string()).c_str(), stdout);
  return Status::Ok();
}

}  // namespace occmap
